#include "probslam/core/pose2.hpp"

#include <cmath>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"

namespace probslam {

Pose2::Pose2(double x_, double y_, double theta_) : x(x_), y(y_), theta(wrap_angle(theta_)) {}

Pose2 Pose2::from_vector(const Eigen::Vector3d& v) {
  require_all_finite(v, "pose");
  return Pose2(v[0], v[1], v[2]);
}

Eigen::Matrix2d rotation_matrix(double theta) {
  const double c = std::cos(theta), s = std::sin(theta);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

Eigen::Matrix2d Pose2::rotation() const { return rotation_matrix(theta); }

Pose2 Pose2::compose(const Pose2& other) const {
  const Eigen::Vector2d t = transform_from(other.translation());
  return Pose2(t.x(), t.y(), theta + other.theta);
}

Pose2 Pose2::inverse() const {
  const Eigen::Vector2d t = -(rotation().transpose() * translation());
  return Pose2(t.x(), t.y(), -theta);
}

Pose2 Pose2::between(const Pose2& other) const { return inverse().compose(other); }

Eigen::Vector2d Pose2::transform_from(const Eigen::Vector2d& body_point) const {
  return rotation() * body_point + translation();
}

Eigen::Vector2d Pose2::transform_to(const Eigen::Vector2d& world_point) const {
  return rotation().transpose() * (world_point - translation());
}

}  // namespace probslam
