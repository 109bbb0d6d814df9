// The backend: the pose graph of submap origins, its optimisation with the dissolution of the
// closures it contradicts (Thrun et al. ch. 11.6 item 3), and finish()'s rounds of search and
// optimisation until the graph is stable (Fig. 11.4).
#include "probslam/slam2d/cpu_clock.hpp"
#include "submap_slam_internal.hpp"

namespace probslam {

PoseGraph2D SubmapSlam2D::graph() const {
  PoseGraph2D g;
  for (std::size_t k = 0; k < nodes_.size(); ++k) g.add_pose(static_cast<int>(k), nodes_[k]);
  if (!nodes_.empty()) g.set_fixed(0);
  for (const SubmapConstraint& c : constraints_)
    if (c.active) g.add_pose_edge(c.from, c.to, c.measurement, c.covariance.inverse());
  return g;
}

double SubmapSlam2D::constraint_chi2(const SubmapConstraint& c) const {
  const Eigen::Vector3d e = linearize_pose_edge(nodes_[c.from], nodes_[c.to], c.measurement).error;
  return e.dot(c.covariance.ldlt().solve(e));
}

void SubmapSlam2D::optimize_and_dissolve() {
  if (nodes_.size() < 2) return;  // one submap: nothing to optimise
  const ScopedCpuTimer timer(timings_.optimize);
  for (;;) {
    PoseGraph2D g = graph();
    optimize(g, options_.optimizer);
    ++counts_.optimizations;
    nodes_ = g.values();
    // Undo the closure the optimised graph contradicts most (ch. 11.6 item 3), one at a time:
    // a single wrong closure can make right ones look wrong until it is gone.
    SubmapConstraint* worst = most_contradicted();
    if (!worst) return;
    worst->active = false;
    ++counts_.closures_dissolved;
  }
}

SubmapConstraint* SubmapSlam2D::most_contradicted() {
  SubmapConstraint* worst = nullptr;
  double worst_chi2 = options_.closures.dissolve_chi2;
  for (SubmapConstraint& c : constraints_) {
    if (!c.loop || !c.active) continue;
    const double chi2 = constraint_chi2(c);
    if (chi2 > worst_chi2) worst = &c, worst_chi2 = chi2;
  }
  return worst;
}

void SubmapSlam2D::finish() {
  const int last = static_cast<int>(nodes_.size()) - 1;
  if (last < 0) return;
  if (options_.closures.enabled) {
    for (int round = 0; round < options_.max_rounds; ++round) {
      const int dissolved = counts_.closures_dissolved;
      int added = 0;
      for (int j = 2; j <= last; ++j) added += search_closures(j);
      optimize_and_dissolve();
      ++counts_.rounds;
      if (added == 0 && counts_.closures_dissolved == dissolved) break;
    }
  } else if (last > 0) {
    optimize_and_dissolve();
  }
}

}  // namespace probslam
