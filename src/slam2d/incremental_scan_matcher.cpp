#include "probslam/slam2d/incremental_scan_matcher.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <string>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/chi_square.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/pose2_covariance.hpp"
#include "probslam/slam2d/cpu_clock.hpp"
#include "probslam/slam2d/scan_batch.hpp"
#include "probslam/slam2d/start_map.hpp"

namespace probslam {

namespace {

/// New and grown local maps get this much room beyond the scan (m), so that a grid is copied
/// to a larger one every few metres of travel rather than every scan.
constexpr double kGrowMargin = 10.0;
/// A field is built this far (m) beyond the region the scan needs: the next scans, a few cm
/// on, then land inside it and reuse it.
constexpr double kFieldRoom = 2.0;
/// A scan is matched on its near hits (match_fraction) only when it has at least this many:
/// fewer cannot fix three degrees of freedom against a noisy map.
constexpr Eigen::Index kMinMatchedHits = 20;
/// The constant-velocity prediction's velocity: the mean over this many matched motions.
constexpr int kVelocityScans = 5;
/// The constant-velocity prediction over a gap in the scans is at most this many times the last
/// motion: beyond, the last velocity says little about what happened in between.
constexpr double kMaxVelocityScale = 3.0;
/// A local match (options.search = fallback) is taken without the search only inside the
/// gates of this probability: its offset from the prediction within the prior's chi2 (3 dof)
/// quantile, its quality not below the last matched scan's by more than the one-sided normal
/// quantile times the standard error. 0.999: the 16.27 the closures' dissolution gate uses
/// (LoopClosureOptions::dissolve_chi2); a gate too strict costs a search, not accuracy.
constexpr double kLocalMatchProbability = 0.999;
/// The reference quality is the last matched scan's among the open submap's last this many.
constexpr int kReferenceScans = 10;

}  // namespace

void OdometryNoise::validate() const {
  for (const auto& [v, name] : {std::pair{trans_per_metre, "trans_per_metre"}, std::pair{trans_per_radian, "trans_per_radian"},
                                std::pair{rot_per_radian, "rot_per_radian"}, std::pair{rot_per_metre, "rot_per_metre"}})
    require(std::isfinite(v) && v >= 0.0, name, "must be finite and >= 0");
  require_positive(trans_floor, "trans_floor");
  require_positive(rot_floor, "rot_floor");
}

Eigen::Matrix3d OdometryNoise::covariance(const Eigen::Vector3d& delta) const {
  const double d = delta.head<2>().norm(), a = std::abs(delta.z());
  const double st = trans_per_metre * d + trans_per_radian * a + trans_floor;
  const double sr = rot_per_radian * a + rot_per_metre * d + rot_floor;
  return Eigen::Vector3d(st * st, st * st, sr * sr).asDiagonal();
}

void IncrementalScanMatcherOptions::validate() const {
  require_positive(resolution, "resolution");
  validate_group(filter, "filter");
  validate_group(field, "field");
  MatchOptions m = match;
  m.use_prior = false;
  validate_group(m, "match");
  validate_group(odometry, "odometry");
  require(std::isfinite(match_fraction) && match_fraction > 0.0 && match_fraction <= 1.0, "match_fraction",
          "must lie in (0, 1]");
  validate_group(update, "update");
  require(std::isfinite(submap_distance) && submap_distance >= 0.0, "submap_distance", "must be finite and >= 0");
  require(submap_scans >= 0, "submap_scans", "must be >= 0");
  require(std::isfinite(min_match_quality) && min_match_quality >= 0.0 && min_match_quality <= 1.0,
          "min_match_quality", "must be in [0, 1]");
  require(warmup_scans >= 1, "warmup_scans", "must be >= 1");
  require(std::isfinite(field_refresh_distance) && field_refresh_distance >= 0.0, "field_refresh_distance",
          "must be finite and >= 0");
  require(std::isfinite(field_refresh_angle) && field_refresh_angle >= 0.0, "field_refresh_angle",
          "must be finite and >= 0");
}

IncrementalScanMatcher::IncrementalScanMatcher(const IncrementalScanMatcherOptions& options) : options_(options) {
  options_.validate();
}

OccupancyGrid2D IncrementalScanMatcher::new_submap_grid(const Eigen::Vector3d& origin) const {
  const double r = options_.filter.usable_range() + kGrowMargin;
  return OccupancyGrid2D::covering(origin.x() - r, origin.y() - r, origin.x() + r, origin.y() + r, options_.resolution);
}

std::optional<OccupancyGrid2D> IncrementalScanMatcher::grown_for(const OccupancyGrid2D& grid, const Eigen::Vector3d& pose) const {
  // Every ray ends within the usable range: grow the grid to hold that disc, with room to spare.
  const double reach = options_.filter.usable_range();
  const Eigen::Vector2d lo = grid.origin();
  const Eigen::Vector2d hi = lo + grid.resolution() * Eigen::Vector2d(grid.width(), grid.height());
  if (pose.x() - reach >= lo.x() && pose.y() - reach >= lo.y() && pose.x() + reach <= hi.x() && pose.y() + reach <= hi.y())
    return std::nullopt;
  const double m = reach + kGrowMargin;
  try {
    return grid.grown_to_include(std::min(lo.x(), pose.x() - m), std::min(lo.y(), pose.y() - m),
                                        std::max(hi.x(), pose.x() + m), std::max(hi.y(), pose.y() + m));
  } catch (const std::invalid_argument& e) {
    // The grid's own message names its bounds; the user passed the odometry that led there.
    throw_invalid_argument("odometry", std::string("moves the scan so far that its submap grid ") + e.what());
  }
}

MatchResult IncrementalScanMatcher::match(const Submap& submap, const Points2& points, const Eigen::Vector3d& prior,
                                          const Eigen::Matrix3d& prior_cov, FieldCache& cache, bool use_prior,
                                          double reference_quality, bool& searched) const {
  MatchOptions m = options_.match;
  m.use_prior = use_prior;
  m.prior_covariance = prior_cov;
  // The field only where the scan can land: its points at the prior heading and at both ends
  // of the angular window (the arcs between bulge by at most r (1 - cos(window / 2))), widened
  // by the linear window and the field's reach.
  Eigen::Vector2d lo = prior.head<2>(), hi = prior.head<2>();
  for (double turn : {-m.window.angular, 0.0, m.window.angular}) {
    const Eigen::Matrix2d R = rotation_matrix(prior.z() + turn);
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
      const Eigen::Vector2d q = R * points.row(i).transpose() + prior.head<2>();
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  }
  const double bulge = points.rowwise().norm().maxCoeff() * (1.0 - std::cos(0.5 * m.window.angular));
  const double margin = m.window.linear + bulge + options_.field.truncation() + 2 * options_.resolution;
  const Eigen::Vector4d region(lo.x() - margin, lo.y() - margin, hi.x() + margin, hi.y() + margin);
  const std::shared_ptr<const CorrelativeScanMatcher> matcher = matcher_for(submap, region, prior, cache);
  // The local optimiser needs the prior: it is what places the scan along what the scan does not
  // fix, and what its innovation is measured against. A constant-velocity prediction is a guess,
  // not a measurement: started from it, the optimiser stays in its basin, and a short-range robot
  // without odometry lost the office loop (Stage-like, frontend alone: 0.51 m ATE searched, 3.96 m
  // local; docs/performance.md). Such a log keeps the search for every scan.
  if (options_.search == FrontendSearch::kFallback && use_prior && !options_.constant_velocity) {
    MatchResult local = matcher->local_match(points, prior, prior, m);
    if (local_match_holds(local, prior, prior_cov, reference_quality)) {
      searched = false;
      return local;
    }
  }
  searched = true;
  // The search's pyramid is built the first time a field is searched (the field is shared).
  const int levels = CorrelativeScanMatcher::levels_for_window(m.window.linear, options_.resolution);
  if (matcher->max_level() >= levels) return matcher->match(points, prior, m);
  cache.matcher = std::make_shared<const CorrelativeScanMatcher>(matcher->with_levels(levels));
  return cache.matcher->match(points, prior, m);
}

bool IncrementalScanMatcher::local_match_holds(const MatchResult& local, const Eigen::Vector3d& prior,
                                               const Eigen::Matrix3d& prior_cov, double reference_quality) const {
  static const double innovation_gate = chi_square_quantile(kLocalMatchProbability, 3);
  static const double quality_sigmas = std::sqrt(chi_square_quantile(2.0 * kLocalMatchProbability - 1.0, 1));
  if (!local.found || !(local.match_quality >= options_.min_match_quality)) return false;
  // Quality: a mean of N values in [0, 1] around q has a standard error of at most
  // sqrt(q (1 - q) / N); a local optimum in the wrong basin leaves many points off their walls.
  if (!std::isfinite(reference_quality)) return false;
  const double se = std::sqrt(reference_quality * (1.0 - reference_quality) / std::max(local.num_points, 1));
  if (local.match_quality < reference_quality - quality_sigmas * se) return false;
  // Innovation: the match's offset from the prediction, in the prior's Mahalanobis terms.
  Eigen::Vector3d d = local.pose - prior;
  d.z() = wrap_angle(d.z());
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(prior_cov);
  return ldlt.info() == Eigen::Success && d.dot(ldlt.solve(d)) <= innovation_gate;
}

double IncrementalScanMatcher::reference_quality() const {
  if (submaps_.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::vector<int>& scans = submaps_.back().scans;
  const int n = static_cast<int>(scans.size());
  for (int k = n - 1; k >= 0 && k >= n - kReferenceScans; --k) {
    const ScanEstimate& e = estimates_[static_cast<std::size_t>(scans[static_cast<std::size_t>(k)])];
    if (e.matched && e.match_quality > 0.0) return e.match_quality;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

std::shared_ptr<const CorrelativeScanMatcher> IncrementalScanMatcher::matcher_for(const Submap& submap,
                                                                                  const Eigen::Vector4d& region,
                                                                                  const Eigen::Vector3d& prior,
                                                                                  FieldCache& c) const {
  const int index = static_cast<int>(&submap - submaps_.data());
  const bool near = (prior.head<2>() - c.built_at.head<2>()).norm() < options_.field_refresh_distance &&
                    std::abs(wrap_angle(prior.z() - c.built_at.z())) < options_.field_refresh_angle;
  const bool fresh = c.matcher && near && c.submap == index && c.grid_origin == submap.grid.origin() &&
                     c.grid_width == submap.grid.width() && c.grid_height == submap.grid.height() &&
                     region[0] >= c.region[0] &&
                     region[1] >= c.region[1] && region[2] <= c.region[2] && region[3] <= c.region[3];
  if (fresh) return c.matcher;
  // Built with room to spare, so that the next scans land inside it too.
  const Eigen::Vector4d grown = region + Eigen::Vector4d(-kFieldRoom, -kFieldRoom, kFieldRoom, kFieldRoom);
  LikelihoodField field = LikelihoodField::from_grid(submap.grid, grown, options_.field);
  // The search's pyramid now, or (fallback) when a scan first needs the search on this field.
  const int levels = options_.search == FrontendSearch::kAlways
                         ? CorrelativeScanMatcher::levels_for_window(options_.match.window.linear, options_.resolution)
                         : 0;
  c.matcher = std::make_shared<const CorrelativeScanMatcher>(std::move(field), levels);
  c.submap = index;
  c.built_at = prior;
  c.region = grown;
  c.grid_origin = submap.grid.origin();
  c.grid_width = submap.grid.width();
  c.grid_height = submap.grid.height();
  return c.matcher;
}

void IncrementalScanMatcher::check_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                        const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                        const Eigen::Vector3d& odometry, double timestamp, long row) const {
  check_scan_input(ranges, beam_angles, odometry, timestamp, row);
}

ScanEstimate IncrementalScanMatcher::add_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                              const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                              const Eigen::Vector3d& odometry, double timestamp) {
  check_scan(ranges, beam_angles, odometry, timestamp);
  return commit(prepare(ranges, beam_angles, odometry, timestamp));
}

void IncrementalScanMatcher::add_scans(const Eigen::Ref<const RowMatrixXd>& ranges,
                                       const Eigen::Ref<const RowMatrixXd>& beam_angles,
                                       const Eigen::Ref<const RowMatrixXd>& odometry,
                                       const Eigen::Ref<const Eigen::VectorXd>& timestamps) {
  add_scan_rows(*this, ranges, beam_angles, odometry, timestamps);
}

IncrementalScanMatcher::PendingScan IncrementalScanMatcher::prepare(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                                                    const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                                                    const Eigen::Vector3d& odometry,
                                                                    double timestamp) const {
  PendingScan p;
  p.odometry = odometry;
  p.timestamp = timestamp;
  const double t0 = cpu_seconds();
  p.insertion = ranges_for_insertion(ranges, options_.filter);
  p.angles = beam_angles;
  ScanEstimate& est = p.est;
  p.hits = scan_hits(ranges, beam_angles, options_.filter);
  // A saved map is whole beyond the scan: its edge pulls nothing, every hit is matched on it.
  const Points2 points = started_on_map_ && submaps_.size() == 1 ? p.hits : matched_hits(p.hits);
  p.filter_seconds = cpu_seconds() - t0;
  est.points = static_cast<int>(points.rows());
  if (submaps_.empty()) {  // the map's frame is the first scan's odometry frame
    est.pose = odometry;
    est.pose.z() = wrap_angle(est.pose.z());
    est.matched = true;
    p.next = new_submap_grid(est.pose);
    est.submap = 0;
    return p;
  }
  // The first scan on a saved map: matched_pose_ holds the start pose, and the odometry has not
  // moved from anything yet.
  const bool on_map = awaits_first_scan_on_map();
  const Eigen::Vector3d delta = on_map ? Eigen::Vector3d::Zero()
                                : options_.constant_velocity
                                    ? last_motion(timestamp).value_or(Eigen::Vector3d::Zero())
                                    : Pose2::from_vector(matched_odometry_).between(Pose2::from_vector(odometry)).vector();
  // The constant-velocity prediction enters the score once there is a velocity: before (the
  // log's first scans), a robot that starts at speed would be held at "no motion".
  const bool prior_known = !options_.constant_velocity || last_motion(timestamp).has_value();
  const Eigen::Vector3d prior = Pose2::from_vector(matched_pose_).compose(Pose2::from_vector(delta)).vector();
  const Eigen::Matrix3d rel_cov = options_.odometry.covariance(delta);
  est.pose = prior;
  est.relative_covariance = rel_cov;
  p.moved = on_map || options_.update.reached(delta.head<2>().norm(), std::abs(delta.z()));
  if (!p.moved) return p;
  const Submap& cur = submaps_.back();
  const Eigen::Matrix3d J = frame_rotation(matched_pose_.z());
  if (points.rows() > 0 && (on_map || static_cast<int>(cur.scans.size()) >= options_.warmup_scans)) {
    const double t1 = cpu_seconds();
    auto cache = std::make_shared<FieldCache>(*field_cache_);
    const MatchResult r = match(cur, points, prior, J * rel_cov * J.transpose(), *cache,
                                options_.use_odometry_prior && !on_map && prior_known, reference_quality(),
                                p.searched);
    p.local = !p.searched;
    // A field of its own (a deeper pyramid on the cached field is no new field).
    p.field_built = !field_cache_->matcher || &cache->matcher->field() != &field_cache_->matcher->field();
    p.cache = std::move(cache);
    p.match_seconds = cpu_seconds() - t1;
    est.match_quality = r.match_quality;
    if (r.match_quality >= options_.min_match_quality) {
      est.pose = r.pose;
      // Into the earlier pose's frame; the first scan on a map has none: the map's frame.
      est.relative_covariance = on_map ? r.covariance : Eigen::Matrix3d(J.transpose() * r.covariance * J);
      est.matched = true;
    } else {
      est.fallback = true;
    }
  }
  // Travel as estimated, not as the odometry says: a log without odometry still moves.
  p.travel = on_map ? 0.0 : cur.travel + (est.pose.head<2>() - matched_pose_.head<2>()).norm();
  p.grid = grown_for(cur.grid, est.pose);
  est.submap = static_cast<int>(submaps_.size()) - 1;
  p.open_next = (options_.submap_distance > 0.0 && p.travel >= options_.submap_distance) ||
                (options_.submap_scans > 0 && cur.matched + est.matched >= options_.submap_scans);
  // The next submap starts here, with this scan in both: consecutive submaps overlap.
  if (p.open_next) p.next = new_submap_grid(est.pose);
  return p;
}

Points2 IncrementalScanMatcher::matched_hits(const Points2& hits) const {
  const double reach = options_.match_fraction * options_.filter.usable_range();
  if (!(reach < options_.filter.usable_range())) return hits;
  const double reach2 = reach * reach;
  Points2 out(hits.rows(), 2);
  Eigen::Index n = 0;
  for (Eigen::Index i = 0; i < hits.rows(); ++i)
    if (hits.row(i).squaredNorm() <= reach2) out.row(n++) = hits.row(i);
  // A scan that sees nothing that near (an open hall, a long corridor's end) keeps every hit:
  // matching the far ones beats falling back to the prediction.
  if (n < kMinMatchedHits) return hits;
  out.conservativeResize(n, 2);
  return out;
}

std::optional<Eigen::Vector3d> IncrementalScanMatcher::last_motion(double timestamp) const {
  // The motion over the last kVelocityScans scans that moved (every scan of a log without
  // odometry, whose update.distance is 0), in the frame of the earliest, scaled to the time since the
  // last: one scan's matched motion scatters by centimetres, their mean over a few does not.
  int last = -1, before = -1, seen = 0;
  for (int k = num_scans() - 1; k >= 0 && seen <= kVelocityScans; --k) {
    if (estimates_[static_cast<std::size_t>(k)].submap < 0) continue;
    if (last < 0) last = k;
    before = k;
    ++seen;
  }
  if (seen <= kVelocityScans) return std::nullopt;
  const Eigen::Vector3d m = Pose2::from_vector(estimates_[static_cast<std::size_t>(before)].pose)
                                .between(Pose2::from_vector(estimates_[static_cast<std::size_t>(last)].pose))
                                .vector();
  const double dt = timestamps_[static_cast<std::size_t>(last)] - timestamps_[static_cast<std::size_t>(before)];
  const double ahead = timestamp - timestamps_[static_cast<std::size_t>(last)];
  const double scale = dt > 0.0 ? std::clamp(ahead / dt, 0.0, kMaxVelocityScale) : 1.0;
  return m * scale;
}

ScanEstimate IncrementalScanMatcher::commit(PendingScan&& p) {
  const int index = num_scans();
  const double reach = options_.filter.usable_range();
  const double t0 = cpu_seconds();
  timings_.filter += p.filter_seconds;
  timings_.match += p.match_seconds;
  timings_.fields_built += p.field_built;
  timings_.local_matches += p.local;
  timings_.searches += p.searched;
  if (p.cache) field_cache_ = std::move(p.cache);
  if (p.moved) {
    Submap& cur = submaps_.back();
    if (p.grid) cur.grid = std::move(*p.grid);
    cur.travel = p.travel;
    cur.matched += p.est.matched;
    cur.grid.insert_rays(p.est.pose, p.insertion, p.angles, reach);
    cur.scans.push_back(index);
  }
  if (p.next) {
    submaps_.push_back(Submap{std::move(*p.next), p.est.pose, {}, 0.0, 0});
    submaps_.back().grid.insert_rays(p.est.pose, p.insertion, p.angles, reach);
    submaps_.back().scans.push_back(index);
  }
  if (p.moved || index == 0) {
    matched_odometry_ = p.odometry;
    matched_pose_ = p.est.pose;
  }
  estimates_.push_back(p.est);
  timestamps_.push_back(p.timestamp);
  timings_.insert += cpu_seconds() - t0;
  return p.est;
}

void IncrementalScanMatcher::release_grid(int k) {
  require(k >= 0 && k + 1 < static_cast<int>(submaps_.size()), "index", "is not a finished submap");
  const OccupancyGrid2D& g = submaps_[static_cast<std::size_t>(k)].grid;
  submaps_[static_cast<std::size_t>(k)].grid = OccupancyGrid2D(g.resolution(), 1, 1, g.origin(), g.p_prior(), g.clamp());
}

void IncrementalScanMatcher::replace_grid(int k, OccupancyGrid2D grid) {
  require(k >= 0 && k + 1 < static_cast<int>(submaps_.size()), "index", "is not a finished submap");
  submaps_[static_cast<std::size_t>(k)].grid = std::move(grid);
}

double IncrementalScanMatcher::grid_bytes() const {
  double b = 0.0;
  for (const Submap& s : submaps_)
    b += static_cast<double>(s.grid.width()) * s.grid.height() * (sizeof(double) + sizeof(std::uint32_t));
  return b;
}

void IncrementalScanMatcher::start_from_map(const OccupancyGrid2D& map, const Eigen::Vector3d& initial_pose) {
  require(estimates_.empty() && submaps_.empty(), "map", "is given before the first scan, and only once");
  check_start_map(map, options_.resolution, initial_pose);
  submaps_.push_back(Submap{map, Eigen::Vector3d::Zero(), {}, 0.0, 0});
  matched_pose_ = initial_pose;
  matched_pose_.z() = wrap_angle(matched_pose_.z());
  started_on_map_ = true;
}

IncrementalScanMatcher::Snapshot IncrementalScanMatcher::snapshot(bool copy_open_grid) const {
  Snapshot s;
  s.scans = estimates_.size();
  s.submaps = submaps_.size();
  if (!submaps_.empty()) {
    const Submap& open = submaps_.back();
    if (copy_open_grid) {
      s.open = open;
    } else {
      const OccupancyGrid2D& g = open.grid;
      s.open = Submap{OccupancyGrid2D(g.resolution(), 1, 1, g.origin(), g.p_prior(), g.clamp()), open.origin, open.scans,
                      open.travel, open.matched};
      s.open_grid_kept = false;
    }
  }
  s.matched_odometry = matched_odometry_;
  s.matched_pose = matched_pose_;
  s.cache = field_cache_;
  return s;
}

OccupancyGrid2D IncrementalScanMatcher::replayed_grid(std::size_t k, const ScanReplay& replay) const {
  const Submap& sub = submaps_[k];
  // As prepare and commit built it: a new submap's grid around its first scan (a saved map for
  // submap 0 of a run started on one), grown before each later scan is inserted where that scan
  // needs it (the first scan on a map too), each scan inserted at its estimate.
  const bool on_map = started_on_map_ && k == 0;
  OccupancyGrid2D grid = on_map ? *replay.start_map : new_submap_grid(sub.origin);
  const double reach = options_.filter.usable_range();
  for (std::size_t n = 0; n < sub.scans.size(); ++n) {
    const int s = sub.scans[n];
    const Eigen::Vector3d& pose = estimates_[static_cast<std::size_t>(s)].pose;
    if (on_map || n > 0) {
      if (std::optional<OccupancyGrid2D> grown = grown_for(grid, pose)) grid = std::move(*grown);
    }
    const auto [ranges, angles] = replay.scan(s);
    grid.insert_rays(pose, ranges_for_insertion(*ranges, options_.filter), *angles, reach);
  }
  return grid;
}

void IncrementalScanMatcher::restore(Snapshot&& s, const ScanReplay* replay) {
  require(s.open_grid_kept || !s.open || (replay && replay->scan && (!started_on_map_ || replay->start_map)), "replay",
          "is needed to restore a snapshot taken without the open submap's grid");
  estimates_.resize(s.scans);
  timestamps_.resize(s.scans);
  submaps_.erase(submaps_.begin() + static_cast<std::ptrdiff_t>(s.submaps), submaps_.end());
  if (s.open) submaps_.back() = std::move(*s.open);
  if (!s.open_grid_kept && s.open) submaps_.back().grid = replayed_grid(submaps_.size() - 1, *replay);
  matched_odometry_ = s.matched_odometry;
  matched_pose_ = s.matched_pose;
  field_cache_ = std::move(s.cache);
}

}  // namespace probslam
