// FastSlam's state (docs/file_format.md).
#include "probslam/core/options_description.hpp"
#include "probslam/core/state_file.hpp"
#include "probslam/fastslam/fast_slam.hpp"

namespace probslam {
namespace {

// Fewest bytes a saved particle takes (its fixed fields, an empty map and path).
constexpr double kMinParticleBytes = 200.0;

}  // namespace

void FastSlam::write_state(StateWriter& w) const {
  write_options(w, o_);
  w.matrix(motion_noise_);
  w.matrix(measurement_noise_);
  w.matrix(initial_pose_);
  w.matrix(motion_factor_);
  w.matrix(control_factor_);
  w.boolean(control_noise_);
  w.matrix(q2_);
  w.f64(q_signature_);
  w.count(particles_.size());
  for (const FastSlamParticle& p : particles_) {
    w.matrix(p.pose);
    w.f64(p.log_weight);
    w.f64(p.last_log_likelihood);
    p.map.write_state(w);
    p.path.write_state(w);
    p.rng.write_state(w);
    w.i64(p.next_id);
    w.boolean(p.has_prior);
    w.i32(p.moves_since_update);
    w.matrix(p.prior_mean);
    w.matrix(p.prior_cov);
    w.f64(p.bearing_offset);
    w.i64(p.scans);
    w.count(p.provisional.size());
    for (long id : p.provisional) w.i64(id);
  }
  rng_.write_state(w);
  w.u64(next_stream_);
  w.i64(resamples_);
  w.boolean(last_resampled_);
  w.ints(last_ancestors_);
}

FastSlam FastSlam::read_state(StateReader& r) {
  FastSlamOptions o;
  read_options(r, o);
  const auto motion_noise = r.matrix<Eigen::MatrixXd>();
  const auto measurement_noise = r.matrix<Eigen::MatrixXd>();
  const auto initial_pose = r.matrix<Eigen::Vector3d>();
  if (o.num_particles >= 1) r.require_bytes(kMinParticleBytes * o.num_particles, "the particles");
  // The constructor checks every option; its particles are then replaced by the saved ones.
  FastSlam f = validated(r, "options", [&] { return FastSlam(motion_noise, measurement_noise, o, initial_pose); });
  f.motion_factor_ = r.matrix<Eigen::Matrix3d>();
  f.control_factor_ = r.matrix<Eigen::Matrix2d>();
  f.control_noise_ = r.boolean();
  f.q2_ = r.matrix<Eigen::Matrix2d>();
  f.q_signature_ = r.f64();
  if (f.control_noise_ != (f.motion_noise_.rows() == 2)) r.fail("the motion noise's kind does not match the options");
  const std::size_t m = r.count(static_cast<std::size_t>(kMinParticleBytes));
  if (m != f.particles_.size()) r.fail("holds " + std::to_string(m) + " particles, its options " + std::to_string(f.particles_.size()));
  for (FastSlamParticle& p : f.particles_) {
    p.pose = r.matrix<Eigen::Vector3d>();
    p.log_weight = r.f64();
    p.last_log_likelihood = r.f64();
    p.map = LandmarkMap::read_state(r);
    p.path = PosePath::read_state(r);
    p.rng = ParticleRng::read_state(r);
    p.next_id = static_cast<long>(r.i64());
    p.has_prior = r.boolean();
    p.moves_since_update = r.i32();
    p.prior_mean = r.matrix<Eigen::Vector3d>();
    p.prior_cov = r.matrix<Eigen::Matrix3d>();
    p.bearing_offset = r.f64();
    p.scans = static_cast<long>(r.i64());
    p.provisional.resize(r.count(8));
    for (long& id : p.provisional) {
      id = static_cast<long>(r.i64());
      if (p.map.find(id) == nullptr) r.fail("a provisional landmark id is not in its particle's map");
    }
    if (p.scans < 0) r.fail("a particle's scan count is negative");
    if (!p.pose.allFinite() || !std::isfinite(p.log_weight) || !p.prior_mean.allFinite() || !p.prior_cov.allFinite() ||
        !std::isfinite(p.bearing_offset) || p.moves_since_update < 0)
      r.fail("a particle holds a value that is not finite or out of range");
    if (p.map.cell_size() != f.o_.cell_size) r.fail("a particle's map has another cell size than the options");
    if (f.o_.record_path && p.path.size() == 0) r.fail("a particle's path is empty although paths are recorded");
  }
  f.rng_ = ParticleRng::read_state(r);
  f.next_stream_ = r.u64();
  f.resamples_ = static_cast<long>(r.i64());
  f.last_resampled_ = r.boolean();
  f.last_ancestors_ = r.ints();
  for (int a : f.last_ancestors_)
    if (a < 0 || static_cast<std::size_t>(a) >= m) r.fail("an ancestor index is out of range");
  return f;
}

void FastSlam::save(const std::string& path) const { save_state(*this, path); }
FastSlam FastSlam::load(const std::string& path) { return load_state<FastSlam>(path); }

}  // namespace probslam
