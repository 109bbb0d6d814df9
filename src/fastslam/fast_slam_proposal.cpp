// FastSLAM 2.0's proposal: the Kalman-form step over one measurement, the free function
// fastslam2_proposal, drawing the pose from it and bridging the path to the drawn pose.
#include "fast_slam_internal.hpp"

#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"

namespace probslam {
using namespace fastslam_detail;

namespace fastslam_detail {

bool proposal_step(Eigen::Vector3d& mu, Eigen::Matrix3d& p, const Landmark& lm, const Eigen::Vector2d& z,
                   const Eigen::Matrix2d& q, double& log_likelihood) {
  Predicted pr;
  if (!predict_measurement(mu, lm.mean, pr)) return false;
  const Eigen::Vector2d nu = innovation(z, pr.z_hat);
  const Eigen::Matrix2d qj = symmetric<2>(pr.hm * lm.cov * pr.hm.transpose()) + q;
  const Eigen::Matrix2d s = symmetric<2>(pr.hx * p * pr.hx.transpose()) + qj;
  const Eigen::Matrix<double, 3, 2> k = p * pr.hx.transpose() * s.inverse();
  mu += k * nu;
  mu[2] = wrap_angle(mu[2]);
  p = symmetric<3>(p - k * s * k.transpose());
  log_likelihood = log_gauss2(nu, s);
  return true;
}

}  // namespace fastslam_detail

// ---- free functions ----

PoseProposal fastslam2_proposal(const Eigen::Vector3d& pose_mean, const Eigen::Matrix3d& pose_cov,
                                const Eigen::Vector2d& landmark_mean, const Eigen::Matrix2d& landmark_cov,
                                const Eigen::Vector2d& z, const Eigen::Matrix2d& measurement_noise) {
  require(on_map(pose_mean), "pose_mean", "must be finite with |x|, |y| <= 1e9 m (kMaxCoordinate)");
  require_covariance(pose_cov, "pose_cov", true);
  require(landmark_mean.allFinite() && landmark_mean.cwiseAbs().maxCoeff() <= kMaxCoordinate,
          "landmark_mean", "must be finite with |x|, |y| <= 1e9 m (kMaxCoordinate)");
  require_covariance(landmark_cov, "landmark_cov", true);
  require(z.allFinite() && z[0] >= 0.0 && z.cwiseAbs().maxCoeff() <= kMaxCoordinate, "z",
          "must be finite with a range in [0, 1e9]");
  require_covariance(measurement_noise, "measurement_noise", false);
  Landmark lm;
  lm.mean = landmark_mean;
  lm.cov = symmetric<2>(landmark_cov);
  PoseProposal out{pose_mean, symmetric<3>(pose_cov), 0.0};
  out.mean[2] = wrap_angle(out.mean[2]);
  require(proposal_step(out.mean, out.cov, lm, z, measurement_noise, out.log_likelihood), "landmark_mean",
          "coincides with the pose (no bearing)");
  require(out.mean.allFinite() && out.cov.allFinite() && std::isfinite(out.log_likelihood), "z",
          "gives a proposal that is not finite");
  return out;
}

void FastSlam::Context::bridge_path(FastSlamParticle& part, const Eigen::Vector3d& x) const {
  const std::size_t n = static_cast<std::size_t>(std::max(1, part.moves_since_update));
  const std::vector<Eigen::Vector3d> moved = part.path.newest(n);
  if (moved.empty() || moved.back() == x) return;  // a noise-free motion: nothing to move
  Eigen::Vector3d shift = x - moved.back();
  shift[2] = wrap_angle(shift[2]);
  for (std::size_t i = 0; i < moved.size(); ++i) part.path.pop();
  for (std::size_t i = 0; i + 1 < moved.size(); ++i) {
    Eigen::Vector3d y = moved[i] + shift * (static_cast<double>(i + 1) / static_cast<double>(moved.size()));
    y[2] = wrap_angle(y[2]);
    part.path.push(y);
  }
  part.path.push(x);
}

void FastSlam::Context::end_motion(FastSlamParticle& part) const {
  if (o.version == 2 && part.has_prior && o.record_path) bridge_path(part, part.pose);
  part.has_prior = false;
  part.moves_since_update = 0;
}

void FastSlam::Context::take_proposal_sample(FastSlamParticle& part, const Eigen::Vector3d& mu,
                                              const Eigen::Matrix3d& p) const {
  const Eigen::Matrix3d l = psd_factor<3>(p);
  const Eigen::Vector3d n(part.rng.normal(), part.rng.normal(), part.rng.normal());
  Eigen::Vector3d x = mu + l * n;
  x[2] = wrap_angle(x[2]);
  require(on_map(x), "z", "moves the pose beyond 1e9 m (kMaxCoordinate)");
  part.pose = x;
}

}  // namespace probslam
