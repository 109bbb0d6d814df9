// What a SubmapSlam2D reports of itself: processor time per stage, the bytes its large buffers
// hold, and the counts of its search and optimisation.
#include "submap_slam_internal.hpp"

namespace probslam {

SubmapSlamTimings SubmapSlam2D::timings() const {
  SubmapSlamTimings t = timings_;
  const ScanMatcherTimings& f = frontend_.timings();
  t.filter = f.filter;
  t.match = f.match;
  t.insert = f.insert;
  t.frontend_fields = f.fields_built;
  t.frontend_local = f.local_matches;
  t.frontend_searches = f.searches;
  t.final_map = map_seconds_;
  return t;
}

SubmapSlamMemory SubmapSlam2D::memory() const {
  SubmapSlamMemory m;
  for (std::size_t k = 0; k < ranges_.size(); ++k) {
    // A scan's beam angles are counted once where it shares them with the scan before.
    const bool shared = k > 0 && angles_[k] == angles_[k - 1];
    m.scans += 8.0 * static_cast<double>(ranges_[k].size() + (shared ? 0 : angles_[k]->size()));
  }
  m.scans += static_cast<double>(hit_counts_.size() * sizeof(int));
  m.scans += static_cast<double>(offset_cov_.size() * sizeof(Eigen::Matrix3d));
  m.submap_grids = frontend_.grid_bytes();
  for (const ObstacleCells& c : closure_cells_) m.closure_cells += static_cast<double>(c.bytes());
  m.closure_fields = fields_->used();
  if (start_map_) m.start_map = 12.0 * start_map_->width() * start_map_->height();
  return m;
}

SubmapSlamSummary SubmapSlam2D::summary() const {
  SubmapSlamSummary out = counts_;
  out.scans = num_scans();
  out.submaps = num_submaps();
  out.matched_scans = 0;
  for (const ScanEstimate& e : frontend_.estimates()) out.matched_scans += e.matched;
  out.closures_accepted = 0;
  for (const SubmapConstraint& c : constraints_) out.closures_accepted += c.loop && c.active;
  out.final_chi2 = nodes_.empty() ? 0.0 : graph().chi2();
  return out;
}

}  // namespace probslam
