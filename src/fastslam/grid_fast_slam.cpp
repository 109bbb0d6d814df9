#include "probslam/fastslam/grid_fast_slam.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <tuple>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/pose2_covariance.hpp"
#include "probslam/core/worker_pool.hpp"
#include "probslam/slam2d/correlative_scan_matcher.hpp"
#include "probslam/slam2d/cpu_clock.hpp"
#include "probslam/slam2d/likelihood_field.hpp"
#include "probslam/slam2d/scan_batch.hpp"
#include "probslam/slam2d/start_map.hpp"

namespace probslam {
namespace {

/// A particle's map grows to hold the usable-range disc around its pose plus this much (m), so
/// that its tile table is rebuilt every few metres of travel rather than every update.
constexpr double kGrowMargin = 10.0;
/// The filter's own random stream (resampling offsets) is stream number 2^63 of the seed, apart
/// from the particles' streams 0, 1, 2, ...
constexpr std::uint64_t kFilterStream = std::uint64_t{1} << 63;
/// Fewer particles than this per worker do not pay for waking a thread.
constexpr int kMinParticlesPerThread = 2;
/// Memory of one tile (its cells, and its control block: vtable, two counts, the
/// counting allocator's pointer pair) and of one tile-table slot, bytes: what the memory bound counts.
constexpr std::size_t kTileBytes = sizeof(TiledGrid2D::Tile) + 5 * sizeof(void*);
constexpr std::size_t kTableSlotBytes = sizeof(std::shared_ptr<TiledGrid2D::Tile>);

std::string gib(double bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g GiB", bytes / (1024.0 * 1024.0 * 1024.0));
  return text;
}

Eigen::Vector3d compose(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return Pose2::from_vector(a).compose(Pose2::from_vector(b)).vector();
}
Eigen::Vector3d between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return Pose2::from_vector(a).between(Pose2::from_vector(b)).vector();
}

/// x + L n for a standard normal n drawn from rng (L the Cholesky factor of `cov`).
Eigen::Vector3d gaussian_offset(const Eigen::Matrix3d& cov, ParticleRng& rng) {
  const Eigen::Matrix3d L = Eigen::LLT<Eigen::Matrix3d>(cov).matrixL();
  const double a = rng.normal(), b = rng.normal(), c = rng.normal();
  return L * Eigen::Vector3d(a, b, c);
}

}  // namespace

IncrementalScanMatcherOptions GridFastSlamOptions::default_corrector() {
  IncrementalScanMatcherOptions o;
  o.submap_distance = 5.0;  // "short stretches": the corrected odometry drifts like a 5 m submap
  // Every hit matched, as before issue 51's match_fraction: with 0.6 the short-range simulated
  // robots' rbpf gained (Stage-like office, the truth as odometry: 1.13 to 0.086 m ATE) but
  // ACES's relations went from 0.046 to 0.077 m.
  o.match_fraction = 1.0;
  // The correlative search for every scan, as before issue 54's local optimiser: the filter's
  // results move with small changes of its corrector (docs/performance.md), so switching it is
  // the RBPF's own step, to be judged over several seeds.
  o.search = FrontendSearch::kAlways;
  return o;
}

void GridFastSlamOptions::validate() const {
  require(num_particles >= 1 && num_particles <= kGridFastSlamMaxParticles, "num_particles",
          "must lie in [1, 100000]");
  require(proposal == GridProposal::kMotion || proposal == GridProposal::kScanMatching ||
              proposal == GridProposal::kImprovedOdometry,
          "proposal", "must be motion, scan-matching or improved-odometry");
  require_positive(resolution, "resolution");
  validate_group(filter, "filter");
  validate_group(odometry, "odometry");
  validate_group(likelihood, "likelihood");
  validate_group(matching, "matching");
  require(std::isfinite(weight_scale) && weight_scale > 0.0 && weight_scale <= 1.0, "weight_scale",
          "must lie in (0, 1]");
  require(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0,
          "resample_threshold", "must lie in [0, 1]");
  validate_group(update, "update");
  require(std::isfinite(update_interval) && update_interval >= 0.0, "update_interval", "must be finite and >= 0");
  if (uses_corrector()) validate_group(corrector, "corrector");
  require(threads >= 1 && threads <= 1024, "threads", "must lie in [1, 1024]");
  require_positive(max_map_bytes, "max_map_bytes");
}

