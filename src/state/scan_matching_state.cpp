// Likelihood fields and IncrementalScanMatcher as state (their options through describe(),
// core/options_description.hpp; docs/file_format.md).
#include <cmath>

#include "probslam/core/options_description.hpp"
#include "probslam/slam2d/incremental_scan_matcher.hpp"
#include "probslam/slam2d/likelihood_field.hpp"

namespace probslam {

void LikelihoodField::write_state(StateWriter& w) const {
  for (double v : {x0_, y0_, res_, inv_res_}) w.f64(v);
  w.i32(width_);
  w.i32(height_);
  w.i32(num_occupied_);
  write_options(w, options_);
  w.f32(floor_);
  w.floats(distance_);
  w.floats(log_likelihood_);
}

LikelihoodField LikelihoodField::read_state(StateReader& r) {
  LikelihoodField f;
  for (double* v : {&f.x0_, &f.y0_, &f.res_, &f.inv_res_}) *v = r.f64();
  f.width_ = r.i32();
  f.height_ = r.i32();
  f.num_occupied_ = r.i32();
  read_options(r, f.options_);
  f.floor_ = r.f32();
  validated(r, "likelihood field options", [&] { f.options_.validate(); });
  const std::vector<float> distance = r.floats(), log_likelihood = r.floats();
  f.distance_.assign(distance.begin(), distance.end());
  f.log_likelihood_.assign(log_likelihood.begin(), log_likelihood.end());
  const double cells = static_cast<double>(f.width_) * static_cast<double>(f.height_);
  if (f.width_ < 0 || f.height_ < 0 || static_cast<double>(f.distance_.size()) != cells ||
      f.log_likelihood_.size() != f.distance_.size() || !(f.res_ > 0.0) || f.inv_res_ != 1.0 / f.res_ ||
      !std::isfinite(f.inv_res_) || !std::isfinite(f.x0_) || !std::isfinite(f.y0_) || f.num_occupied_ < 0 ||
      static_cast<double>(f.num_occupied_) > cells)
    r.fail("a likelihood field's size or lattice is inconsistent");
  f.build_tables();
  return f;
}

void IncrementalScanMatcher::write_state(StateWriter& w) const {
  write_options(w, options_);
  w.count(estimates_.size());
  for (const ScanEstimate& e : estimates_) {
    w.matrix(e.pose);
    w.matrix(e.relative_covariance);
    w.f64(e.match_quality);
    w.boolean(e.matched);
    w.boolean(e.fallback);
    w.i32(e.submap);
    w.i32(e.points);
  }
  w.doubles(timestamps_);
  w.count(submaps_.size());
  for (const Submap& s : submaps_) {
    s.grid.write_state(w);
    w.matrix(s.origin);
    w.ints(s.scans);
    w.f64(s.travel);
    w.i32(s.matched);
  }
  w.matrix(matched_odometry_);
  w.matrix(matched_pose_);
  w.boolean(started_on_map_);
  const FieldCache& c = *field_cache_;
  w.boolean(c.matcher != nullptr);
  if (c.matcher) {
    c.matcher->field().write_state(w);
    w.i32(c.matcher->max_level());
  }
  w.i32(c.submap);
  w.i32(c.grid_width);
  w.i32(c.grid_height);
  w.matrix(c.built_at);
  w.matrix(c.region);
  w.matrix(c.grid_origin);
}

IncrementalScanMatcher IncrementalScanMatcher::read_state(StateReader& r) {
  IncrementalScanMatcherOptions o;
  read_options(r, o);
  IncrementalScanMatcher m = validated(r, "scan matcher options", [&] { return IncrementalScanMatcher(o); });
  const std::size_t n = r.count(24 + 88 + 8 + 2 + 8);
  m.estimates_.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    ScanEstimate e;
    e.pose = r.matrix<Eigen::Vector3d>();
    e.relative_covariance = r.matrix<Eigen::Matrix3d>();
    e.match_quality = r.f64();
    e.matched = r.boolean();
    e.fallback = r.boolean();
    e.submap = r.i32();
    e.points = r.i32();
    if (!e.pose.allFinite() || !e.relative_covariance.allFinite() || e.points < 0)
      r.fail("a scan's estimate is not finite");
    m.estimates_.push_back(e);
  }
  m.timestamps_ = r.doubles();
  if (m.timestamps_.size() != n) r.fail("the scan matcher holds a timestamp per scan");
  const std::size_t ns = r.count(100);
  for (std::size_t k = 0; k < ns; ++k) {
    OccupancyGrid2D grid = OccupancyGrid2D::read_state(r);
    Submap s{std::move(grid), r.matrix<Eigen::Vector3d>(), r.ints(), 0.0, 0};
    s.travel = r.f64();
    s.matched = r.i32();
    if (!s.origin.allFinite()) r.fail("a submap's origin is not finite");
    // A scan lies in the submap it names, or opened the next one there too (submaps overlap).
    const int submap = static_cast<int>(k);
    for (int scan : s.scans)
      if (scan < 0 || static_cast<std::size_t>(scan) >= n ||
          (m.estimates_[static_cast<std::size_t>(scan)].submap != submap &&
           m.estimates_[static_cast<std::size_t>(scan)].submap != submap - 1))
        r.fail("a submap names a scan out of range or of another submap");
    m.submaps_.push_back(std::move(s));
  }
  if (n > 0 && ns == 0) r.fail("the scan matcher holds scans but no submap");
  for (const ScanEstimate& e : m.estimates_)
    if (e.submap < -1 || e.submap >= static_cast<int>(ns)) r.fail("a scan names a submap out of range");
  m.matched_odometry_ = r.matrix<Eigen::Vector3d>();
  m.matched_pose_ = r.matrix<Eigen::Vector3d>();
  if (!m.matched_odometry_.allFinite() || !m.matched_pose_.allFinite()) r.fail("the last matched pose is not finite");
  m.started_on_map_ = r.boolean();
  auto cache = std::make_shared<FieldCache>();
  if (r.boolean()) {
    LikelihoodField field = LikelihoodField::read_state(r);
    const int levels = r.int_in(0, CorrelativeScanMatcher::kMaxLevel, "the matcher's pyramid levels");
    cache->matcher = std::make_shared<const CorrelativeScanMatcher>(std::move(field), levels);
  }
  cache->submap = r.i32();
  cache->grid_width = r.i32();
  cache->grid_height = r.i32();
  cache->built_at = r.matrix<Eigen::Vector3d>();
  cache->region = r.matrix<Eigen::Vector4d>();
  cache->grid_origin = r.matrix<Eigen::Vector2d>();
  if (cache->submap < -1 || cache->submap >= static_cast<int>(ns)) r.fail("the field cache names a submap out of range");
  m.field_cache_ = std::move(cache);
  return m;
}

void IncrementalScanMatcher::save(const std::string& path) const { save_state(*this, path); }
IncrementalScanMatcher IncrementalScanMatcher::load(const std::string& path) {
  return load_state<IncrementalScanMatcher>(path);
}

}  // namespace probslam
