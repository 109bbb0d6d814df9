// SubmapSlam2D's state (docs/file_format.md).
#include <cmath>

#include "probslam/core/options_description.hpp"
#include "probslam/slam2d/submap_slam.hpp"

namespace probslam {
void SubmapSlam2D::write_state(StateWriter& w) const {
  write_options(w, options_);  // the fields in describe()'s order
  if (closure_cells_.empty()) {
    frontend_.write_state(w);
  } else {
    // The finished submaps' grids were released (keep_closure_cells): each is written as what was
    // kept of it, a grid over its closure region whose obstacle cells hold the clamp's maximum and
    // the rest the prior. read_state takes the same cells from it, so the format is unchanged and
    // a loaded object searches the same fields.
    IncrementalScanMatcher frontend = frontend_;
    for (std::size_t k = 0; k < closure_cells_.size(); ++k) {
      const ObstacleCells& c = closure_cells_[k];
      const OccupancyGrid2D& released = frontend_.submaps()[k].grid;
      if (c.width == 0 || c.height == 0) continue;  // nothing kept (a region off the grid): the 1 x 1 grid
      OccupancyGrid2D g(c.resolution, c.width, c.height, Eigen::Vector2d(c.x0, c.y0), released.p_prior(),
                        released.clamp());
      const double occupied = logit(options_.frontend.field.occupied_threshold);
      const double high = released.clamp().enabled && std::isfinite(released.clamp().max) &&
                                  released.clamp().max > occupied
                              ? released.clamp().max
                              : occupied + 1.0;
      for (std::size_t i = 0; i < c.cells.size(); ++i)
        if (c.cells[i]) g.data()[i] = high;
      frontend.replace_grid(static_cast<int>(k), std::move(g));
    }
    frontend.write_state(w);
  }
  // Each scan's hits: not kept (hits_of computes them from the ranges), written for the format.
  w.count(ranges_.size());
  for (std::size_t k = 0; k < ranges_.size(); ++k) w.matrix(hits_of(static_cast<int>(k)));
  w.count(offset_cov_.size());
  for (const Eigen::Matrix3d& c : offset_cov_) w.matrix(c);
  w.count(nodes_.size());
  for (const Eigen::Vector3d& n : nodes_) w.matrix(n);
  w.count(constraints_.size());
  for (const SubmapConstraint& c : constraints_) {
    w.i32(c.from);
    w.i32(c.to);
    w.matrix(c.measurement);
    w.matrix(c.covariance);
    w.boolean(c.loop);
    w.i32(c.scan);
    w.f64(c.match_quality);
    w.boolean(c.active);
  }
  w.count(ranges_.size());
  for (std::size_t k = 0; k < ranges_.size(); ++k) {
    w.matrix(ranges_[k]);
    w.matrix(*angles_[k]);
  }
  w.matrix(chain_pose_);
  w.matrix(chain_cov_);
  w.i32(chain_submap_);
  w.count(attempts_.size());
  for (const auto& [key, pose] : attempts_) {
    w.i32(key.first);
    w.i32(key.second);
    w.matrix(pose);
  }
  const SubmapSlamSummary& s = counts_;
  for (int v : {s.scans, s.submaps, s.matched_scans, s.closures_searched, s.closures_accepted, s.closures_rejected,
                s.closures_dissolved, s.rounds, s.optimizations})
    w.i32(v);
  w.f64(s.final_chi2);
  w.boolean(start_map_.has_value());
  if (start_map_) start_map_->write_state(w);
}

SubmapSlam2D SubmapSlam2D::read_state(StateReader& r) {
  SubmapSlamOptions o;
  read_options(r, o);
  SubmapSlam2D s = validated(r, "options", [&] { return SubmapSlam2D(o); });
  s.frontend_ = IncrementalScanMatcher::read_state(r);
  const std::size_t scans = static_cast<std::size_t>(s.frontend_.num_scans());
  const std::size_t np = r.count(16);
  std::vector<Points2> hits;  // checked against the ranges below (the object computes them from those)
  for (std::size_t k = 0; k < np; ++k) hits.push_back(r.matrix<Points2>());
  for (const Points2& p : hits)
    if (!p.allFinite()) r.fail("a scan's hits are not finite");
  // Every per-scan and per-submap list must hold one entry per scan / submap before any is used
  // (the loop-closure search indexes them by scan and by submap).
  if (np != scans) r.fail("the hits stored do not match the frontend's scans");
  const std::size_t nc = r.count(88);
  if (nc != scans) r.fail("the scans' offset covariances do not match the frontend's scans");
  for (std::size_t k = 0; k < nc; ++k) s.offset_cov_.push_back(r.matrix<Eigen::Matrix3d>());
  const std::size_t nn = r.count(40);
  // A node per submap once a scan is in (the first scan places node 0, each new submap its own).
  if (nn != (scans > 0 ? s.frontend_.submaps().size() : 0))
    r.fail("the graph's nodes do not match the frontend's submaps");
  for (std::size_t k = 0; k < nn; ++k) s.nodes_.push_back(r.matrix<Eigen::Vector3d>());
  for (std::size_t k = 0; k < nc; ++k)
    if (!s.offset_cov_[k].allFinite()) r.fail("a scan's offset covariance is not finite");
  for (std::size_t k = 0; k < nn; ++k)
    if (!s.nodes_[k].allFinite()) r.fail("a submap's node is not finite");
  const int nodes = static_cast<int>(nn);
  const std::size_t ne = r.count(150);
  for (std::size_t k = 0; k < ne; ++k) {
    SubmapConstraint c;
    c.from = r.i32();
    c.to = r.i32();
    c.measurement = r.matrix<Eigen::Vector3d>();
    c.covariance = r.matrix<Eigen::Matrix3d>();
    c.loop = r.boolean();
    c.scan = r.i32();
    c.match_quality = r.f64();
    c.active = r.boolean();
    if (c.from < 0 || c.from >= nodes || c.to < 0 || c.to >= nodes || c.scan < -1 || c.scan >= static_cast<int>(scans))
      r.fail("a constraint names a submap or scan out of range");
    if (!c.measurement.allFinite() || !c.covariance.allFinite()) r.fail("a constraint is not finite");
    s.constraints_.push_back(c);
  }
  const std::size_t ns = r.count(32);
  if (ns != scans) r.fail("the scans stored do not match the frontend's");
  for (std::size_t k = 0; k < ns; ++k) {
    s.ranges_.push_back(r.matrix<Eigen::VectorXd>());
    s.keep_angles(r.matrix<Eigen::VectorXd>());
    if (s.ranges_.back().size() != s.angles_.back()->size()) r.fail("a scan has not one angle per range");
    if (!s.angles_.back()->allFinite()) r.fail("a scan's beam angles are not finite");
    const Points2 computed = s.hits_of(static_cast<int>(k));
    if (computed.rows() != hits[k].rows() || computed != hits[k]) r.fail("a scan's hits do not follow from its ranges");
    s.hit_counts_.push_back(static_cast<int>(computed.rows()));
    hits[k] = Points2();
  }
  s.chain_pose_ = r.matrix<Eigen::Vector3d>();
  s.chain_cov_ = r.matrix<Eigen::Matrix3d>();
  s.chain_submap_ = r.i32();
  if (!s.chain_pose_.allFinite() || !s.chain_cov_.allFinite()) r.fail("the open chain's pose is not finite");
  const std::size_t na = r.count(48);
  for (std::size_t k = 0; k < na; ++k) {
    const int scan = r.i32(), submap = r.i32();
    const Eigen::Vector3d predicted = r.matrix<Eigen::Vector3d>();
    if (scan < 0 || static_cast<std::size_t>(scan) >= scans || submap < 0 || submap >= nodes)
      r.fail("a searched pair names a scan or submap out of range");
    if (!predicted.allFinite()) r.fail("a searched pair's prediction is not finite");
    if (!s.attempts_.emplace(std::make_pair(scan, submap), predicted).second) r.fail("a searched pair is repeated");
  }
  SubmapSlamSummary& c = s.counts_;
  for (int* v : {&c.scans, &c.submaps, &c.matched_scans, &c.closures_searched, &c.closures_accepted,
                 &c.closures_rejected, &c.closures_dissolved, &c.rounds, &c.optimizations})
    if ((*v = r.i32()) < 0) r.fail("a counter is negative");
  c.final_chi2 = r.f64();
  if (r.boolean()) s.set_start_map(OccupancyGrid2D::read_state(r));
  if (s.frontend_.awaits_first_scan_on_map() && !s.start_map_)
    r.fail("the frontend waits for its first scan on a map the state does not hold");
  if (s.chain_submap_ < 0 || static_cast<std::size_t>(s.chain_submap_) > s.frontend_.submaps().size())
    r.fail("the open chain does not match the frontend's submaps");
  // The finished submaps' obstacle cells, as add_scan keeps them (a file written before they were
  // kept holds the whole grids: the same cells).
  for (int k = 0; k + 1 < static_cast<int>(nn); ++k) s.keep_closure_cells(k);
  return s;
}

void SubmapSlam2D::save(const std::string& path) const { save_state(*this, path); }
SubmapSlam2D SubmapSlam2D::load(const std::string& path) { return load_state<SubmapSlam2D>(path); }

}  // namespace probslam
