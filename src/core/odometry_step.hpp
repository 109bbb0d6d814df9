#pragma once
// One odometry step x (+) delta with its two Jacobians, shared by the landmark filters'
// odometry predictions (EkfSlam's covariance, FastSlam version 2's motion prior).
#include <Eigen/Core>

#include "probslam/core/angle.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/pose2_covariance.hpp"

namespace probslam::core_detail {

/// x (+) delta: the step's translation turned by x's heading; G = d(x (+) delta) / d x (only the
/// heading column differs from the identity), J = d(x (+) delta) / d delta.
struct OdometryStep {
  Eigen::Vector3d next;
  Eigen::Matrix3d g, j;
};

inline OdometryStep odometry_step(const Eigen::Vector3d& x, const Eigen::Vector3d& delta) {
  const Eigen::Matrix2d rx = rotation_matrix(x[2]);
  const Eigen::Vector2d turned = rx * delta.head<2>();
  OdometryStep s;
  s.g = heading_jacobian(turned);
  s.j = Eigen::Matrix3d::Identity();
  s.j.topLeftCorner<2, 2>() = rx;
  s.next = Eigen::Vector3d(x[0] + turned.x(), x[1] + turned.y(), wrap_angle(x[2] + delta[2]));
  return s;
}

}  // namespace probslam::core_detail
