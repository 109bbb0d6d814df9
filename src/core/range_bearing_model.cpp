#include "probslam/core/range_bearing_model.hpp"

#include <cmath>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"

namespace probslam {
namespace {

// A landmark closer than 1 nm to the robot has no meaningful bearing; its Jacobian entries
// (1/q) would exceed 1e18 and poison any filter that used them.
constexpr double kMinRangeSquared = 1e-18;

void check_pose_landmark(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& lm) {
  require_all_finite(pose, "pose");
  require_all_finite(lm, "landmark");
}

}  // namespace

Eigen::Vector2d range_bearing(const Eigen::Vector3d& pose, const Eigen::Vector2d& landmark) {
  check_pose_landmark(pose, landmark);
  const double dx = landmark[0] - pose[0], dy = landmark[1] - pose[1];
  return {std::sqrt(dx * dx + dy * dy), wrap_angle(std::atan2(dy, dx) - pose[2])};
}

Eigen::Vector3d range_bearing(const Eigen::Vector3d& pose, const Eigen::Vector3d& landmark) {
  const Eigen::Vector2d z = range_bearing(pose, Eigen::Vector2d(landmark.head<2>()));
  return {z[0], z[1], landmark[2]};
}

// Table 10.1 line 16 (rows corrected per the errata).
MeasurementJacobians<2> range_bearing_jacobians(const Eigen::Vector3d& pose,
                                                const Eigen::Vector2d& landmark) {
  check_pose_landmark(pose, landmark);
  const double dx = landmark[0] - pose[0], dy = landmark[1] - pose[1];
  const double q = dx * dx + dy * dy;
  require(q >= kMinRangeSquared, "landmark", "coincides with the robot position");
  const double r = std::sqrt(q);
  MeasurementJacobians<2> j;
  j.pose << -dx / r, -dy / r, 0.0,  //
      dy / q, -dx / q, -1.0;
  j.landmark << dx / r, dy / r,  //
      -dy / q, dx / q;
  return j;
}

MeasurementJacobians<3> range_bearing_jacobians(const Eigen::Vector3d& pose,
                                                const Eigen::Vector3d& landmark) {
  require_finite(landmark[2], "landmark");
  const MeasurementJacobians<2> j2 = range_bearing_jacobians(pose, Eigen::Vector2d(landmark.head<2>()));
  MeasurementJacobians<3> j;
  j.pose.setZero();
  j.pose.topRows<2>() = j2.pose;
  j.landmark.setZero();
  j.landmark.topLeftCorner<2, 2>() = j2.landmark;
  j.landmark(2, 2) = 1.0;  // the signature is observed directly
  return j;
}

// Table 10.1 line 10.
Eigen::Vector2d landmark_from_range_bearing(const Eigen::Vector3d& pose, const Eigen::Vector2d& z) {
  require_all_finite(pose, "pose");
  require_all_finite(z, "z");
  require(z[0] >= 0.0, "z", "range must be >= 0");
  const double a = z[1] + pose[2];
  return {pose[0] + z[0] * std::cos(a), pose[1] + z[0] * std::sin(a)};
}

MeasurementJacobians<2> landmark_from_range_bearing_jacobians(const Eigen::Vector3d& pose,
                                                              const Eigen::Vector2d& z) {
  require_all_finite(pose, "pose");
  require_all_finite(z, "z");
  require(z[0] >= 0.0, "z", "range must be >= 0");
  const double a = z[1] + pose[2];
  const double c = std::cos(a), s = std::sin(a);
  MeasurementJacobians<2> j;
  j.pose << 1.0, 0.0, -z[0] * s,  //
      0.0, 1.0, z[0] * c;
  j.landmark << c, -z[0] * s,  //
      s, z[0] * c;
  return j;
}

}  // namespace probslam
