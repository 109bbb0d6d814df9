#include "probslam/fastslam/grid_fast_slam.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/pose2_covariance.hpp"
#include "probslam/core/worker_pool.hpp"

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
  return o;
}

void GridFastSlamOptions::validate() const {
  require(num_particles >= 1 && num_particles <= kGridFastSlamMaxParticles, "num_particles",
          "must lie in [1, 100000]");
  require(proposal == GridProposal::kMotion || proposal == GridProposal::kScanMatching ||
              proposal == GridProposal::kImprovedOdometry,
          "proposal", "must be motion, scan-matching or improved-odometry");
  require_positive(resolution, "resolution");
  filter.validate();
  odometry.validate();
  likelihood.validate();
  matching.validate();
  require(std::isfinite(weight_scale) && weight_scale > 0.0 && weight_scale <= 1.0, "weight_scale",
          "must lie in (0, 1]");
  require(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0,
          "resample_threshold", "must lie in [0, 1]");
  require(std::isfinite(update_distance) && update_distance >= 0.0, "update_distance", "must be finite and >= 0");
  require(std::isfinite(update_angle) && update_angle >= 0.0, "update_angle", "must be finite and >= 0");
  if (uses_corrector()) corrector.validate();
  require(threads >= 1 && threads <= 1024, "threads", "must lie in [1, 1024]");
}

GridFastSlam::GridFastSlam(const GridFastSlamOptions& options)
    : options_((options.validate(), options)),
      likelihood_(options.likelihood, options.resolution),
      rng_(options.seed, kFilterStream) {
  if (options_.uses_corrector())
    corrector_ = std::make_unique<IncrementalScanMatcher>(options_.corrector);
  particles_.resize(static_cast<std::size_t>(options_.num_particles));
  for (std::size_t k = 0; k < particles_.size(); ++k) particles_[k].rng = ParticleRng(options_.seed, k);
  next_stream_ = particles_.size();
}

GridFastSlam::~GridFastSlam() = default;

bool GridFastSlam::add_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                            const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const Eigen::Vector3d& odometry,
                            double timestamp) {
  require_all_finite(odometry, "odometry");
  check_scan_shape(odometry, ranges, beam_angles);
  require(std::isfinite(timestamp), "timestamp", "must be finite");
  require(odometry.head<2>().cwiseAbs().maxCoeff() <= kGridFastSlamMaxCoordinate, "odometry",
          "coordinates must be <= 1e9 m");

  // The motion source: the odometry, or the odometry corrected by incremental scan matching.
  Eigen::Vector3d source = odometry;
  bool source_matched = false;
  Eigen::Matrix3d step_cov = Eigen::Matrix3d::Zero();
  if (corrector_) {
    const ScanEstimate e = corrector_->add_scan(ranges, beam_angles, odometry, timestamp);
    source = e.pose;
    source_matched = e.matched;
    step_cov = e.relative_covariance;
  }
  timestamps_.push_back(timestamp);
  ++summary_.scans;

  if (scan_step_.empty()) {
    first_scan(ranges_for_insertion(ranges, options_.filter), beam_angles, source);
    start_stretch(source, odometry, 0);
    return true;
  }
  if (corrector_ && source_matched) {
    // The chain of scan-matched steps since the last update, and its composed covariance.
    corrected_cov_ = compose_covariance(between(last_update_odometry_, last_corrected_), corrected_cov_,
                                        between(last_corrected_, source), step_cov);
    last_corrected_ = source;
  }
  const Eigen::Vector3d delta = between(last_update_odometry_, source);
  const int step = static_cast<int>(summary_.updates);
  if (delta.head<2>().norm() < options_.update_distance && std::fabs(delta.z()) < options_.update_angle) {
    scan_step_.push_back(step);
    scan_offset_.push_back(delta);
    return false;
  }
  Motion motion{delta, Eigen::Matrix3d::Zero(), std::nullopt};
  if (options_.proposal == GridProposal::kImprovedOdometry) {
    motion.cov = corrected_motion_covariance(source);
  } else {
    motion.delta = between(last_update_raw_, odometry);  // the raw odometry's motion model
    motion.cov = options_.odometry.covariance(motion.delta);
    if (corrector_) motion.start = delta;
  }
  motion.cov = 0.5 * (motion.cov + motion.cov.transpose());
  update(scan_hits(ranges, beam_angles, options_.filter), ranges_for_insertion(ranges, options_.filter), beam_angles,
         motion);
  start_stretch(source, odometry, step + 1);
  return true;
}

Eigen::Matrix3d GridFastSlam::corrected_motion_covariance(const Eigen::Vector3d& source) const {
  // Motion since the last matched scan is the raw odometry's: its noise on top, rotated into
  // the frame of the last update.
  const Eigen::Vector3d rest = between(last_corrected_, source);
  const Eigen::Matrix3d R = frame_rotation(between(last_update_odometry_, last_corrected_).z());
  Eigen::Matrix3d cov = corrected_cov_;
  if (!rest.isZero()) cov += R * options_.odometry.covariance(rest) * R.transpose();
  // A chain of perfectly matched steps may carry no rotation uncertainty at all: keep the
  // motion model's floors so the covariance stays positive definite.
  const OdometryNoise& n = options_.odometry;
  cov.diagonal() += Eigen::Vector3d(n.trans_floor * n.trans_floor, n.trans_floor * n.trans_floor, n.rot_floor * n.rot_floor);
  return cov;
}

