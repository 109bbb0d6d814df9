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
  w.count(f_.poses.size());
  for (std::size_t j = 0; j < f_.poses.size(); ++j) {
    for (int c = 0; c < 3; ++c) w.f64(f_.poses[j][c]);
    w.f64(f_.log_weights[j]);
    f_.rngs[j].write_state(w);
  }
  f_.filter_rng.write_state(w);
  w.u64(f_.next_stream);
  w.matrix(f_.pending);
  for (double v : {f_.travel_d, f_.travel_a, f_.w_slow, f_.w_fast, f_.slow_raw, f_.fast_raw, f_.slow_mass, f_.fast_mass, f_.random_fraction})
    w.f64(v);
  w.i32(f_.low_updates);
  w.i32(f_.num_updates);
  w.matrix(f_.estimate);
  w.matrix(f_.covariance);
  w.f64(f_.cluster_weight);
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
  f.f_.poses.assign(m, Eigen::Vector3d::Zero());
  f.f_.log_weights.assign(m, 0.0);
  f.f_.rngs.clear();
  f.f_.rngs.reserve(m);
  for (std::size_t j = 0; j < m; ++j) {
    for (int c = 0; c < 3; ++c) f.f_.poses[j][c] = r.f64();
    f.f_.log_weights[j] = r.f64();
    f.f_.rngs.push_back(ParticleRng::read_state(r));
    // A log-weight may be -inf (a particle the scan ruled out), never NaN or +inf.
    if (!f.f_.poses[j].allFinite() || std::isnan(f.f_.log_weights[j]) || f.f_.log_weights[j] == HUGE_VAL)
      r.fail("particle " + std::to_string(j) + " holds a pose or weight that is not finite");
  }
  f.f_.filter_rng = ParticleRng::read_state(r);
  f.f_.next_stream = r.u64();
  f.f_.pending = r.matrix<Eigen::Vector3d>();
  for (double* v : {&f.f_.travel_d, &f.f_.travel_a, &f.f_.w_slow, &f.f_.w_fast, &f.f_.slow_raw, &f.f_.fast_raw, &f.f_.slow_mass,
                    &f.f_.fast_mass, &f.f_.random_fraction})
    if (!std::isfinite(*v = r.f64()) || *v < 0.0) r.fail("a travel or average is not finite and >= 0");
  f.f_.low_updates = r.i32();
  f.f_.num_updates = r.i32();
  if (f.f_.low_updates < 0 || f.f_.num_updates < 0) r.fail("a counter is negative");
  f.f_.estimate = r.matrix<Eigen::Vector3d>();
  f.f_.covariance = r.matrix<Eigen::Matrix3d>();
  if (!f.f_.pending.allFinite() || !f.f_.estimate.allFinite() || !f.f_.covariance.allFinite())
    r.fail("the pending motion or the estimate is not finite");
  // The estimate's share of the weight, which the convergence test reads: a fraction.
  f.f_.cluster_weight = r.f64();
  if (!(f.f_.cluster_weight >= 0.0 && f.f_.cluster_weight <= 1.0)) r.fail("the estimate's cluster weight is not in [0, 1]");
  return f;
}

void MonteCarloLocalization::save(const std::string& path) const { save_state(*this, path); }
MonteCarloLocalization MonteCarloLocalization::load(const std::string& path) {
  return load_state<MonteCarloLocalization>(path);
}

}  // namespace probslam
