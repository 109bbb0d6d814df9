#include "probslam/core/ackermann_motion_model.hpp"

#include <cmath>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/pose2_covariance.hpp"

namespace probslam {
namespace {

// What one step's controls give: the speed at the rear axle's centre, the yaw rate, and their
// derivatives with respect to (speed, steering).
struct Kinematics {
  double vc, w, dvc_dv, dvc_da, dw_dv, dw_da;
};

Kinematics kinematics(double speed, double steering, double dt, const AckermannGeometry& g) {
  g.validate();
  require_finite(speed, "speed");
  require_finite(steering, "steering");
  require_positive(dt, "dt");
  require(std::abs(steering) < 0.5 * kPi, "steering", "must lie in (-pi/2, pi/2)");
  const double t = std::tan(steering), sec2 = 1.0 + t * t;
  const double ratio = 1.0 - t * g.encoder_offset / g.wheelbase;
  require(ratio >= kMinEncoderSpeedRatio, "steering",
          "turns the encoder wheel about itself (1 - tan(steering) H / L must be >= 0.01)");
  Kinematics k{};
  k.vc = speed / ratio;
  k.dvc_dv = 1.0 / ratio;
  k.dvc_da = speed * g.encoder_offset / g.wheelbase * sec2 / (ratio * ratio);
  k.w = k.vc * t / g.wheelbase;
  k.dw_dv = k.dvc_dv * t / g.wheelbase;
  k.dw_da = (k.dvc_da * t + k.vc * sec2) / g.wheelbase;
  require(std::isfinite(k.vc * dt) && std::isfinite(k.w * dt) && std::isfinite(k.dvc_da * dt) &&
              std::isfinite(k.dw_da * dt),
          "speed", "* dt is beyond the double range");
  return k;
}

template <typename Derived>
const Derived& finite_result(const Eigen::MatrixBase<Derived>& r) {
  require(r.allFinite(), "speed", "gives a result beyond the double range");
  return r.derived();
}

}  // namespace

void AckermannGeometry::validate() const {
  require_positive(wheelbase, "wheelbase");
  require_finite(encoder_offset, "encoder_offset");
  require_finite(sensor_ahead, "sensor_ahead");
  require_finite(sensor_left, "sensor_left");
}

// The sensor at (a, b) of a body whose rear axle's centre moves at vc with yaw rate w moves at
// (vc - w b, w a) in the body's frame.
Eigen::Vector3d ackermann_increment(double speed, double steering, double dt, const AckermannGeometry& g) {
  const Kinematics k = kinematics(speed, steering, dt, g);
  const Eigen::Vector3d d(dt * (k.vc - k.w * g.sensor_left), dt * k.w * g.sensor_ahead, dt * k.w);
  return finite_result(d);
}

Eigen::Matrix<double, 3, 2> ackermann_increment_jacobian(double speed, double steering, double dt,
                                                         const AckermannGeometry& g) {
  const Kinematics k = kinematics(speed, steering, dt, g);
  Eigen::Matrix<double, 3, 2> j;
  j << dt * (k.dvc_dv - k.dw_dv * g.sensor_left), dt * (k.dvc_da - k.dw_da * g.sensor_left),
      dt * k.dw_dv * g.sensor_ahead, dt * k.dw_da * g.sensor_ahead, dt * k.dw_dv, dt * k.dw_da;
  return finite_result(j);
}

Eigen::Vector3d ackermann_motion(const Eigen::Vector3d& pose, double speed, double steering, double dt,
                                 const AckermannGeometry& g) {
  require_all_finite(pose, "pose");
  const Eigen::Vector3d d = ackermann_increment(speed, steering, dt, g);
  Eigen::Vector3d next;
  next.head<2>() = pose.head<2>() + rotation_matrix(pose[2]) * d.head<2>();
  next[2] = wrap_angle(pose[2] + d[2]);
  return finite_result(next);
}

// Only the heading column differs from the identity: the step turns with the heading.
Eigen::Matrix3d ackermann_motion_jacobian(const Eigen::Vector3d& pose, double speed, double steering, double dt,
                                          const AckermannGeometry& g) {
  require_all_finite(pose, "pose");
  const Eigen::Vector3d d = ackermann_increment(speed, steering, dt, g);
  return finite_result(heading_jacobian(rotation_matrix(pose[2]) * d.head<2>()));
}

Eigen::Matrix<double, 3, 2> ackermann_motion_control_jacobian(const Eigen::Vector3d& pose, double speed,
                                                              double steering, double dt,
                                                              const AckermannGeometry& g) {
  require_all_finite(pose, "pose");
  Eigen::Matrix<double, 3, 2> j = ackermann_increment_jacobian(speed, steering, dt, g);
  j.topRows<2>() = (rotation_matrix(pose[2]) * j.topRows<2>()).eval();
  return finite_result(j);
}

}  // namespace probslam