void GridFastSlam::start_stretch(const Eigen::Vector3d& source, const Eigen::Vector3d& raw, int step) {
  last_update_odometry_ = last_corrected_ = source;
  last_update_raw_ = raw;
  corrected_cov_.setZero();
  scan_step_.push_back(step);
  scan_offset_.push_back(Eigen::Vector3d::Zero());
}

void GridFastSlam::first_scan(const Eigen::VectorXd& insertion, const Eigen::Ref<const Eigen::VectorXd>& angles,
                              const Eigen::Vector3d& odometry) {
  const double r = options_.filter.usable_range() + kGrowMargin;
  const OccupancyGrid2D prototype = OccupancyGrid2D::covering(odometry.x() - r, odometry.y() - r, odometry.x() + r,
                                                              odometry.y() + r, options_.resolution);
  Particle& first = particles_.front();
  first.pose = odometry;
  first.map = std::make_shared<TiledGrid2D>(prototype);
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

void GridFastSlam::insert(Particle& p, const Eigen::VectorXd& insertion, const Eigen::Ref<const Eigen::VectorXd>& angles) const {
  if (p.map.use_count() > 1) {
    p.map = std::make_shared<TiledGrid2D>(*p.map);  // its own tile table; the tiles stay shared
  } else {
    std::atomic_thread_fence(std::memory_order_acquire);  // see TiledGrid2D::writable_tile
  }
  const double r = options_.filter.usable_range() + 1.0;
  const Eigen::Vector2d lo = p.map->origin();
  const Eigen::Vector2d hi = lo + p.map->resolution() * Eigen::Vector2d(p.map->width(), p.map->height());
  if (p.pose.x() - r < lo.x() || p.pose.y() - r < lo.y() || p.pose.x() + r > hi.x() || p.pose.y() + r > hi.y()) {
    const double m = r + kGrowMargin;
    p.map->grow_to_include(p.pose.x() - m, p.pose.y() - m, p.pose.x() + m, p.pose.y() + m);
  }
  p.map->insert_rays(p.pose, insertion, angles, options_.filter.usable_range());
}

void GridFastSlam::update(const Points2& points, const Eigen::VectorXd& insertion,
                          const Eigen::Ref<const Eigen::VectorXd>& angles, const Motion& motion) {
  const int m = num_particles();
  const int workers = std::min(options_.threads, std::max(1, m / kMinParticlesPerThread));
  std::vector<long> matched(static_cast<std::size_t>(workers), 0), fallbacks(static_cast<std::size_t>(workers), 0);
  auto run = [&](std::size_t w) {
    const int begin = static_cast<int>(static_cast<long>(m) * static_cast<long>(w) / workers);
    const int end = static_cast<int>(static_cast<long>(m) * static_cast<long>(w + 1) / workers);
    for (int k = begin; k < end; ++k)
      update_particle(particles_[static_cast<std::size_t>(k)], points, insertion, angles, motion, matched[w],
                      fallbacks[w]);
  };
  if (workers <= 1) {
    run(0);
  } else {
    if (!pool_ || static_cast<int>(pool_->size()) != workers) pool_ = std::make_unique<WorkerPool>(workers);
    pool_->run(run);
  }
  for (int w = 0; w < workers; ++w) {
    summary_.matched += matched[static_cast<std::size_t>(w)];
    summary_.fallbacks += fallbacks[static_cast<std::size_t>(w)];
  }
  ++summary_.updates;
  normalise_and_resample();
}

void GridFastSlam::update_particle(Particle& p, const Points2& points, const Eigen::VectorXd& insertion,
                                   const Eigen::Ref<const Eigen::VectorXd>& angles, const Motion& motion, long& matched,
                                   long& fallbacks) const {
  bool done = false;
  if (options_.proposal == GridProposal::kScanMatching && points.rows() > 0) {
    const Eigen::Vector3d predicted = compose(p.pose, motion.delta);
    const Eigen::Matrix3d R = frame_rotation(p.pose.z());
    const Eigen::Matrix3d prior_cov = R * motion.cov * R.transpose();
    const ScanProposal q =
        scan_matching_proposal(likelihood_, *p.map, points, predicted, 0.5 * (prior_cov + prior_cov.transpose()),
                               options_.matching,
                               motion.start ? std::optional<Eigen::Vector3d>(compose(p.pose, *motion.start)) : std::nullopt);
    if (q.matched) {
      Eigen::Vector3d x = q.mean + gaussian_offset(q.covariance, p.rng);
      x.z() = wrap_angle(x.z());
      p.pose = x;
      // The normaliser estimates the integral of p(z | x, m) p(x | x_t-1, u), which the
      // motion-model fallback's p(z | x, m) estimates too: both weights are on one scale.
      p.log_weight += options_.weight_scale * q.log_normaliser;
      ++matched;
      done = true;
    } else {
      ++fallbacks;
    }
  }
  if (!done) {
    Eigen::Vector3d x = compose(p.pose, motion.delta + gaussian_offset(motion.cov, p.rng));
    p.pose = x;
    p.log_weight += options_.weight_scale * likelihood_.log_likelihood(*p.map, x, points);
  }
  insert(p, insertion, angles);
  p.path.push(p.pose);
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

OccupancyGrid2D GridFastSlam::map(int particle) const { return tiled_map(particle).to_grid(); }

TileSharing GridFastSlam::tile_sharing() const {
  std::vector<const TiledGrid2D*> grids;
  for (const Particle& p : particles_)
    if (p.map) grids.push_back(p.map.get());
  return TiledGrid2D::sharing(grids);
}

GridFastSlamSummary GridFastSlam::summary() const { return summary_; }

}  // namespace probslam
