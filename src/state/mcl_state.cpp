// MonteCarloLocalization's state (docs/file_format.md): the options, the map, and the filter:
// particles with their random streams, the augmented-MCL averages, the motion not yet applied
// and the estimate. The map's derived tables (free and occupied cells, the likelihood field or
// the beam model's map) are rebuilt from the map and options by the constructor, as a copy
// shares them.
#include <cmath>
#include <string>

#include "options_state.hpp"
#include "probslam/localization/monte_carlo_localization.hpp"

namespace probslam {
namespace {

void write_options(StateWriter& w, const MonteCarloLocalizationOptions& o) {
  state_detail::write_enum(w, o.sensor_model);
  for (double v : {o.odometry.alpha1, o.odometry.alpha2, o.odometry.alpha3, o.odometry.alpha4}) w.f64(v);
  for (double v : {o.occupied_threshold, o.free_threshold, o.sigma_hit, o.p_rand}) w.f64(v);
  const BeamMixture& b = o.beam;
  for (double v : {b.z_hit, b.z_short, b.z_max, b.z_rand, b.sigma_hit, b.lambda_short, b.max_range}) w.f64(v);
  w.f64(o.max_range);
  w.f64(o.min_range);
  w.i32(o.max_beams);
  w.f64(o.weight_scale);
  w.i32(o.min_particles);
  w.i32(o.max_particles);
  for (double v : {o.kld_epsilon, o.kld_z, o.bin_xy, o.bin_theta, o.alpha_slow, o.alpha_fast, o.recovery_ratio}) w.f64(v);
  w.i32(o.recovery_updates);
  w.i32(o.recovery_candidates);
  for (double v : {o.resample_threshold, o.update_min_d, o.update_min_a}) w.f64(v);
  w.u64(o.seed);
  w.i32(o.threads);
}

MonteCarloLocalizationOptions read_options(StateReader& r) {
  MonteCarloLocalizationOptions o;
  o.sensor_model = state_detail::read_enum(r, MclSensorModel::kBeam, "the sensor model");
  for (double* v : {&o.odometry.alpha1, &o.odometry.alpha2, &o.odometry.alpha3, &o.odometry.alpha4}) *v = r.f64();
  for (double* v : {&o.occupied_threshold, &o.free_threshold, &o.sigma_hit, &o.p_rand}) *v = r.f64();
  BeamMixture& b = o.beam;
  for (double* v : {&b.z_hit, &b.z_short, &b.z_max, &b.z_rand, &b.sigma_hit, &b.lambda_short, &b.max_range}) *v = r.f64();
  o.max_range = r.f64();
  o.min_range = r.f64();
  o.max_beams = r.i32();
  o.weight_scale = r.f64();
  o.min_particles = r.i32();
  o.max_particles = r.i32();
  for (double* v : {&o.kld_epsilon, &o.kld_z, &o.bin_xy, &o.bin_theta, &o.alpha_slow, &o.alpha_fast, &o.recovery_ratio})
    *v = r.f64();
  o.recovery_updates = r.i32();
  o.recovery_candidates = r.i32();
  for (double* v : {&o.resample_threshold, &o.update_min_d, &o.update_min_a}) *v = r.f64();
  o.seed = r.u64();
  o.threads = r.i32();
  return o;
}

// Bytes of one saved particle: pose, log-weight, random stream (four words, spare, flag).
constexpr std::size_t kParticleBytes = 3 * 8 + 8 + 4 * 8 + 8 + 1;

}  // namespace

void MonteCarloLocalization::write_state(StateWriter& w) const {
  write_options(w, options_);
  map_.write_state(w);
  w.count(poses_.size());
  for (std::size_t j = 0; j < poses_.size(); ++j) {
    for (int c = 0; c < 3; ++c) w.f64(poses_[j][c]);
    w.f64(log_weights_[j]);
    rngs_[j].write_state(w);
  }
  filter_rng_.write_state(w);
  w.u64(next_stream_);
  w.matrix(pending_);
  for (double v : {travel_d_, travel_a_, w_slow_, w_fast_, slow_raw_, fast_raw_, slow_mass_, fast_mass_, random_fraction_})
    w.f64(v);
  w.i32(low_updates_);
  w.i32(num_updates_);
  w.matrix(estimate_);
  w.matrix(covariance_);
  w.f64(cluster_weight_);
}

MonteCarloLocalization MonteCarloLocalization::read_state(StateReader& r) {
  const MonteCarloLocalizationOptions o = read_options(r);
  const OccupancyGrid2D map = OccupancyGrid2D::read_state(r);
  // The particles' bytes must be there before the constructor draws max_particles of its own.
  const std::size_t m = r.count(kParticleBytes);
  // The constructor checks the options and the map and builds the map's tables; its particles
  // are then replaced by the saved ones.
  MonteCarloLocalization f = validated(r, "options or map", [&] { return MonteCarloLocalization(map, o); });
  if (m < 1 || m > static_cast<std::size_t>(o.max_particles))
    r.fail("holds " + std::to_string(m) + " particles, outside [1, max_particles = " + std::to_string(o.max_particles) + "]");
  f.poses_.assign(m, Eigen::Vector3d::Zero());
  f.log_weights_.assign(m, 0.0);
  f.rngs_.clear();
  f.rngs_.reserve(m);
  for (std::size_t j = 0; j < m; ++j) {
    for (int c = 0; c < 3; ++c) f.poses_[j][c] = r.f64();
    f.log_weights_[j] = r.f64();
    f.rngs_.push_back(ParticleRng::read_state(r));
    // A log-weight may be -inf (a particle the scan ruled out), never NaN or +inf.
    if (!f.poses_[j].allFinite() || std::isnan(f.log_weights_[j]) || f.log_weights_[j] == HUGE_VAL)
      r.fail("particle " + std::to_string(j) + " holds a pose or weight that is not finite");
  }
  f.filter_rng_ = ParticleRng::read_state(r);
  f.next_stream_ = r.u64();
  f.pending_ = r.matrix<Eigen::Vector3d>();
  for (double* v : {&f.travel_d_, &f.travel_a_, &f.w_slow_, &f.w_fast_, &f.slow_raw_, &f.fast_raw_, &f.slow_mass_,
                    &f.fast_mass_, &f.random_fraction_})
    if (!std::isfinite(*v = r.f64()) || *v < 0.0) r.fail("a travel or average is not finite and >= 0");
  f.low_updates_ = r.i32();
  f.num_updates_ = r.i32();
  if (f.low_updates_ < 0 || f.num_updates_ < 0) r.fail("a counter is negative");
  f.estimate_ = r.matrix<Eigen::Vector3d>();
  f.covariance_ = r.matrix<Eigen::Matrix3d>();
  if (!f.pending_.allFinite() || !f.estimate_.allFinite() || !f.covariance_.allFinite())
    r.fail("the pending motion or the estimate is not finite");
  // The estimate's share of the weight, which the convergence test reads: a fraction.
  f.cluster_weight_ = r.f64();
  if (!(f.cluster_weight_ >= 0.0 && f.cluster_weight_ <= 1.0)) r.fail("the estimate's cluster weight is not in [0, 1]");
  return f;
}

void MonteCarloLocalization::save(const std::string& path) const { save_state(*this, path); }
MonteCarloLocalization MonteCarloLocalization::load(const std::string& path) {
  return load_state<MonteCarloLocalization>(path);
}

}  // namespace probslam
