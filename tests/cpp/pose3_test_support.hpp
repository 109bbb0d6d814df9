#pragma once
// SE(3) helpers shared by the PoseGraph3D test files, written apart from the library's own
// composition (quaternion products, normalised) so the tests do not check the library with itself.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "probslam/core/so3.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_3d.hpp"

namespace probslam::test_support {

// Central differences with step h: truncation O(h^2) ~ 1e-12 and rounding ~ 1e-16 / h ~ 1e-10 for
// these O(1)-O(10) functions; 1e-7 leaves a wide margin for both.
constexpr double kFiniteDifferenceStep = 1e-6;
constexpr double kJacobianTolerance = 1e-7;
// Exact data solved exactly: what is left is rounding in a few dozen operations per vertex.
constexpr double kExactTolerance = 1e-9;

/// A pose with N(0, translation_scale^2) translation and a rotation vector N(0, angle_scale^2).
inline Pose3 random_pose(std::mt19937& rng, double translation_scale, double angle_scale) {
  std::normal_distribution<double> normal;
  const Eigen::Vector3d w(normal(rng), normal(rng), normal(rng));
  return {so3_exp(angle_scale * w), translation_scale * Eigen::Vector3d(normal(rng), normal(rng), normal(rng))};
}

/// A random N x N information matrix A A^T + I (A's entries N(0, 1), column by column).
template <int N>
Eigen::Matrix<double, N, N> random_information(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::Matrix<double, N, N> a;
  for (int i = 0; i < N * N; ++i) a.data()[i] = normal(rng);
  return a * a.transpose() + Eigen::Matrix<double, N, N>::Identity();
}

/// optimize(g) with `algorithm`, expected to converge; its report.
inline OptimizationReport converged_optimum(PoseGraph3D& g, OptimizerAlgorithm algorithm) {
  OptimizerOptions options;
  options.algorithm = algorithm;
  const OptimizationReport report = optimize(g, options);
  EXPECT_TRUE(report.converged) << report.stop_reason;
  return report;
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