GridFastSlamOptions GridFastSlamOptions::coupled() const {
  GridFastSlamOptions o = *this;
  o.corrector.resolution = resolution;
  o.corrector.filter = filter;
  o.corrector.odometry = odometry;
  return o;
}

GridFastSlam::GridFastSlam(const GridFastSlamOptions& options)
    : options_(options.coupled()),
      likelihood_((options_.validate(), options.likelihood), options.resolution),
      rng_(options.seed, kFilterStream) {
  check_particle_budget();  // before any particle is allocated
  if (options_.uses_corrector())
    corrector_ = std::make_unique<IncrementalScanMatcher>(options_.corrector);
  particles_.resize(static_cast<std::size_t>(options_.num_particles));
  for (std::size_t k = 0; k < particles_.size(); ++k) particles_[k].rng = ParticleRng(options_.seed, k);
  next_stream_ = particles_.size();
}

void GridFastSlam::check_particle_budget() {
  // Rule: bounded sizes. One update may clone, per particle, every tile of the usable-range disc
  // around its pose (rays end inside it) and copy its tile table: refuse a particle count whose
  // first update alone could exceed max_map_bytes, before any map exists.
  const double tile_m = TiledGrid2D::kTileSize * options_.resolution;
  const double reach = options_.filter.usable_range() + 1.0;
  const double disc_tiles = std::pow(std::ceil(2.0 * reach / tile_m) + 1.0, 2);
  footprint_bytes_ = disc_tiles * static_cast<double>(kTileBytes);
  const double side = 2.0 * (options_.filter.usable_range() + kGrowMargin) / tile_m + 1.0;
  const double per_particle = footprint_bytes_ + side * side * static_cast<double>(kTableSlotBytes);
  const double allowed = std::floor(options_.max_map_bytes / per_particle);
  if (static_cast<double>(options_.num_particles) > allowed)
    throw_invalid_argument("num_particles", "= " + std::to_string(options_.num_particles) +
                                                " could need " + gib(per_particle * options_.num_particles) +
                                                " of map tiles in one update (at this resolution and usable range), more "
                                                "than max_map_bytes = " + gib(options_.max_map_bytes) +
                                                ": lower num_particles (at most " + std::to_string(static_cast<long long>(allowed)) +
                                                " here) or max_usable_range / max_range, or raise resolution or max_map_bytes");
}

GridFastSlam::GridFastSlam(const GridFastSlam& other)
    : options_(other.options_),
      likelihood_(other.likelihood_),
      corrector_(other.corrector_ ? std::make_unique<IncrementalScanMatcher>(*other.corrector_) : nullptr),
      particles_(other.particles_),
      rng_(other.rng_),
      next_stream_(other.next_stream_),
      last_update_odometry_(other.last_update_odometry_),
      last_update_raw_(other.last_update_raw_),
      corrected_cov_(other.corrected_cov_),
      last_corrected_(other.last_corrected_),
      scan_step_(other.scan_step_),
      scan_offset_(other.scan_offset_),
      timestamps_(other.timestamps_),
      summary_(other.summary_),
      timings_(other.timings_),
      map_seconds_(other.map_seconds_),
      footprint_bytes_(other.footprint_bytes_),
      start_map_(other.start_map_),
      initial_pose_(other.initial_pose_) {
  std::vector<std::shared_ptr<TiledGrid2D>> maps;
  maps.reserve(particles_.size());
  for (const Particle& p : particles_) maps.push_back(p.map);
  maps = TiledGrid2D::deep_copy(maps);
  for (std::size_t k = 0; k < particles_.size(); ++k) particles_[k].map = std::move(maps[k]);
}

GridFastSlam::~GridFastSlam() = default;

void GridFastSlam::check_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                              const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const Eigen::Vector3d& odometry,
                              double timestamp, long row) const {
  check_scan_input(ranges, beam_angles, odometry, timestamp, row);
}

void GridFastSlam::add_scans(const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                             const Eigen::Ref<const RowMatrixXd>& odometry,
                             const Eigen::Ref<const Eigen::VectorXd>& timestamps) {
  add_scan_rows(*this, ranges, beam_angles, odometry, timestamps);
}

