// The optimiser's per-iteration callback: what it is told, stopping by returning false, and an
// exception from it (Ctrl-C in the bindings) leaving the graph at the last completed iteration.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "probslam/graph/graph_initialization.hpp"
#include "probslam/graph/graph_optimizer.hpp"

namespace probslam {
namespace {

// A square loop walked several times with noisy odometry and a few closures, started from
// scrambled values, so that Gauss-Newton takes several iterations.
PoseGraph2D noisy_square() {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.05);
  PoseGraph2D g;
  const int n = 24;
  for (int i = 0; i < n; ++i) g.add_pose(i, {0.3 * noise(rng) * i, 0.3 * noise(rng) * i, 0.0});
  const Eigen::Matrix3d info = Eigen::Vector3d(100.0, 100.0, 400.0).asDiagonal();
  for (int i = 0; i + 1 < n; ++i) {
    const bool corner = (i + 1) % 3 == 0;
    g.add_pose_edge(i, i + 1, {1.0 + noise(rng), noise(rng), (corner ? M_PI / 2 : 0.0) + noise(rng)}, info);
  }
  for (int i = 0; i + 12 < n; i += 4) g.add_pose_edge(i, i + 12, {noise(rng), noise(rng), noise(rng)}, info);
  return g;
}

// The values after `iterations` iterations of an optimisation with no callback: the reference
// a stopped or interrupted run must equal bit for bit (the same arithmetic in the same order).
std::vector<Eigen::Vector3d> after(int iterations) {
  PoseGraph2D g = noisy_square();
  OptimizerOptions o;
  o.max_iterations = iterations;
  optimize(g, o);
  return g.values();
}

TEST(OptimizerCallback, SeesEveryIterationAndItsChi2) {
  PoseGraph2D g = noisy_square();
  std::vector<int> seen;
  std::vector<double> chi2;
  const OptimizationReport r = optimize(g, {}, [&](int iteration, double c) {
    seen.push_back(iteration);
    chi2.push_back(c);
    return true;
  });
  ASSERT_GE(r.iterations, 3);  // else the stopping tests below test nothing
  ASSERT_EQ(static_cast<int>(seen.size()), r.iterations);
  for (int k = 0; k < r.iterations; ++k) EXPECT_EQ(seen[k], k + 1);
  EXPECT_EQ(chi2, r.chi2_history);
  PoseGraph2D plain = noisy_square();
  optimize(plain);
  EXPECT_EQ(g.values(), plain.values());  // watching changes nothing
}

TEST(OptimizerCallback, ReturningFalseStopsAtThatIteration) {
  PoseGraph2D g = noisy_square();
  const OptimizationReport r = optimize(g, {}, [](int iteration, double) { return iteration < 2; });
  EXPECT_EQ(r.iterations, 2);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.stop_reason, "stopped by the callback");
  EXPECT_EQ(g.values(), after(2));
  EXPECT_EQ(r.chi2, g.chi2());
}

TEST(OptimizerCallback, AnExceptionLeavesTheLastCompletedIteration) {
  PoseGraph2D g = noisy_square();
  struct Interrupted {};
  EXPECT_THROW(optimize(g, {},
                        [](int iteration, double) -> bool {
                          if (iteration == 2) throw Interrupted{};
                          return true;
                        }),
               Interrupted);
  EXPECT_EQ(g.values(), after(2));
}

TEST(OptimizerCallback, AFailureBeforeTheCallbackLeavesTheGraphUnchanged) {
  PoseGraph2D g;
  g.add_pose(0, Eigen::Vector3d::Zero());
  g.add_pose(1, Eigen::Vector3d::Zero());
  g.add_pose(2, Eigen::Vector3d::Zero());
  g.add_pose(3, Eigen::Vector3d::Zero());
  g.add_pose_edge(0, 1, {1.0, 0.0, 0.0}, Eigen::Matrix3d::Identity());
  g.add_pose_edge(2, 3, {1.0, 0.0, 0.0}, Eigen::Matrix3d::Identity());  // 2 and 3 float free
  const std::vector<Eigen::Vector3d> before = g.values();
  int calls = 0;
  EXPECT_THROW(optimize(g, {}, [&](int, double) { return ++calls > 0; }), std::invalid_argument);
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(g.values(), before);
}

}  // namespace
}  // namespace probslam
