// The closure search's likelihood fields: what is kept of each finished submap to build its
// field (its obstacle cells in the region its hits cover), the field's build, and the cache
// that keeps the recently searched fields within a byte budget.
#include <algorithm>
#include <vector>

#include "probslam/slam2d/cpu_clock.hpp"
#include "submap_slam_internal.hpp"

namespace probslam {

using submap_slam_detail::pose_of;

namespace {

/// A window half-width wider than 2^kSearchLevels cells starts with several top-level nodes;
/// 8 levels (12.8 m at 5 cm) cover the largest default window with one.
constexpr int kSearchLevels = 8;

}  // namespace

CorrelativeScanMatcher& SubmapSlam2D::FieldCache::get(int submap, int levels, int width, int height,
                                                      const std::function<CorrelativeScanMatcher(int)>& build) {
  const auto it = entries_.find(submap);
  if (it != entries_.end()) {
    order_.splice(order_.begin(), order_, it->second.position);
    Entry& e = it->second;
    if (e.matcher->max_level() < levels) deepen(e, submap, levels, width, height);
    return *e.matcher;
  }
  // Room is made before the build, so that the cache never holds more than its budget and
  // the field being built (the field's size is known from the cells it is built from).
  const double bytes = CorrelativeScanMatcher::bytes_for(width, height, levels);
  make_room(bytes, -1);
  auto matcher = std::make_shared<CorrelativeScanMatcher>(build(levels));
  order_.push_front(submap);
  entries_[submap] = Entry{matcher, bytes, order_.begin()};
  used_ += bytes;
  return *matcher;
}

void SubmapSlam2D::FieldCache::deepen(Entry& e, int submap, int levels, int width, int height) {
  const double bytes = CorrelativeScanMatcher::bytes_for(width, height, levels);
  make_room(bytes - e.bytes, submap);
  e.matcher->extend_levels(levels);
  used_ += bytes - e.bytes;
  e.bytes = bytes;
}

void SubmapSlam2D::FieldCache::make_room(double bytes, int keep) {
  for (auto it = order_.end(); used_ + bytes > budget_ && it != order_.begin();) {
    --it;
    if (*it == keep) continue;
    used_ -= entries_[*it].bytes;
    entries_.erase(*it);
    it = order_.erase(it);
  }
}

void SubmapSlam2D::FieldCache::forget_from(int first) {
  for (auto it = order_.begin(); it != order_.end();) {
    if (*it < first) {
      ++it;
      continue;
    }
    used_ -= entries_[*it].bytes;
    entries_.erase(*it);
    it = order_.erase(it);
  }
}

void SubmapSlam2D::keep_closure_cells(int j) {
  // A finished submap's grid (12 bytes a cell, sized for the sensor's reach around every scan)
  // is only read again to build its loop-closure field, which needs one bit of each cell in its
  // region: keeping that (a byte a cell) and freeing the grid takes a long log from gigabytes
  // to megabytes (docs/performance.md). The field built from it is from_grid's, value for value.
  closure_cells_.resize(static_cast<std::size_t>(j));  // one link per submap, in order: a no-op
  closure_cells_.push_back(LikelihoodField::obstacles_of(frontend_.submaps()[j].grid, closure_region(j),
                                                         options_.frontend.field.occupied_threshold));
  frontend_.release_grid(j);
}

Eigen::Vector4d SubmapSlam2D::closure_region(int i) const {
  // The field over the submap's hits only (a submap grid is sized for the sensor's full reach).
  const Submap& sub = frontend_.submaps()[i];
  const std::vector<ScanEstimate>& est = frontend_.estimates();
  Eigen::Vector2d lo = sub.origin.head<2>(), hi = lo;
  if (i == 0 && start_map_) {  // the saved map's occupied extent
    lo = lo.cwiseMin(start_map_bounds_.head<2>());
    hi = hi.cwiseMax(start_map_bounds_.tail<2>());
  }
  for (int k : sub.scans) {
    const Pose2 p = pose_of(est[k].pose);
    const Points2 hits = hits_of(k);
    for (Eigen::Index n = 0; n < hits.rows(); ++n) {
      const Eigen::Vector2d q = p.transform_from(hits.row(n).transpose());
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  }
  const double margin = options_.frontend.field.truncation() + 2.0 * options_.frontend.resolution;
  return Eigen::Vector4d(lo.x() - margin, lo.y() - margin, hi.x() + margin, hi.y() + margin);
}

CorrelativeScanMatcher SubmapSlam2D::build_matcher(int i, int levels) {
  const double t0 = cpu_seconds();
  CorrelativeScanMatcher matcher(LikelihoodField::from_obstacles(closure_cells_[static_cast<std::size_t>(i)],
                                                                 options_.frontend.field),
                                 levels);
  timings_.closure_fields += cpu_seconds() - t0;
  ++timings_.closure_fields_built;
  return matcher;
}

const CorrelativeScanMatcher& SubmapSlam2D::closure_matcher(int i, double linear_window) {
  const ObstacleCells& cells = closure_cells_[static_cast<std::size_t>(i)];
  // The pyramid only as deep as this window needs (a search of a deeper one is the same
  // search): most windows are a few decimetres, and the deep levels, padded by their span,
  // are most of a field's bytes and build time.
  const int levels = std::min(kSearchLevels, CorrelativeScanMatcher::levels_for_window(linear_window, cells.resolution));
  const double fields_before = timings_.closure_fields, t_field = cpu_seconds();
  const CorrelativeScanMatcher& matcher =
      fields_->get(i, levels, cells.width, cells.height, [&](int depth) { return build_matcher(i, depth); });
  timings_.closure_fields = fields_before + (cpu_seconds() - t_field);  // a build's or a deepening's
  return matcher;
}

}  // namespace probslam