GridFastSlam::Snapshot GridFastSlam::snapshot() const {
  Snapshot s;
  if (corrector_) s.corrector = corrector_->snapshot();
  s.particles = particles_;
  s.rng = rng_;
  s.next_stream = next_stream_;
  s.last_update_odometry = last_update_odometry_;
  s.last_update_raw = last_update_raw_;
  s.last_corrected = last_corrected_;
  s.corrected_cov = corrected_cov_;
  s.scans = scan_step_.size();
  s.summary = summary_;
  return s;
}

void GridFastSlam::restore(Snapshot&& s) {
  if (corrector_ && s.corrector) corrector_->restore(std::move(*s.corrector));
  particles_ = std::move(s.particles);
  rng_ = s.rng;
  next_stream_ = s.next_stream;
  last_update_odometry_ = s.last_update_odometry;
  last_update_raw_ = s.last_update_raw;
  last_corrected_ = s.last_corrected;
  corrected_cov_ = s.corrected_cov;
  scan_step_.resize(s.scans);
  scan_offset_.resize(s.scans);
  timestamps_.resize(s.scans);
  summary_ = s.summary;
}

bool GridFastSlam::add_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                            const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const Eigen::Vector3d& odometry,
                            double timestamp) {
  check_scan(ranges, beam_angles, odometry, timestamp);
  // Phase 1, into temporaries: the object is unchanged should anything below throw.
  // The motion source: the odometry, or the odometry corrected by incremental scan matching
  // (prepared, committed with the update).
  std::optional<IncrementalScanMatcher::PendingScan> corrected;
  Eigen::Vector3d source = odometry;
  double t0 = cpu_seconds();
  if (corrector_) {
    corrected = corrector_->prepare(ranges, beam_angles, odometry, timestamp);
    source = corrected->est.pose;
  }
  double t1 = cpu_seconds();
  double corrector_seconds = t1 - t0;
  const Eigen::VectorXd insertion = ranges_for_insertion(ranges, options_.filter);
  timings_.filter += cpu_seconds() - t1;
  auto commit_scan = [&] {
    const double c0 = cpu_seconds();
    if (corrector_) {
      corrector_->commit(std::move(*corrected));
      release_corrector_grids();
    }
    timestamps_.push_back(timestamp);
    ++summary_.scans;
    timings_.corrector += corrector_seconds + cpu_seconds() - c0;
  };
  if (scan_step_.empty()) {
    // On a start map the first pose is in the map's frame; the motion after it is relative.
    const Eigen::Vector3d first_pose =
        start_map_ ? pose_on_start_map(scan_hits(ranges, beam_angles, options_.filter)) : source;
    std::shared_ptr<TiledGrid2D> map = start_map_ ? std::make_shared<TiledGrid2D>(*start_map_) : first_map(source);
    Eigen::Vector4d b;
    if (needs_growth(*map, first_pose, b)) map->grow_to_include(b[0], b[1], b[2], b[3]);  // before anything changes
    commit_scan();
    first_scan(std::move(map), insertion, beam_angles, first_pose);
    start_stretch(source, odometry, 0);
    return true;
  }
  Eigen::Matrix3d chain_cov = corrected_cov_;
  Eigen::Vector3d last_corrected = last_corrected_;
  if (corrector_ && corrected->est.matched) {
    // The chain of scan-matched steps since the last update, and its composed covariance.
    chain_cov = compose_covariance(between(last_update_odometry_, last_corrected_), corrected_cov_,
                                   between(last_corrected_, source), corrected->est.relative_covariance);
    last_corrected = source;
  }
  const Eigen::Vector3d delta = between(last_update_odometry_, source);
  const int step = static_cast<int>(summary_.updates);
  const bool timed = options_.update_interval > 0.0 && timestamp - last_update_time() >= options_.update_interval;
  if (!timed && !options_.update.reached(delta.head<2>().norm(), std::fabs(delta.z()))) {
    commit_scan();
    corrected_cov_ = chain_cov;
    last_corrected_ = last_corrected;
    scan_step_.push_back(step);
    scan_offset_.push_back(delta);
    return false;
  }
  Motion motion{delta, Eigen::Matrix3d::Zero(), std::nullopt};
  if (options_.proposal == GridProposal::kImprovedOdometry) {
    motion.cov = corrected_motion_covariance(source, chain_cov, last_corrected);
  } else {
    motion.delta = between(last_update_raw_, odometry);  // the raw odometry's motion model
    motion.cov = options_.odometry.covariance(motion.delta);
    if (corrector_) motion.start = delta;
  }
  motion.cov = 0.5 * (motion.cov + motion.cov.transpose());
  t0 = cpu_seconds();
  // The corrector filtered the scan already with the filter's options (coupled()): its hits, not
  // a second pass.
  const Points2 hits = corrector_ ? std::move(corrected->hits) : scan_hits(ranges, beam_angles, options_.filter);
  t1 = cpu_seconds();
  timings_.filter += t1 - t0;
  std::vector<Sampled> sampled = sample(hits, motion);
  check_update(sampled);
  timings_.proposal += cpu_seconds() - t1;
  // Phase 2: commit; nothing below throws.
  commit_scan();
  commit_update(std::move(sampled), insertion, beam_angles);
  start_stretch(source, odometry, step + 1);
  return true;
}

