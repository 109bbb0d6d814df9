// The loop-closure search: which scans of a finished submap are matched against which older
// submaps, the window the graph's uncertainty sets for each, and the tests a match must pass
// to become a constraint (quality, window edge, the graph's gate and uniqueness).
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "probslam/core/angle.hpp"
#include "probslam/core/chi_square.hpp"
#include "probslam/core/pose2_covariance.hpp"
#include "probslam/slam2d/cpu_clock.hpp"
#include "submap_slam_internal.hpp"

namespace probslam {

using submap_slam_detail::kMinConstraintVariance;
using submap_slam_detail::pose_of;

namespace {

/// A best pose this close to the window's edge (in cells or angular steps) may be the edge of
/// a peak that lies outside: such a match is not trusted as a closure.
constexpr double kEdgeCells = 1.0;
/// The quality test is made at the refined pose and the minimum score on the lattice: a lattice
/// pose a fraction of a cell off scores lower, so the bound is loosened by this factor.
constexpr double kClosureScoreSlack = 1.25;
/// Scans with fewer hits than this are not used for closures: too few to tell places apart.
constexpr int kMinClosurePoints = 30;

double largest_eigenvalue(const Eigen::Matrix2d& m) {
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(0.5 * (m + m.transpose())).eigenvalues()(1);
}

/// The search of a scan at world pose covariance SW against a submap with marginal Si whose
/// origin lies `lever` (squared, m^2) from the scan: the window spans window_sigmas of the
/// relative pose's largest spread, within the options' bounds; no prior, refined.
MatchOptions closure_window(const SubmapSlamOptions& o, const Eigen::Matrix3d& SW, const Eigen::Matrix3d& Si,
                            double lever) {
  const LoopClosureOptions& lc = o.closures;
  const double lin_sd = std::sqrt(std::max(0.0, largest_eigenvalue(SW.topLeftCorner<2, 2>()) +
                                                    largest_eigenvalue(Si.topLeftCorner<2, 2>()) + Si(2, 2) * lever));
  const double ang_sd = std::sqrt(std::max(0.0, SW(2, 2) + Si(2, 2)));
  MatchOptions m = o.frontend.match;
  m.use_prior = false;
  m.refine = true;
  m.window.linear = std::clamp(lc.window_sigmas * lin_sd, lc.min_linear_window, lc.max_linear_window);
  m.window.angular = std::clamp(lc.window_sigmas * ang_sd, lc.min_angular_window, lc.max_angular_window);
  return m;
}

/// The least score a match of `points` hits at min_match_quality can have: log p >= (1 - h)
/// log p_rand for a hit share h (log p is concave in h), so a pose whose mean h reaches it
/// scores at least this, and the search prunes everything below.
double min_closure_score(Eigen::Index points, const SubmapSlamOptions& o) {
  return kClosureScoreSlack * static_cast<double>(points) * (1.0 - o.closures.min_match_quality) *
         std::log(o.frontend.field.p_rand);
}

/// Whether match r lies at the edge of a window narrower than the largest (cells of
/// `resolution` m, the match's angular steps): the peak may lie outside.
bool at_window_edge(const MatchResult& r, const Eigen::Vector3d& predicted, const MatchOptions& m,
                    const LoopClosureOptions& lc, double resolution) {
  const Eigen::Vector3d off = r.search_pose - predicted;
  return (m.window.linear < lc.max_linear_window &&
          std::max(std::abs(off.x()), std::abs(off.y())) > m.window.linear - kEdgeCells * resolution) ||
         (m.window.angular < lc.max_angular_window &&
          std::abs(wrap_angle(off.z())) > m.window.angular - kEdgeCells * r.angular_step);
}

}  // namespace

int SubmapSlam2D::search_closures(int j) {
  if (j < 2) return 0;
  const ScopedCpuTimer timer(timings_.closure_search);
  const std::vector<int> candidates = closure_candidates(j);
  if (candidates.empty()) return 0;
  const std::vector<Eigen::Matrix3d> marginals = submap_marginals(j);
  const int n = std::min<int>(options_.closures.scans_per_submap, static_cast<int>(candidates.size()));
  // Submap by submap, so that each field is wanted once per search, not once per scan (a cache
  // smaller than the submaps searched would rebuild every field n times); the closures found
  // are added scan by scan, the order of old, which the optimiser's sums depend on.
  std::vector<std::vector<SubmapConstraint>> found(static_cast<std::size_t>(n));
  std::vector<int> scans(static_cast<std::size_t>(n));
  std::vector<Points2> hits(static_cast<std::size_t>(n));
  for (int q = 0; q < n; ++q) {
    scans[static_cast<std::size_t>(q)] = candidates[static_cast<std::size_t>((q + 0.5) * candidates.size() / n)];
    hits[static_cast<std::size_t>(q)] = hits_of(scans[static_cast<std::size_t>(q)]);
  }
  for (int i = 0; i + 2 <= j; ++i)
    for (int q = 0; q < n; ++q) {
      const std::size_t k = static_cast<std::size_t>(q);
      if (auto c = try_closure(scans[k], hits[k], i, marginals)) found[k].push_back(*c);
    }
  std::vector<SubmapConstraint> all;
  for (const std::vector<SubmapConstraint>& f : found) all.insert(all.end(), f.begin(), f.end());
  return add_consistent(all);
}

std::vector<int> SubmapSlam2D::closure_candidates(int j) const {
  const std::vector<ScanEstimate>& est = frontend_.estimates();
  std::vector<int> candidates;
  for (int s : frontend_.submaps()[j].scans)
    if (est[s].submap == j && hit_counts_[static_cast<std::size_t>(s)] >= kMinClosurePoints) candidates.push_back(s);
  return candidates;
}

std::vector<Eigen::Matrix3d> SubmapSlam2D::submap_marginals(int j) const {
  const PoseGraph2D g = graph();
  std::vector<int> ids(static_cast<std::size_t>(j) + 1);
  for (int k = 0; k <= j; ++k) ids[k] = k;
  std::vector<Eigen::Matrix3d> marginals;
  for (const Eigen::MatrixXd& m : marginal_covariances(g, ids, options_.optimizer.linear_solver))
    marginals.push_back(m);
  return marginals;
}

std::optional<SubmapConstraint> SubmapSlam2D::try_closure(int s, const Points2& points, int i,
                                                          const std::vector<Eigen::Matrix3d>& marginals) {
  const LoopClosureOptions& lc = options_.closures;
  // The scan in the world as the graph has it (W, with covariance SW), and submap i's frontend
  // frame in the world (Ti): its scans' positions, where W must come near.
  const int j = frontend_.estimates()[s].submap;
  const Eigen::Vector3d o = scan_offset(s);
  const Eigen::Vector3d W = pose_of(nodes_[j]).compose(pose_of(o)).vector();
  const Eigen::Matrix3d SW = compose_covariance(nodes_[j], marginals[j], o, offset_cov_[s]);
  const Eigen::Matrix3d& Si = marginals[i];
  const Pose2 Ti = pose_of(nodes_[i]).compose(pose_of(frontend_.submaps()[i].origin).inverse());
  MatchOptions m = closure_window(options_, SW, Si, (W.head<2>() - nodes_[i].head<2>()).squaredNorm());
  if (distance_to_submap(i, Ti, W) > lc.max_distance + m.window.linear) return std::nullopt;

  // Where the graph puts the scan in submap i's grid.
  const Eigen::Vector3d predicted = Ti.inverse().compose(pose_of(W)).vector();
  if (searched_before(s, i, predicted)) return std::nullopt;
  const CorrelativeScanMatcher& matcher = closure_matcher(i, m.window.linear);
  m.min_score = min_closure_score(points.rows(), options_);
  const MatchResult r = matcher.match(points, predicted, m);
  ++counts_.closures_searched;
  ++timings_.closure_matches;
  if (!r.found) {
    ++counts_.closures_rejected;
    return std::nullopt;
  }
  const bool at_edge = at_window_edge(r, predicted, m, lc, matcher.field().resolution());
  const Eigen::Matrix3d gate = graph_gate(r, Ti, W, SW, i, Si);
  if (r.match_quality < lc.min_match_quality || at_edge || gate_chi2(gate, r.pose, predicted) > lc.dissolve_chi2 ||
      !unique_match(matcher, points, predicted, m, r, gate)) {
    ++counts_.closures_rejected;
    return std::nullopt;
  }
  return closure_constraint(s, i, r);
}

Eigen::Vector3d SubmapSlam2D::scan_offset(int s) const {
  const ScanEstimate& e = frontend_.estimates()[s];
  return pose_of(frontend_.submaps()[e.submap].origin).between(pose_of(e.pose)).vector();
}

double SubmapSlam2D::distance_to_submap(int i, const Pose2& Ti, const Eigen::Vector3d& W) const {
  const std::vector<ScanEstimate>& est = frontend_.estimates();
  double nearest = std::numeric_limits<double>::infinity();
  for (int k : frontend_.submaps()[i].scans)
    nearest = std::min(nearest, (Ti.transform_from(est[k].pose.head<2>()) - W.head<2>()).norm());
  if (i == 0 && start_map_) {  // the saved map reaches beyond the scans of its stretch
    const Eigen::Vector2d w = Ti.inverse().transform_from(W.head<2>());
    const Eigen::Vector2d out = (start_map_bounds_.head<2>() - w).cwiseMax(w - start_map_bounds_.tail<2>()).cwiseMax(0.0);
    nearest = std::min(nearest, out.norm());
  }
  return nearest;
}

bool SubmapSlam2D::searched_before(int s, int i, const Eigen::Vector3d& predicted) {
  const LoopClosureOptions& lc = options_.closures;
  // A pair searched with the scan predicted at about the same place would find the same.
  const auto key = std::make_pair(s, i);
  const auto seen = attempts_.find(key);
  if (seen != attempts_.end()) {
    const Eigen::Vector3d d = seen->second - predicted;
    if (d.head<2>().norm() < 0.5 * lc.min_linear_window && std::abs(wrap_angle(d.z())) < 0.5 * lc.min_angular_window)
      return true;
  }
  attempts_[key] = predicted;
  // A pair that holds an active closure is not searched again: once the graph moved, the same
  // match would be added a second time and count twice (a look-alike's as much as a true one's).
  for (const SubmapConstraint& c : constraints_)
    if (c.loop && c.active && c.scan == s && c.from == i) return true;
  return false;
}

SubmapConstraint SubmapSlam2D::closure_constraint(int s, int i, const MatchResult& r) const {
  // The scan in submap i's frame (a), and submap j's origin seen from the scan (b = o^-1).
  const Pose2 origin_i = pose_of(frontend_.submaps()[i].origin);
  const Eigen::Vector3d o = scan_offset(s);
  const Eigen::Vector3d a = origin_i.between(pose_of(r.pose)).vector();
  const Eigen::Matrix3d Ri = frame_rotation(origin_i.theta);
  const Eigen::Matrix3d Sa = Ri.transpose() * r.covariance * Ri;
  const Eigen::Vector3d b = pose_of(o).inverse().vector();
  const Eigen::Matrix3d Jinv = inverse_jacobian(o);
  SubmapConstraint c;
  c.from = i;
  c.to = frontend_.estimates()[s].submap;
  c.loop = true;
  c.scan = s;
  c.match_quality = r.match_quality;
  c.measurement = pose_of(a).compose(pose_of(b)).vector();
  c.covariance = compose_covariance(a, Sa, b, Jinv * offset_cov_[s] * Jinv.transpose()) +
                 kMinConstraintVariance * Eigen::Matrix3d::Identity();
  return c;
}

Eigen::Matrix3d SubmapSlam2D::graph_gate(const MatchResult& r, const Pose2& Ti, const Eigen::Vector3d& W,
                                         const Eigen::Matrix3d& SW, int i, const Eigen::Matrix3d& Si) const {
  // The match against where the graph predicts the scan, in the world frame: the window spans
  // the prediction's largest spread on both axes and the largest turn, so a look-alike place
  // can score well inside it where the prediction's own spread makes it improbable (a corridor
  // known across, not along; the map's heading known to a degree). A closure the optimised
  // graph would dissolve at once (dissolve_chi2) is not added: the same test, before, with the
  // two submaps' marginals taken as independent (their correlation only shrinks the spread of
  // the difference, so this errs towards accepting) and submap i's heading spread carried to
  // the scan by its lever arm.
  const Eigen::Matrix3d R = frame_rotation(Ti.theta);  // submap i's frontend frame -> the world's
  const Eigen::Matrix3d J = heading_jacobian(W.head<2>() - nodes_[i].head<2>());
  const Eigen::Matrix3d C = SW + J * Si * J.transpose() + R * r.covariance * R.transpose();
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(0.5 * (C + C.transpose()));
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all()) return Eigen::Matrix3d::Zero();
  const Eigen::Matrix3d info = R.transpose() * ldlt.solve(R);
  return 0.5 * (info + info.transpose());
}

