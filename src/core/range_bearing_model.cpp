#include "probslam/core/range_bearing_model.hpp"

#include <cmath>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"

namespace probslam {
namespace {

// A landmark closer than 1 nm to the robot has no meaningful bearing; its Jacobian entries
// (1/q) would exceed 1e18 and poison any filter that used them.
constexpr double kMinRangeSquared = 1e-18;

// The landmark's offset from the pose; std::invalid_argument unless it is finite.
Eigen::Vector2d offset(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& lm) {
  require_all_finite(pose, "pose");
  require_all_finite(lm, "landmark");
  const Eigen::Vector2d d(lm[0] - pose[0], lm[1] - pose[1]);
  require(d.allFinite(), "landmark", "is beyond the double range from the pose");
  return d;
}

}  // namespace

Eigen::Vector2d range_bearing(const Eigen::Vector3d& pose, const Eigen::Vector2d& landmark) {
  const Eigen::Vector2d d = offset(pose, landmark);
  const double r = std::hypot(d.x(), d.y());  // overflows where both offsets are near the double maximum
  require(std::isfinite(r), "landmark", "is beyond the double range from the pose");
  return {r, wrap_angle(std::atan2(d.y(), d.x()) - pose[2])};
}

Eigen::Vector3d range_bearing(const Eigen::Vector3d& pose, const Eigen::Vector3d& landmark) {
  require_finite(landmark[2], "landmark");
  const Eigen::Vector2d z = range_bearing(pose, Eigen::Vector2d(landmark.head<2>()));
  return {z[0], z[1], landmark[2]};
}

// Table 10.1 line 16 (rows corrected per the errata).
MeasurementJacobians<2> range_bearing_jacobians(const Eigen::Vector3d& pose,
                                                const Eigen::Vector2d& landmark) {
  const Eigen::Vector2d d = offset(pose, landmark);
  const double r = std::hypot(d.x(), d.y());
  require(r * r >= kMinRangeSquared, "landmark", "coincides with the robot position");
  Eigen::Vector2d z;
  MeasurementJacobians<2> j;
  range_bearing_unchecked(pose, landmark, z, j);
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
  const Eigen::Vector2d m(pose[0] + z[0] * std::cos(a), pose[1] + z[0] * std::sin(a));
  require(m.allFinite(), "z", "places the landmark beyond the double range");
  return m;
}

MeasurementJacobians<2> landmark_from_range_bearing_jacobians(const Eigen::Vector3d& pose,
                                                              const Eigen::Vector2d& z) {
  require_all_finite(pose, "pose");
  require_all_finite(z, "z");
  require(z[0] >= 0.0, "z", "range must be >= 0");
  require(std::isfinite(z[1] + pose[2]), "z", "bearing plus heading is beyond the double range");
  Eigen::Vector2d m;
  MeasurementJacobians<2> j;
  landmark_from_range_bearing_unchecked(pose, z, m, j);
  return j;
}

}  // namespace probslam
