// Starting points for the graph optimiser: dead reckoning and incremental optimisation.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include <Eigen/Geometry>

#include "probslam/graph/graph_initialization.hpp"

namespace probslam {
namespace {

// Composition of a few poses in double precision is exact to about this.
constexpr double kComposed = 1e-12;
// Two converged optimisations of the same objective, reached along different paths, agree to
// about this (relative chi2).
constexpr double kSameMinimum = 1e-9;

// (x, y, theta) (+) (dx, dy, dtheta), written out independently of Pose2.
Eigen::Vector3d compose(const Eigen::Vector3d& a, const Eigen::Vector3d& d) {
  const double c = std::cos(a[2]), s = std::sin(a[2]);
  return {a[0] + c * d[0] - s * d[1], a[1] + s * d[0] + c * d[1], std::remainder(a[2] + d[2], 2 * M_PI)};
}

TEST(InitializeOdometry, ComposesTheChainFromTheFirstPoseAndPlacesPoints) {
  PoseGraph2D g;
  const Eigen::Vector3d start(1.0, 2.0, 0.3), d1(1.0, 0.2, 0.5), d2(0.5, -0.1, -1.2);
  g.add_pose(10, start);
  g.add_pose(11, {9.0, 9.0, 9.0});
  g.add_pose(12, {9.0, 9.0, 9.0});
  g.add_pose(13, {7.0, 7.0, 0.0});  // no edges: unreached, keeps its value
  g.add_point(20, {0.0, 0.0});
  const Eigen::Matrix3d info = Eigen::Matrix3d::Identity();
  g.add_pose_edge(10, 11, d1, info);
  g.add_pose_edge(12, 11, d2, info);  // backwards: 12 = 11 (+) d2^-1
  g.add_point_edge(11, 20, {2.0, 1.0}, Eigen::Matrix2d::Identity());
  initialize_odometry(g);

  const Eigen::Vector3d p11 = compose(start, d1);
  EXPECT_TRUE(g.vertex(0).value.isApprox(start));
  EXPECT_LT((g.vertex(1).value - p11).norm(), kComposed);
  // 12 composed with d2 must give 11.
  EXPECT_LT((compose(g.vertex(2).value, d2) - p11).norm(), kComposed);
  EXPECT_EQ(g.vertex(3).value, Eigen::Vector3d(7.0, 7.0, 0.0));
  const Eigen::Vector3d point = compose(p11, {2.0, 1.0, 0.0});
  EXPECT_LT((g.vertex(4).value.head<2>() - point.head<2>()).norm(), kComposed);
  EXPECT_NEAR(g.chi2(), 0.0, kComposed);
}

TEST(InitializeOdometry, StartsFromFixedVerticesAndLeavesThemAlone) {
  PoseGraph2D g;
  g.add_pose(0, {5.0, 5.0, 5.0});
  g.add_pose(1, {1.0, 1.0, 1.0});
  g.add_pose_edge(0, 1, {1.0, 0.0, 0.0}, Eigen::Matrix3d::Identity());
  g.set_fixed(1);
  initialize_odometry(g);
  EXPECT_EQ(g.vertex(1).value, Eigen::Vector3d(1.0, 1.0, 1.0));
  EXPECT_LT((compose(g.vertex(0).value, {1.0, 0.0, 0.0}) - g.vertex(1).value).norm(), kComposed);
}

// A noisy loop with landmarks, values scrambled: batch and incremental optimisation from
// dead reckoning must meet at the same minimum.
PoseGraph2D noisy_loop(std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, 0.05);
  PoseGraph2D g;
  const int n = 40;
  for (int i = 0; i < n; ++i) g.add_pose(i, Eigen::Vector3d::Zero());
  for (int k = 0; k < 4; ++k) g.add_point(100 + k, Eigen::Vector2d::Zero());
  const Eigen::Matrix3d info = Eigen::Vector3d(50.0, 50.0, 200.0).asDiagonal();
  const double turn = 2 * M_PI / n;
  for (int i = 0; i + 1 < n; ++i)
    g.add_pose_edge(i, i + 1, {1.0 + noise(rng), noise(rng), turn + noise(rng)}, info);
  for (int i = 0; i < n; ++i) {
    // The loop's poses sit on a circle of radius 1 / (2 sin(turn / 2)); landmarks near its centre.
    const double radius = 0.5 / std::sin(turn / 2);
    const double heading = i * turn, angle = heading - M_PI / 2;
    const Eigen::Vector2d position(radius * std::cos(angle), radius * std::sin(angle) + radius);
    const Eigen::Vector2d landmark(0.5 * (i % 4) - 1.0, radius);
    const Eigen::Rotation2Dd r(heading);
    const Eigen::Vector2d z = r.inverse() * (landmark - position) + Eigen::Vector2d(noise(rng), noise(rng));
    g.add_point_edge(i, 100 + i % 4, z, 4.0 * Eigen::Matrix2d::Identity());
  }
  return g;
}

TEST(OptimizeIncremental, ReachesTheBatchMinimum) {
  std::mt19937 rng(7);
  PoseGraph2D batch = noisy_loop(rng);
  initialize_odometry(batch);
  PoseGraph2D incremental = batch;
  const OptimizationReport b = optimize(batch);
  ASSERT_TRUE(b.converged);
  IncrementalOptions options;
  options.poses_per_step = 7;
  const IncrementalReport r = optimize_incremental(incremental, options);
  EXPECT_EQ(r.steps, 6);  // ceil(40 / 7)
  EXPECT_EQ(static_cast<int>(r.step_chi2.size()), r.steps);
  EXPECT_NEAR(r.chi2, b.chi2, kSameMinimum * b.chi2);
  EXPECT_NEAR(incremental.chi2(), r.chi2, kComposed);
  // The last step optimises everything: a further batch run starts at its minimum.
  EXPECT_NEAR(optimize(incremental).chi2, r.chi2, kSameMinimum * r.chi2);
}

TEST(OptimizeIncremental, RejectsBadOptions) {
  std::mt19937 rng(7);
  PoseGraph2D g = noisy_loop(rng);
  IncrementalOptions options;
  options.poses_per_step = 0;
  EXPECT_THROW(optimize_incremental(g, options), std::invalid_argument);
  PoseGraph2D points_only;
  points_only.add_point(1, {0.0, 0.0});
  EXPECT_THROW(optimize_incremental(points_only), std::invalid_argument);
}

}  // namespace
}  // namespace probslam