Eigen::Matrix3d GridFastSlam::corrected_motion_covariance(const Eigen::Vector3d& source, const Eigen::Matrix3d& chain_cov,
                                                          const Eigen::Vector3d& last_corrected) const {
  // Motion since the last matched scan is the raw odometry's: its noise on top, rotated into
  // the frame of the last update.
  const Eigen::Vector3d rest = between(last_corrected, source);
  const Eigen::Matrix3d R = frame_rotation(between(last_update_odometry_, last_corrected).z());
  Eigen::Matrix3d cov = chain_cov;
  if (!rest.isZero()) cov += R * options_.odometry.covariance(rest) * R.transpose();
  // A chain of perfectly matched steps may carry no rotation uncertainty at all: keep the
  // motion model's floors so the covariance stays positive definite.
  const OdometryNoise& n = options_.odometry;
  cov.diagonal() += Eigen::Vector3d(n.trans_floor * n.trans_floor, n.trans_floor * n.trans_floor, n.rot_floor * n.rot_floor);
  return cov;
}

double GridFastSlam::last_update_time() const {
  // The scans hang from the update before them in order: the first that hangs from the last
  // update is the scan it updated on.
  const auto first = std::lower_bound(scan_step_.begin(), scan_step_.end(), scan_step_.back());
  return timestamps_[static_cast<std::size_t>(first - scan_step_.begin())];
}

void GridFastSlam::start_stretch(const Eigen::Vector3d& source, const Eigen::Vector3d& raw, int step) {
  last_update_odometry_ = last_corrected_ = source;
  last_update_raw_ = raw;
  corrected_cov_.setZero();
  scan_step_.push_back(step);
  scan_offset_.push_back(Eigen::Vector3d::Zero());
}

void GridFastSlam::start_from_map(const OccupancyGrid2D& map, const Eigen::Vector3d& initial_pose) {
  require(scan_step_.empty() && !start_map_, "map", "is given before the first scan, and only once");
  check_start_map(map, options_.resolution, initial_pose);
  start_map_ = map;
  initial_pose_ = initial_pose;
  initial_pose_.z() = wrap_angle(initial_pose_.z());
}

Eigen::Vector3d GridFastSlam::pose_on_start_map(const Points2& points) const {
  if (points.rows() == 0) return initial_pose_;
  const MatchOptions m{};  // the default window; no prior: initial_pose is a guess within it
  LikelihoodFieldOptions f;
  f.sigma = options_.likelihood.sigma;
  f.p_rand = options_.likelihood.p_rand;
  // The field where the scan can land: its reach around the guess, widened by the window.
  const double reach = points.rowwise().norm().maxCoeff() + m.window.linear + f.truncation();
  const Eigen::Vector4d region(initial_pose_.x() - reach, initial_pose_.y() - reach, initial_pose_.x() + reach,
                               initial_pose_.y() + reach);
  int levels = 0;
  const double cells = 2.0 * std::ceil(m.window.linear / options_.resolution) + 1.0;
  while (levels < CorrelativeScanMatcher::kMaxLevel && (1 << levels) < cells) ++levels;
  const CorrelativeScanMatcher matcher(LikelihoodField::from_grid(*start_map_, region, f), levels);
  const MatchResult r = matcher.match(points, initial_pose_, m);
  return r.found ? r.pose : initial_pose_;
}

