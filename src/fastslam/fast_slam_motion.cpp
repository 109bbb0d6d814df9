// FastSLAM's motion: every particle moved by a sampled velocity or odometry step (in place,
// undone when a sample throws), with version 2's motion prior composed since the last update.
#include "fast_slam_internal.hpp"

#include <string>

#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "../core/odometry_step.hpp"

namespace probslam {
using namespace fastslam_detail;

template <class Sample>
void FastSlam::move_particles(int steps, Sample&& sample) {
  // One pass, in place (no particle is copied, so no shared node's count changes): worker k
  // keeps particle k's state in moves_[k], stamped with this call, before it moves the particle.
  // A sample that throws leaves its particle untouched (the path poses it appended are popped);
  // every particle already moved is then put back from moves_, so the call changes nothing.
  moves_.resize(particles_.size());
  const std::uint64_t stamp = ++move_calls_;
  try {
    for_particles([&](int k) {
      const auto i = static_cast<std::size_t>(k);
      FastSlamParticle& p = particles_[i];
      ParticleRng rng = p.rng;
      const Motion before{p.pose, p.prior_mean, p.prior_cov};
      Motion now = before;
      // Version 2: the motion prior composes from the last update's pose (has_prior: no update
      // since), so the proposal covers every motion between two updates.
      bool has_prior = p.has_prior;
      int moves = p.moves_since_update;
      int pushed = 0;
      try {
        for (int step = 0; step < steps; ++step) {
          Motion next;
          sample(step, now.pose, rng, next, o_.version == 2 && has_prior ? &now : nullptr);
          now.pose = next.pose;
          if (o_.version == 2) {
            now.prior_mean = next.prior_mean;
            now.prior_cov = next.prior_cov;
            moves = has_prior ? moves + 1 : 1;
            has_prior = true;
          }
          // Version 2's path holds the motion prior's mean: an update draws the pose and bridges
          // the poses since the last one to it (bridge_path), so they carry no noise of their own.
          if (o_.record_path) {
            p.path.push(o_.version == 2 ? next.prior_mean : next.pose);
            ++pushed;
          }
        }
      } catch (...) {
        for (; pushed > 0; --pushed) p.path.pop();
        throw;
      }
      moves_[i] = Move{before, p.rng, p.has_prior, p.moves_since_update, stamp, pushed};
      p.rng = rng;
      p.pose = now.pose;
      p.prior_mean = now.prior_mean;
      p.prior_cov = now.prior_cov;
      p.has_prior = has_prior;
      p.moves_since_update = moves;
    });
  } catch (...) {
    for (std::size_t i = 0; i < particles_.size(); ++i) {
      const Move& kept = moves_[i];
      if (kept.stamp != stamp) continue;
      FastSlamParticle& p = particles_[i];
      p.pose = kept.before.pose;
      p.prior_mean = kept.before.prior_mean;
      p.prior_cov = kept.before.prior_cov;
      p.rng = kept.rng;
      p.has_prior = kept.has_prior;
      p.moves_since_update = kept.moves_since_update;
      for (int n = 0; n < kept.pushed; ++n) p.path.pop();
    }
    throw;
  }
  last_ancestors_.clear();
}

void FastSlam::predict(double v, double w, double dt) {
  // Validates v, w, dt (finite, dt > 0) before anything changes.
  velocity_motion_jacobian(initial_pose_, v, w, dt);
  require(std::fabs(v * dt) <= kMaxCoordinate, "v", "* dt must be <= 1e9 m (kMaxCoordinate)");
  const Eigen::Matrix3d r = control_noise_ ? Eigen::Matrix3d::Zero() : Eigen::Matrix3d(motion_noise_);
  const Eigen::Matrix2d mc = control_noise_ ? Eigen::Matrix2d(motion_noise_) : Eigen::Matrix2d::Zero();
  move_particles(1, [&](int, const Eigen::Vector3d& x, ParticleRng& rng, Motion& mv, const Motion* since) {
    if (control_noise_) {
      const Eigen::Vector2d e = control_factor_ * Eigen::Vector2d(rng.normal(), rng.normal());
      mv.pose = velocity_motion(x, v + e[0], w + e[1], dt);
    } else {
      const Eigen::Vector3d e = motion_factor_ * Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
      mv.pose = velocity_motion(x, v, w, dt) + e;
      mv.pose[2] = wrap_angle(mv.pose[2]);
    }
    require(on_map(mv.pose), "v", "moves the robot beyond 1e9 m (kMaxCoordinate)");
    if (o_.version == 2) {
      const Eigen::Vector3d& from = since ? since->prior_mean : x;
      mv.prior_mean = velocity_motion(from, v, w, dt);
      if (control_noise_) {
        const Eigen::Matrix<double, 3, 2> vj = velocity_motion_control_jacobian(from, v, w, dt);
        mv.prior_cov = symmetric<3>(vj * mc * vj.transpose());
      } else {
        mv.prior_cov = r;
      }
      if (since) {
        const Eigen::Matrix3d g = velocity_motion_jacobian(from, v, w, dt);
        mv.prior_cov = symmetric<3>(g * since->prior_cov * g.transpose() + mv.prior_cov);
      }
    }
  });
}

void FastSlam::predict_odometry(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise) {
  require_odometry_step(delta, noise, "delta", "noise");
  const Eigen::Matrix3d cov = symmetric<3>(noise);
  odometry_steps({delta}, {cov}, {psd_factor<3>(cov)}, "delta");
}

void FastSlam::predict_odometry_batch(const Eigen::Ref<const RowMatrixXd>& deltas,
                                      const Eigen::Ref<const RowMatrixXd>& noises) {
  require_odometry_batch(deltas, noises);
  const auto n = static_cast<std::size_t>(deltas.rows());
  require(n <= static_cast<std::size_t>(std::numeric_limits<int>::max()), "deltas", "has too many rows");
  std::vector<Eigen::Vector3d> d(n);
  std::vector<Eigen::Matrix3d> covs(n), factors(n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto row = static_cast<Eigen::Index>(k);
    d[k] = deltas.row(row).transpose();
    const Eigen::Matrix3d noise = odometry_batch_noise(noises, row);
    const std::string dn = "deltas[" + std::to_string(k) + "]", nn = "noises[" + std::to_string(k) + "]";
    require_odometry_step(d[k], noise, dn.c_str(), nn.c_str());
    covs[k] = symmetric<3>(noise);
    factors[k] = psd_factor<3>(covs[k]);
  }
  if (n > 0) odometry_steps(d, covs, factors, "deltas");
}

void FastSlam::odometry_steps(const std::vector<Eigen::Vector3d>& deltas, const std::vector<Eigen::Matrix3d>& covs,
                              const std::vector<Eigen::Matrix3d>& factors, const char* name) {
  move_particles(static_cast<int>(deltas.size()), [&](int step, const Eigen::Vector3d& x, ParticleRng& rng, Motion& mv,
                                                      const Motion* since) {
    const auto k = static_cast<std::size_t>(step);
    const Eigen::Vector3d& delta = deltas[k];
    const Eigen::Matrix2d rx = rotation_matrix(x[2]);
    const Eigen::Vector3d d = delta + factors[k] * Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
    mv.pose.head<2>() = x.head<2>() + rx * d.head<2>();
    mv.pose[2] = wrap_angle(x[2] + d[2]);
    require(on_map(mv.pose), name, "moves the robot beyond 1e9 m (kMaxCoordinate)");
    if (o_.version == 2) {
      const Eigen::Vector3d& from = since ? since->prior_mean : x;
      const core_detail::OdometryStep prior = core_detail::odometry_step(from, delta);
      mv.prior_mean = prior.next;
      mv.prior_cov = symmetric<3>(prior.j * covs[k] * prior.j.transpose());
      if (since) mv.prior_cov = symmetric<3>(prior.g * since->prior_cov * prior.g.transpose() + mv.prior_cov);
    }
  });
}

}  // namespace probslam
