#pragma once
#include <Eigen/Core>

namespace probslam {

/// The 2x2 rotation by theta radians (counter-clockwise).
Eigen::Matrix2d rotation_matrix(double theta);

/// A planar pose (x, y in metres, theta in radians, wrapped to (-pi, pi]): the transform
/// from the body frame to the world frame.
struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;

  Pose2() = default;
  Pose2(double x, double y, double theta);
  /// From a (x, y, theta) vector; throws std::invalid_argument if any entry is not finite.
  static Pose2 from_vector(const Eigen::Vector3d& v);

  Eigen::Vector3d vector() const { return {x, y, theta}; }
  Eigen::Vector2d translation() const { return {x, y}; }
  Eigen::Matrix2d rotation() const;

  /// this (+) other: other expressed in this pose's frame, mapped to the world.
  Pose2 compose(const Pose2& other) const;
  Pose2 inverse() const;
  /// this^-1 (+) other: other relative to this pose.
  Pose2 between(const Pose2& other) const;
  /// Body-frame point to world frame.
  Eigen::Vector2d transform_from(const Eigen::Vector2d& body_point) const;
  /// World-frame point to body frame.
  Eigen::Vector2d transform_to(const Eigen::Vector2d& world_point) const;
};

}  // namespace probslam