std::shared_ptr<TiledGrid2D> GridFastSlam::first_map(const Eigen::Vector3d& odometry) const {
  const double r = options_.filter.usable_range() + kGrowMargin;
  const OccupancyGrid2D prototype = OccupancyGrid2D::covering(odometry.x() - r, odometry.y() - r, odometry.x() + r,
                                                              odometry.y() + r, options_.resolution);
  return std::make_shared<TiledGrid2D>(prototype);
}

void GridFastSlam::first_scan(std::shared_ptr<TiledGrid2D> map, const Eigen::VectorXd& insertion,
                              const Eigen::Ref<const Eigen::VectorXd>& angles, const Eigen::Vector3d& odometry) {
  Particle& first = particles_.front();
  first.pose = odometry;
  first.map = std::move(map);
  insert(first, insertion, angles);
  first.path.push(odometry);
  const double lw = -std::log(static_cast<double>(particles_.size()));
  for (Particle& p : particles_) {
    if (&p != &first) {
      p.pose = first.pose;
      p.map = first.map;  // one map for all: shared, copied on the first write
      p.path = first.path;
    }
    p.log_weight = lw;
  }
}

bool GridFastSlam::needs_growth(const TiledGrid2D& map, const Eigen::Vector3d& pose, Eigen::Vector4d& bounds) const {
  const double r = options_.filter.usable_range() + 1.0;
  const Eigen::Vector2d lo = map.origin();
  const Eigen::Vector2d hi = lo + map.resolution() * Eigen::Vector2d(map.width(), map.height());
  if (pose.x() - r >= lo.x() && pose.y() - r >= lo.y() && pose.x() + r <= hi.x() && pose.y() + r <= hi.y())
    return false;
  const double m = r + kGrowMargin;
  bounds << pose.x() - m, pose.y() - m, pose.x() + m, pose.y() + m;
  return true;
}

void GridFastSlam::release_corrector_grids() {
  const int finished = static_cast<int>(corrector_->submaps().size()) - 1;
  for (int k = finished - 1; k >= 0; --k) {  // the newest first: older ones are released already
    const OccupancyGrid2D& g = corrector_->submaps()[static_cast<std::size_t>(k)].grid;
    if (g.width() == 1 && g.height() == 1) break;
    corrector_->release_grid(k);
  }
}

double GridFastSlam::insert(Particle& p, const Eigen::VectorXd& insertion,
                            const Eigen::Ref<const Eigen::VectorXd>& angles) const {
  double copy_seconds = 0.0;
  if (p.map.use_count() > 1) {
    const double t0 = cpu_seconds();
    p.map = std::make_shared<TiledGrid2D>(*p.map);  // its own tile table; the tiles stay shared
    copy_seconds = cpu_seconds() - t0;
  } else {
    std::atomic_thread_fence(std::memory_order_acquire);  // see TiledGrid2D::writable_tile
  }
  Eigen::Vector4d b;
  if (needs_growth(*p.map, p.pose, b)) p.map->grow_to_include(b[0], b[1], b[2], b[3]);  // checked by check_update
  p.map->insert_rays(p.pose, insertion, angles, options_.filter.usable_range());
  return copy_seconds;
}

template <typename Body>
void GridFastSlam::for_each_particle(const Body& body) {
  const int m = num_particles();
  const int workers = std::min(options_.threads, std::max(1, m / kMinParticlesPerThread));
  auto run = [&](std::size_t w) {
    const int begin = static_cast<int>(static_cast<long>(m) * static_cast<long>(w) / workers);
    const int end = static_cast<int>(static_cast<long>(m) * static_cast<long>(w + 1) / workers);
    for (int k = begin; k < end; ++k) body(static_cast<std::size_t>(k));
  };
  if (workers <= 1) {
    run(0);
    return;
  }
  if (!pool_ || static_cast<int>(pool_->size()) != workers) pool_ = std::make_unique<WorkerPool>(workers);
  pool_->run(run);
}

