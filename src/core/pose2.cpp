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

namespace {
// Finite or raise: poses near the double range can overflow when combined.
Pose2 finite_pose(const Eigen::Vector2d& t, double theta) {
  require(t.allFinite() && std::isfinite(theta), "pose", "result is beyond the double range");
  return Pose2(t.x(), t.y(), theta);
}

Eigen::Vector2d finite_point(const Eigen::Vector2d& p) {
  require(p.allFinite(), "point", "result is beyond the double range");
  return p;
}
}  // namespace

Pose2 Pose2::compose(const Pose2& other) const {
  const Eigen::Vector2d t = rotation() * other.translation() + translation();
  return finite_pose(t, theta + other.theta);
}

Pose2 Pose2::inverse() const {
  const Eigen::Vector2d t = -(rotation().transpose() * translation());
  return finite_pose(t, -theta);
}

Pose2 Pose2::between(const Pose2& other) const { return inverse().compose(other); }

Eigen::Vector2d Pose2::transform_from(const Eigen::Vector2d& body_point) const {
  return finite_point(rotation() * body_point + translation());
}

Eigen::Vector2d Pose2::transform_to(const Eigen::Vector2d& world_point) const {
  return finite_point(rotation().transpose() * (world_point - translation()));
}

}  // namespace probslam
