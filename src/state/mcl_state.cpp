// MonteCarloLocalization's state (docs/file_format.md): the options, the map, and the filter:
// particles with their random streams, the augmented-MCL averages, the motion not yet applied
// and the estimate. The map's derived tables (free and occupied cells, the likelihood field or
// the beam model's map) are rebuilt from the map and options by the constructor, as a copy
// shares them.
#include <cmath>
#include <string>

#include "probslam/core/options_description.hpp"
#include "probslam/localization/monte_carlo_localization.hpp"

namespace probslam {
namespace {

// Bytes of one saved particle: pose, log-weight, random stream (four words, spare, flag).
constexpr std::size_t kParticleBytes = 3 * 8 + 8 + 4 * 8 + 8 + 1;

}  // namespace

void MonteCarloLocalization::write_state(StateWriter& w) const {
  write_options(w, options_);  // the fields in describe()'s order
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
  MonteCarloLocalizationOptions o;
  read_options(r, o);
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