std::vector<GridFastSlam::Sampled> GridFastSlam::sample(const Points2& points, const Motion& motion) {
  const std::size_t n = particles_.size();
  std::vector<Sampled> out(n);
  if (options_.proposal != GridProposal::kScanMatching || points.rows() == 0) {
    for_each_particle([&](std::size_t k) { out[k] = sample_particle(particles_[k], nullptr, points, motion); });
    return out;
  }
  // Particles resampled from one parent hold its map and its pose until they update: their
  // proposals (a deterministic climb and fit on that map from that pose) are one, computed once
  // by the first of them (`source`); each then draws from it with its own stream.
  std::vector<std::size_t> order(n), source(n);
  for (std::size_t k = 0; k < n; ++k) order[k] = k;
  auto key = [&](std::size_t k) {
    const Particle& p = particles_[k];
    return std::make_tuple(p.map.get(), p.pose.x(), p.pose.y(), p.pose.z(), k);
  };
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = order[i];
    const bool same = i > 0 && particles_[order[i - 1]].map == particles_[k].map &&
                      particles_[order[i - 1]].pose == particles_[k].pose;
    source[k] = same ? source[order[i - 1]] : k;
  }
  std::vector<ScanProposal> proposals(n);
  for_each_particle([&](std::size_t k) {
    if (source[k] == k) proposals[k] = propose(particles_[k], points, motion);
  });
  for (std::size_t k = 0; k < n; ++k)
    if (source[k] == k) {
      ++timings_.proposals;
      timings_.proposal_local += proposals[k].local;
      timings_.proposal_evaluations += proposals[k].evaluations;
    }
  for_each_particle([&](std::size_t k) { out[k] = sample_particle(particles_[k], &proposals[source[k]], points, motion); });
  return out;
}

void GridFastSlam::check_update(const std::vector<Sampled>& sampled) const {
  double tables = 0.0, added = 0.0;
  for (std::size_t k = 0; k < particles_.size(); ++k) {
    const TiledGrid2D& map = *particles_[k].map;
    const double slots = static_cast<double>(map.tiles_x()) * map.tiles_y();
    double new_slots = particles_[k].map.use_count() > 1 ? slots : 0.0;  // the table copied
    Eigen::Vector4d b;
    if (needs_growth(map, sampled[k].pose, b)) {
      // Rule: bounded sizes, checked before the commit (a pure size computation, no allocation).
      if (map.cells_after_growth(b[0], b[1], b[2], b[3]) > static_cast<double>(OccupancyGrid2D::kMaxCells))
        throw_invalid_argument("odometry", "moves particle " + std::to_string(k) +
                                               " so far that its map would grow beyond OccupancyGrid2D.max_cells = " +
                                               std::to_string(OccupancyGrid2D::kMaxCells) + " cells");
      new_slots = map.tiles_after_growth(b[0], b[1], b[2], b[3]);
    }
    tables += slots * kTableSlotBytes;
    added += new_slots * kTableSlotBytes + footprint_bytes_;
  }
  // Tiles alive (the particles' maps are one family: copies of the first) plus every table,
  // plus what this update can add.
  const double live = static_cast<double>(particles_.front().map->live_tiles()) * kTileBytes + tables;
  if (live + added > options_.max_map_bytes)
    throw_invalid_argument("num_particles", "= " + std::to_string(num_particles()) + ": the particles' maps hold " +
                                                gib(live) + " and this update could add " + gib(added) +
                                                ", more than max_map_bytes = " + gib(options_.max_map_bytes) +
                                                ": lower num_particles or max_usable_range, or raise resolution or "
                                                "max_map_bytes");
}

void GridFastSlam::commit_update(std::vector<Sampled>&& sampled, const Eigen::VectorXd& insertion,
                                 const Eigen::Ref<const Eigen::VectorXd>& angles) {
  const double t0 = cpu_seconds();
  std::vector<double> copies(particles_.size(), 0.0);  // per particle: the workers write their own
  for_each_particle([&](std::size_t k) {
    Particle& p = particles_[k];
    p.pose = sampled[k].pose;
    p.log_weight = sampled[k].log_weight;
    p.rng = sampled[k].rng;
    copies[k] = insert(p, insertion, angles);
    p.path.push(p.pose);
  });
  const double t1 = cpu_seconds();
  timings_.map_update += t1 - t0;
  for (double c : copies) timings_.table_copies += c;
  for (const Sampled& s : sampled) {
    summary_.matched += s.matched;
    summary_.fallbacks += s.fallback;
  }
  ++summary_.updates;
  normalise_and_resample();
  timings_.resample += cpu_seconds() - t1;
}

