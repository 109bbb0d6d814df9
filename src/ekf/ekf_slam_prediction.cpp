// EKF SLAM's prediction (Table 10.1 lines 2-5): the velocity and odometry motion models, with
// the covariance's robot rows and columns planned first and written only when finite.
#include "ekf_slam_internal.hpp"

#include <cmath>
#include <string>

#include "probslam/core/angle.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "../core/odometry_step.hpp"

namespace probslam {
using namespace ekf_detail;

// Table 10.1 line 5 exploiting G = I + F_x^T g F_x: only robot rows and columns change. Both
// are computed first and written only when finite.
EkfSlam::Motion EkfSlam::plan_motion(const Eigen::Vector3d& new_pose, const Eigen::Matrix3d& g,
                                     const Eigen::Matrix3d& r) const {
  const Eigen::MatrixXd& p = s_->cov;
  const Eigen::Matrix3d prr = g * p.topLeftCorner<3, 3>() * g.transpose() + r;
  Motion m{new_pose, 0.5 * (prr + prr.transpose()), g * p.block(0, 3, 3, n_ - 3), g};
  require(m.prr.allFinite() && m.prm.allFinite() && m.prr.cwiseAbs().maxCoeff() <= kMaxCovarianceEntry, "noise",
          "and the motion would make the covariance too large to stay finite");
  return m;
}

void EkfSlam::apply(const Motion& motion) {
  Eigen::MatrixXd& p = s_->cov;
  const Eigen::Index m = n_ - 3;
  p.topLeftCorner<3, 3>() = motion.prr;
  p.block(0, 3, 3, m) = motion.prm;
  p.block(3, 0, m, 3) = motion.prm.transpose();
  s_->mean.head<3>() = motion.pose;
}

void EkfSlam::predict(double v, double w, double dt) {
  predict(v, w, dt, control_noise_ ? Eigen::MatrixXd(m_control_) : Eigen::MatrixXd(r_pose_));
}

void EkfSlam::predict(double v, double w, double dt, const Eigen::MatrixXd& noise) {
  apply(plan_predict(v, w, dt, noise));
}

EkfSlam::Motion EkfSlam::plan_predict(double v, double w, double dt, const Eigen::MatrixXd& noise) const {
  const Eigen::Vector3d x = pose();
  const Eigen::Matrix3d g = velocity_motion_jacobian(x, v, w, dt);  // validates v, w, dt
  require(std::fabs(v * dt) <= kMaxCoordinate, "v", "* dt must be <= 1e9 m (kMaxCoordinate)");
  require_motion_noise(noise, "noise", true);
  Eigen::Matrix3d r = noise.rows() == 3 ? Eigen::Matrix3d(noise) : Eigen::Matrix3d::Zero();
  if (noise.rows() == 2) {
    const Eigen::Matrix<double, 3, 2> vj = velocity_motion_control_jacobian(x, v, w, dt);
    r = vj * noise * vj.transpose();
  }
  const Eigen::Vector3d next = velocity_motion(x, v, w, dt);
  require_on_map(next, "v", "moves the robot beyond 1e9 m (kMaxCoordinate)");
  return plan_motion(next, g, r);
}

namespace {
// One odometry step from pose x: the new pose, the motion's Jacobian G and the noise's J N J^T;
// predict_odometry's checks, naming `delta_name` / `noise_name`.
struct OdometryMotion {
  Eigen::Vector3d next;
  Eigen::Matrix3d g, r;
};
OdometryMotion odometry_motion(const Eigen::Vector3d& x, const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise,
                               const char* delta_name, const char* noise_name) {
  require_odometry_step(delta, noise, delta_name, noise_name);
  const core_detail::OdometryStep step = core_detail::odometry_step(x, delta);
  const OdometryMotion s{step.next, step.g, step.j * noise * step.j.transpose()};
  require_on_map(s.next, delta_name, "moves the robot beyond 1e9 m (kMaxCoordinate)");
  return s;
}
}  // namespace

void EkfSlam::predict_odometry(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise) {
  const OdometryMotion s = odometry_motion(pose(), delta, noise, "delta", "noise");
  apply(plan_motion(s.next, s.g, s.r));
}

Poses2 EkfSlam::predict_odometry_batch(const Eigen::Ref<const RowMatrixXd>& deltas,
                                       const Eigen::Ref<const RowMatrixXd>& noises) {
  require_odometry_batch(deltas, noises);
  const Eigen::Index n = deltas.rows();
  Poses2 poses(n, 3);
  if (n == 0) return poses;
  Eigen::Vector3d x = pose();
  Eigen::Matrix3d prr = s_->cov.topLeftCorner<3, 3>();
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();  // the steps' Jacobians, composed
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Matrix3d noise = odometry_batch_noise(noises, k);
    const std::string dn = "deltas[" + std::to_string(k) + "]", nn = "noises[" + std::to_string(k) + "]";
    const OdometryMotion s = odometry_motion(x, deltas.row(k).transpose(), noise, dn.c_str(), nn.c_str());
    const Eigen::Matrix3d next = s.g * prr * s.g.transpose() + s.r;  // plan_motion's, step by step
    prr = 0.5 * (next + next.transpose());
    require(prr.allFinite() && prr.cwiseAbs().maxCoeff() <= kMaxCovarianceEntry, nn.c_str(),
            "and the motion would make the covariance too large to stay finite");
    g = s.g * g;
    x = s.next;
    poses.row(k) = x.transpose();
  }
  Motion m{x, prr, g * s_->cov.block(0, 3, 3, n_ - 3), g};
  require(m.prm.allFinite(), "noises", "and the motion would make the covariance too large to stay finite");
  apply(m);
  return poses;
}

}  // namespace probslam
