#pragma once
// SE(3) helpers shared by the PoseGraph3D test files, written apart from the library's own
// composition (quaternion products, normalised) so the tests do not check the library with itself.
#include <Eigen/Geometry>
#include <random>

#include "probslam/core/so3.hpp"
#include "probslam/graph/pose_graph_3d.hpp"

namespace probslam::test_support {

/// A pose with N(0, translation_scale^2) translation and a rotation vector N(0, angle_scale^2).
inline Pose3 random_pose(std::mt19937& rng, double translation_scale, double angle_scale) {
  std::normal_distribution<double> normal;
  const Eigen::Vector3d w(normal(rng), normal(rng), normal(rng));
  return {so3_exp(angle_scale * w), translation_scale * Eigen::Vector3d(normal(rng), normal(rng), normal(rng))};
}

/// a * b.
inline Pose3 compose(const Pose3& a, const Pose3& b) {
  return {(a.rotation * b.rotation).normalized(), a.translation + a.rotation * b.translation};
}

/// a^-1 b.
inline Pose3 between(const Pose3& a, const Pose3& b) {
  const Eigen::Quaterniond ra = a.rotation.conjugate();
  return {(ra * b.rotation).normalized(), ra * (b.translation - a.translation)};
}

}  // namespace probslam::test_support
