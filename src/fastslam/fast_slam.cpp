#include "probslam/fastslam/fast_slam.hpp"

#include "fast_slam_internal.hpp"

#include <unordered_set>
#include <utility>

#include "probslam/core/check.hpp"

namespace probslam {
using namespace fastslam_detail;
namespace {

// The filter's own random stream (resampling offsets): a stream number no particle reaches.
constexpr std::uint64_t kFilterStream = ~std::uint64_t{0};

}  // namespace

void FastSlamOptions::validate() const {
  require(num_particles >= 1 && num_particles <= kFastSlamMaxParticles, "num_particles",
          "must be in [1, 2^20] (kFastSlamMaxParticles)");
  require(version == 1 || version == 2, "version", "must be 1 or 2");
  require(threads >= 1 && threads <= kFastSlamMaxThreads, "threads", "must be in [1, 256] (kFastSlamMaxThreads)");
  require(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0,
          "resample_threshold", "must be in [0, 1]");
  require(std::isfinite(p_new) && p_new > 0.0 && std::isfinite(std::log(p_new)), "p_new", "must be finite and > 0");
  require(std::isfinite(outlier_density) && outlier_density >= 0.0, "outlier_density",
          "must be finite and >= 0 (0: no outlier model)");
  require(std::isfinite(association_radius) && association_radius >= 0.0 && association_radius <= kMaxCoordinate,
          "association_radius", "must be in [0, 1e9] m");
  require(std::isfinite(cell_size) && cell_size >= kMinHashCellSize && cell_size <= kMaxCoordinate, "cell_size",
          "must be in [1e-6, 1e9] m (kMinHashCellSize)");
  require(std::isfinite(existence_hit) && existence_hit >= 0.0 && existence_hit <= kMaxCoordinate, "existence_hit",
          "must be in [0, 1e9]");
  require(std::isfinite(existence_miss) && existence_miss >= 0.0 && existence_miss <= kMaxCoordinate,
          "existence_miss", "must be in [0, 1e9]");
  require(min_sightings >= 1 && min_sightings <= kFastSlamMaxCount, "min_sightings", "must be in [1, 1e6]");
  require(provisional_max_age >= 0 && provisional_max_age <= kFastSlamMaxCount, "provisional_max_age",
          "must be in [0, 1e6]");
  require(sensor_range > 0.0 && (std::isinf(sensor_range) || sensor_range <= kMaxCoordinate), "sensor_range",
          "must be > 0 m (and at most 1e9 m, or infinite)");
  require(!negative_information || std::isfinite(sensor_range), "sensor_range",
          "must be finite with negative_information");
  require(std::isfinite(sensor_fov) && sensor_fov > 0.0 && sensor_fov <= kTwoPi, "sensor_fov",
          "must be in (0, 2 pi] rad");
  require(std::isfinite(bearing_offset_sigma) && bearing_offset_sigma >= 0.0 && bearing_offset_sigma <= kPi,
          "bearing_offset_sigma", "must be in [0, pi] rad");
  require(std::isfinite(bearing_offset_correlation) && bearing_offset_correlation >= 0.0 &&
              bearing_offset_correlation < 1.0,
          "bearing_offset_correlation", "must be in [0, 1)");
}

FastSlam::FastSlam(const Eigen::MatrixXd& motion_noise, const Eigen::MatrixXd& measurement_noise,
                   const FastSlamOptions& options, const Eigen::Vector3d& initial_pose)
    : o_(options) {
  o_.validate();
  require((motion_noise.rows() == 3 && motion_noise.cols() == 3) || (motion_noise.rows() == 2 && motion_noise.cols() == 2),
          "motion_noise", "must be 3x3 (pose space) or 2x2 (control space)");
  require_covariance(motion_noise, "motion_noise", true);
  const int md = o_.use_signatures ? 3 : 2;
  require(measurement_noise.rows() == md && measurement_noise.cols() == md, "measurement_noise",
          o_.use_signatures ? "must be 3x3 (range, bearing, signature)" : "must be 2x2 (range, bearing)");
  require_covariance(measurement_noise, "measurement_noise", false);
  if (o_.use_signatures)
    require(measurement_noise(0, 2) == 0.0 && measurement_noise(1, 2) == 0.0 && measurement_noise(2, 0) == 0.0 &&
                measurement_noise(2, 1) == 0.0,
            "measurement_noise", "the signature must be uncorrelated with range and bearing (zero off-diagonal entries)");
  require(on_map(initial_pose), "initial_pose", "must be finite with |x|, |y| <= 1e9 m (kMaxCoordinate)");

  motion_noise_ = symmetric<Eigen::Dynamic>(motion_noise);
  control_noise_ = motion_noise_.rows() == 2;
  if (control_noise_) control_factor_ = psd_factor<2>(Eigen::Matrix2d(motion_noise_));
  else motion_factor_ = psd_factor<3>(Eigen::Matrix3d(motion_noise_));
  measurement_noise_ = symmetric<Eigen::Dynamic>(measurement_noise);
  q2_ = measurement_noise_.topLeftCorner<2, 2>();
  if (o_.use_signatures) q_signature_ = measurement_noise_(2, 2);
  initial_pose_ = initial_pose;
  initial_pose_[2] = wrap_angle(initial_pose_[2]);

  const int m = o_.num_particles;
  particles_.resize(static_cast<std::size_t>(m));
  for (int k = 0; k < m; ++k) {
    FastSlamParticle& p = particles_[static_cast<std::size_t>(k)];
    p.pose = initial_pose_;
    p.log_weight = -std::log(static_cast<double>(m));
    p.map = LandmarkMap(o_.cell_size);
    p.rng = ParticleRng(o_.seed, static_cast<std::uint64_t>(k));
    if (o_.bearing_offset_sigma > 0.0) p.bearing_offset = o_.bearing_offset_sigma * p.rng.normal();  // stationary
    if (o_.record_path) p.path.push(p.pose);
  }
  next_stream_ = static_cast<std::uint64_t>(m);
  rng_ = ParticleRng(o_.seed, kFilterStream);
}

FastSlam::FastSlam(const FastSlam& other)
    : o_(other.o_),
      motion_noise_(other.motion_noise_),
      measurement_noise_(other.measurement_noise_),
      initial_pose_(other.initial_pose_),
      motion_factor_(other.motion_factor_),
      control_factor_(other.control_factor_),
      control_noise_(other.control_noise_),
      q2_(other.q2_),
      q_signature_(other.q_signature_),
      particles_(other.particles_),
      rng_(other.rng_),
      next_stream_(other.next_stream_),
      resamples_(other.resamples_),
      last_resampled_(other.last_resampled_),
      last_ancestors_(other.last_ancestors_) {}

FastSlam& FastSlam::operator=(const FastSlam& other) {
  if (this != &other) {
    FastSlam copy(other);
    *this = std::move(copy);
  }
  return *this;
}

FastSlam::FastSlam(FastSlam&&) noexcept = default;
FastSlam& FastSlam::operator=(FastSlam&&) noexcept = default;
FastSlam::~FastSlam() = default;

const FastSlamParticle& FastSlam::particle(int k) const {
  require(k >= 0 && k < num_particles(), "index", "is not a particle index");
  return particles_[static_cast<std::size_t>(k)];
}

Poses2 FastSlam::poses() const { return particle_poses(particles_); }

Eigen::VectorXd FastSlam::log_weights() const { return particle_log_weights(particles_); }

Eigen::VectorXd FastSlam::per_particle(double FastSlamParticle::*field) const {
  Eigen::VectorXd out(num_particles());
  for (int k = 0; k < num_particles(); ++k) out[k] = particles_[static_cast<std::size_t>(k)].*field;
  return out;
}

Eigen::VectorXd FastSlam::last_log_likelihoods() const { return per_particle(&FastSlamParticle::last_log_likelihood); }

Eigen::VectorXd FastSlam::bearing_offsets() const { return per_particle(&FastSlamParticle::bearing_offset); }

double FastSlam::effective_sample_size() const {
  double s = 0.0;
  for (const FastSlamParticle& p : particles_) s += std::exp(2.0 * p.log_weight);
  return 1.0 / s;
}

int FastSlam::best_index() const { return heaviest_particle(particles_); }

Poses2 FastSlam::path(int k) const { return particle(k).path.poses(); }

Eigen::Vector3d FastSlam::mean_pose() const {
  double x = 0.0, y = 0.0, c = 0.0, s = 0.0;
  for (const FastSlamParticle& p : particles_) {
    const double w = std::exp(p.log_weight);
    x += w * p.pose[0];
    y += w * p.pose[1];
    c += w * std::cos(p.pose[2]);
    s += w * std::sin(p.pose[2]);
  }
  return {x, y, std::atan2(s, c)};
}

Eigen::Matrix3d FastSlam::pose_covariance() const {
  const Eigen::Vector3d mean = mean_pose();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const FastSlamParticle& p : particles_) {
    Eigen::Vector3d e = p.pose - mean;
    e[2] = wrap_angle(e[2]);
    cov += std::exp(p.log_weight) * e * e.transpose();
  }
  return symmetric<3>(cov);
}

std::vector<Landmark> FastSlam::landmarks(int k) const {
  std::vector<Landmark> out;
  const LandmarkMap& map = particle(k).map;
  out.reserve(map.size());
  map.for_each([&](const Landmark& lm) { out.push_back(lm); });
  std::sort(out.begin(), out.end(), [](const Landmark& a, const Landmark& b) { return a.id < b.id; });
  return out;
}

MapSharing FastSlam::map_sharing() const {
  MapSharing s;
  std::unordered_set<const void*> seen, path_seen;
  for (const FastSlamParticle& p : particles_) {
    s.distinct_nodes += p.map.collect_nodes(seen);
    s.total_nodes += p.map.num_nodes();
    s.landmarks += p.map.size();
    s.path_nodes += p.path.collect_nodes(path_seen);
  }
  return s;
}

}  // namespace probslam