ScanProposal GridFastSlam::propose(const Particle& p, const Points2& points, const Motion& motion) const {
  const Eigen::Vector3d predicted = compose(p.pose, motion.delta);
  const Eigen::Matrix3d R = frame_rotation(p.pose.z());
  const Eigen::Matrix3d prior_cov = R * motion.cov * R.transpose();
  return scan_matching_proposal(likelihood_, *p.map, points, predicted, 0.5 * (prior_cov + prior_cov.transpose()),
                                options_.matching,
                                motion.start ? std::optional<Eigen::Vector3d>(compose(p.pose, *motion.start)) : std::nullopt);
}

GridFastSlam::Sampled GridFastSlam::sample_particle(const Particle& p, const ScanProposal* q, const Points2& points,
                                                    const Motion& motion) const {
  Sampled s;
  s.rng = p.rng;
  s.log_weight = p.log_weight;
  if (q) {
    if (q->matched) {
      Eigen::Vector3d x = q->mean + gaussian_offset(q->covariance, s.rng);
      x.z() = wrap_angle(x.z());
      s.pose = x;
      // The normaliser estimates the integral of p(z | x, m) p(x | x_t-1, u), which the
      // motion-model fallback's p(z | x, m) estimates too: both weights are on one scale.
      s.log_weight += options_.weight_scale * q->log_normaliser;
      s.matched = true;
      return s;
    }
    s.fallback = true;
  }
  s.pose = compose(p.pose, motion.delta + gaussian_offset(motion.cov, s.rng));
  s.log_weight += options_.weight_scale * likelihood_.log_likelihood(*p.map, s.pose, points);
  return s;
}

void GridFastSlam::normalise_and_resample() {
  summary_.effective_sample_size = normalise_log_weights(particles_);
  if (!(summary_.effective_sample_size < options_.resample_threshold * num_particles())) return;
  resample_particles(particles_, rng_, options_.seed, next_stream_);  // O(1) copies: shared map and path
  ++summary_.resamples;
}

Poses2 GridFastSlam::poses() const { return particle_poses(particles_); }

Eigen::VectorXd GridFastSlam::log_weights() const { return particle_log_weights(particles_); }

int GridFastSlam::best_index() const { return heaviest_particle(particles_); }

Poses2 GridFastSlam::scan_poses(int particle) const {
  require(particle >= 0 && particle < num_particles(), "particle", "must be a particle index");
  const Poses2 steps = particles_[static_cast<std::size_t>(particle)].path.poses();
  Poses2 out(num_scans(), 3);
  for (int s = 0; s < num_scans(); ++s) {
    const Eigen::Vector3d at = steps.row(scan_step_[static_cast<std::size_t>(s)]).transpose();
    out.row(s) = compose(at, scan_offset_[static_cast<std::size_t>(s)]).transpose();
  }
  return out;
}

const TiledGrid2D& GridFastSlam::tiled_map(int particle) const {
  require(particle >= 0 && particle < num_particles(), "particle", "must be a particle index");
  require(particles_[static_cast<std::size_t>(particle)].map != nullptr, "particle", "has no map before the first scan");
  return *particles_[static_cast<std::size_t>(particle)].map;
}

OccupancyGrid2D GridFastSlam::map(int particle) const {
  const double t0 = cpu_seconds();
  OccupancyGrid2D grid = tiled_map(particle).to_grid();
  map_seconds_ += cpu_seconds() - t0;
  return grid;
}

GridFastSlamTimings GridFastSlam::timings() const {
  GridFastSlamTimings t = timings_;
  t.final_map = map_seconds_;
  if (corrector_) {
    t.corrector_local = corrector_->timings().local_matches;
    t.corrector_searches = corrector_->timings().searches;
  }
  return t;
}

TileSharing GridFastSlam::tile_sharing() const {
  std::vector<const TiledGrid2D*> grids;
  for (const Particle& p : particles_)
    if (p.map) grids.push_back(p.map.get());
  return TiledGrid2D::sharing(grids);
}

GridFastSlamSummary GridFastSlam::summary() const { return summary_; }

}  // namespace probslam