double SubmapSlam2D::gate_chi2(const Eigen::Matrix3d& gate, const Eigen::Vector3d& pose, const Eigen::Vector3d& predicted) {
  Eigen::Vector3d d = pose - predicted;
  d.z() = wrap_angle(d.z());
  return d.dot(gate * d);
}

bool SubmapSlam2D::unique_match(const CorrelativeScanMatcher& matcher, const Points2& points,
                                const Eigen::Vector3d& predicted, const MatchOptions& m, const MatchResult& r,
                                const Eigen::Matrix3d& gate) const {
  // A look-alike place (the next door along a corridor, the neighbouring box) can score as well
  // as the match and lie within the graph's gate as well: the match alone cannot tell them
  // apart, and the one it picked may be the wrong one (Olson 2009's uniqueness test). The
  // runner-up is the best pose that is another place (beyond the match's own spread at
  // dissolve_chi2 and beyond the field's reach of its points) which the graph's gate admits as
  // well; the match is kept only when it explains the scan better than the runner-up beyond
  // chance: Vuong's statistic above the normal quantile of dissolve_chi2's confidence (one
  // sided: 3.09 at 0.999).
  const double chi2 = options_.closures.dissolve_chi2;
  const MatchResult ru = matcher.runner_up(points, predicted, m, r, chi2, gate / chi2);
  const double z = ru.found ? matcher.closeness(points, r.pose, ru.pose) : std::numeric_limits<double>::infinity();
  const double confidence = chi_square_cdf(chi2, 3);
  const double z_min = std::sqrt(chi_square_quantile(2.0 * confidence - 1.0, 1));
  return z > z_min;
}

}  // namespace probslam
