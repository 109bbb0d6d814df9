// PoseGraph3D's point landmarks (g2o EDGE_SE3_TRACKXYZ): the point edge's Jacobians against
// central finite differences, an exact graph optimised to chi2 0, the initialisers placing
// points, marginals of the right size, and bad input refused with the graph unchanged.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>
#include <stdexcept>
#include <vector>

#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_3d.hpp"
#include "probslam/graph/pose_graph_3d_initialization.hpp"
#include "pose3_test_support.hpp"

namespace probslam {
namespace {

using namespace test_support;  // the SE(3) helpers of pose3_test_support.hpp

// The point in the frame of the sensor at `offset` on pose x, written independently of the
// library's linearisation: (x * offset)^-1 p.
Eigen::Vector3d observe(const Pose3& x, const Pose3& offset, const Eigen::Vector3d& p) {
  const Pose3 s = compose(x, offset);
  return s.rotation.conjugate() * (p - s.translation);
}

TEST(PoseGraph3DPoints, PointEdgeJacobiansMatchCentralDifferences) {
  std::mt19937 rng(21);
  std::normal_distribution<double> normal;
  for (int trial = 0; trial < 50; ++trial) {
    const Pose3 x = random_pose(rng, 3.0, 1.0);
    const Pose3 offset = trial % 2 ? random_pose(rng, 0.5, 0.5) : Pose3{};
    const Eigen::Vector3d p(5 * normal(rng), 5 * normal(rng), 5 * normal(rng));
    const Eigen::Vector3d z = observe(x, offset, p) + 0.3 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    const Point3EdgeLinearization lin = linearize_point3_edge(x, p, z, offset);
    EXPECT_LE((lin.error - (observe(x, offset, p) - z)).norm(), 1e-12) << trial;
    Eigen::Matrix<double, 3, 6> d_pose;
    Eigen::Matrix3d d_point;
    for (int k = 0; k < 6; ++k) {
      const Vector6d h = kFiniteDifferenceStep * Vector6d::Unit(k);
      d_pose.col(k) = (linearize_point3_edge(retract(x, h), p, z, offset).error -
                       linearize_point3_edge(retract(x, -h), p, z, offset).error) /
                      (2.0 * kFiniteDifferenceStep);
    }
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d h = kFiniteDifferenceStep * Eigen::Vector3d::Unit(k);
      d_point.col(k) = (linearize_point3_edge(x, p + h, z, offset).error -
                        linearize_point3_edge(x, p - h, z, offset).error) /
                       (2.0 * kFiniteDifferenceStep);
    }
    EXPECT_LE((lin.d_pose - d_pose).cwiseAbs().maxCoeff(), kJacobianTolerance) << trial;
    EXPECT_LE((lin.d_point - d_point).cwiseAbs().maxCoeff(), kJacobianTolerance) << trial;
  }
}

struct Truth {
  std::vector<Pose3> poses;
  std::vector<Eigen::Vector3d> points;
};

// A loop of poses (ids 0..n-1) and points (ids 100..) each seen from three poses, every edge
// exact; pose edges around the loop and a closing chord. `offset` is every point edge's sensor.
PoseGraph3D exact_graph(const Truth& t, const Pose3& offset, std::mt19937& rng) {
  PoseGraph3D g;
  const int n = static_cast<int>(t.poses.size());
  for (int i = 0; i < n; ++i) {
    g.add_pose(i, t.poses[i]);
    if (i == 1) {  // points interleaved with poses in the vertex list
      for (size_t k = 0; k < t.points.size(); ++k) g.add_point(100 + static_cast<int>(k), t.points[k]);
    }
  }
  Matrix6d info = Matrix6d::Identity() * 10.0;
  for (int i = 0; i + 1 < n; ++i) g.add_pose_edge(i, i + 1, between(t.poses[i], t.poses[i + 1]), info);
  g.add_pose_edge(n - 1, 0, between(t.poses[n - 1], t.poses[0]), info);
  for (size_t k = 0; k < t.points.size(); ++k)
    for (int j = 0; j < 3; ++j) {
      const int pose = (static_cast<int>(k) + 2 * j) % n;
      g.add_point_edge(pose, 100 + static_cast<int>(k), observe(t.poses[pose], offset, t.points[k]),
                       random_information<3>(rng), offset);
    }
  return g;
}

Truth random_truth(std::mt19937& rng, int poses, int points) {
  std::normal_distribution<double> normal;
  Truth t;
  t.poses.push_back(random_pose(rng, 1.0, 1.0));
  for (int i = 1; i < poses; ++i) t.poses.push_back(compose(t.poses.back(), random_pose(rng, 1.0, 0.4)));
  for (int k = 0; k < points; ++k) t.points.emplace_back(3 * normal(rng), 3 * normal(rng), 3 * normal(rng));
  return t;
}

void expect_at_truth(const PoseGraph3D& g, const Truth& t) {
  for (int v = 0; v < g.num_vertices(); ++v) {
    const Pose3Vertex& vertex = g.vertex(v);
    if (vertex.kind == VertexKind::kPoint) {
      EXPECT_LE((vertex.value.translation - t.points[vertex.id - 100]).norm(), kExactTolerance) << vertex.id;
    } else {
      EXPECT_LE((vertex.value.translation - t.poses[vertex.id].translation).norm(), kExactTolerance) << vertex.id;
      EXPECT_LE(so3_log(vertex.value.rotation.conjugate() * t.poses[vertex.id].rotation).norm(), kExactTolerance)
          << vertex.id;
    }
  }
}

TEST(PoseGraph3DPoints, ExactGraphOptimisesToChi2ZeroWithEitherAlgorithm) {
  for (const auto algorithm : {OptimizerAlgorithm::kGaussNewton, OptimizerAlgorithm::kLevenbergMarquardt}) {
    for (const bool with_offset : {false, true}) {
      std::mt19937 rng(22);
      const Truth t = random_truth(rng, 8, 6);
      const Pose3 offset = with_offset ? random_pose(rng, 0.3, 0.5) : Pose3{};
      PoseGraph3D g = exact_graph(t, offset, rng);
      EXPECT_EQ(g.num_points(), 6);
      EXPECT_EQ(g.edge_chi2().size(), 8 + 18);
      EXPECT_LE(g.chi2(), 1e-20);
      std::vector<int> pose_ids;
      std::vector<Pose3> poses;
      for (int i = 1; i < 8; ++i) {  // pose 0 is held
        pose_ids.push_back(i);
        poses.push_back(compose(t.poses[i], random_pose(rng, 0.2, 0.1)));
      }
      g.set_poses(pose_ids, poses);
      std::vector<int> point_ids;
      std::vector<Eigen::Vector3d> points;
      for (int k = 0; k < 6; ++k) {
        point_ids.push_back(100 + k);
        points.push_back(t.points[k] + Eigen::Vector3d(0.3, -0.2, 0.25));
      }
      g.set_points(point_ids, points);
      EXPECT_GT(g.chi2(), 1.0);
      const OptimizationReport report = converged_optimum(g, algorithm);
      EXPECT_LE(report.chi2, 1e-18);
      expect_at_truth(g, t);
    }
  }
}

// Points 100 .. 100 + count - 1 all moved to one far place, so that only an initialiser that
// places them from their sightings brings them back.
void move_points_away(PoseGraph3D& g, int count) {
  std::vector<int> ids;
  for (int k = 0; k < count; ++k) ids.push_back(100 + k);
  g.set_points(ids, std::vector<Eigen::Vector3d>(ids.size(), Eigen::Vector3d(50.0, -40.0, 30.0)));
}

TEST(PoseGraph3DPoints, InitialisersPlacePointsFromTheirFirstObservation) {
  std::mt19937 rng(23);
  const Truth t = random_truth(rng, 8, 5);
  const Pose3 offset = random_pose(rng, 0.3, 0.5);
  for (const bool chordal : {false, true}) {
    PoseGraph3D g = exact_graph(t, offset, rng);
    move_points_away(g, 5);
    if (chordal)
      initialize_chordal(g);
    else
      initialize_odometry(g);
    expect_at_truth(g, t);
  }
}

TEST(PoseGraph3DPoints, MarginalsAre3x3ForPointsAnd6x6ForPoses) {
  std::mt19937 rng(24);
  const Truth t = random_truth(rng, 6, 4);
  const PoseGraph3D g = exact_graph(t, Pose3{}, rng);
  const std::vector<Eigen::MatrixXd> m = marginal_covariances(g, {100, 3, 0});
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m[0].rows(), 3);
  EXPECT_EQ(m[1].rows(), 6);
  EXPECT_EQ(m[2].norm(), 0.0);  // the held first pose
  // The point's covariance is the inverse of its Schur complement: at least as large as the
  // inverse of its own information block (the sum of its edges' J^T Omega J).
  Eigen::Matrix3d own = Eigen::Matrix3d::Zero();
  for (const Point3Edge& e : g.point_edges())
    if (g.vertex(e.point).id == 100) {
      const auto lin = linearize_point3_edge(g.vertex(e.pose).value, g.vertex(e.point).value.translation,
                                             e.measurement, e.offset);
      own += lin.d_point.transpose() * e.information * lin.d_point;
    }
  const Eigen::Matrix3d excess = m[0] - own.inverse();
  EXPECT_GE(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(excess).eigenvalues().minCoeff(), -1e-12);
}

TEST(PoseGraph3DPoints, BadInputIsRefusedAndLeavesTheGraphUnchanged) {
  PoseGraph3D g;
  g.add_pose(0, {});
  g.add_pose(1, {});
  g.add_point(5, Eigen::Vector3d(1, 2, 3));
  g.add_point_edge(0, 5, Eigen::Vector3d(1, 2, 3), Eigen::Matrix3d::Identity());
  const auto same = [&] {
    return g.num_vertices() == 3 && g.num_points() == 1 && g.point_edges().size() == 1 && g.pose_edges().empty() &&
           g.vertex(2).value.translation == Eigen::Vector3d(1, 2, 3);
  };
  const Eigen::Matrix3d info = Eigen::Matrix3d::Identity();
  const Eigen::Vector3d z(1, 0, 0);
  EXPECT_THROW(g.add_point(0, z), std::invalid_argument);  // id of a pose
  EXPECT_THROW(g.add_point(5, z), std::invalid_argument);  // repeated
  EXPECT_THROW(g.add_point(6, Eigen::Vector3d(NAN, 0, 0)), std::invalid_argument);
  EXPECT_THROW(g.add_pose(5, {}), std::invalid_argument);
  EXPECT_THROW(g.add_point_edge(7, 5, z, info), std::invalid_argument);  // unknown pose
  EXPECT_THROW(g.add_point_edge(0, 7, z, info), std::invalid_argument);  // unknown point
  EXPECT_THROW(g.add_point_edge(5, 5, z, info), std::invalid_argument);  // a point as the pose
  EXPECT_THROW(g.add_point_edge(0, 1, z, info), std::invalid_argument);  // a pose as the point
  EXPECT_THROW(g.add_pose_edge(0, 5, {}, Matrix6d::Identity()), std::invalid_argument);
  EXPECT_THROW(g.add_pose_prior(5, {}, Matrix6d::Identity()), std::invalid_argument);
  EXPECT_THROW(g.add_point_edge(0, 5, Eigen::Vector3d(0, INFINITY, 0), info), std::invalid_argument);
  Eigen::Matrix3d indefinite = info;
  indefinite(2, 2) = -1.0;
  EXPECT_THROW(g.add_point_edge(0, 5, z, indefinite), std::invalid_argument);
  Eigen::Matrix3d asymmetric = info;
  asymmetric(0, 1) = 0.5;
  EXPECT_THROW(g.add_point_edge(0, 5, z, asymmetric), std::invalid_argument);
  Pose3 bad_offset;
  bad_offset.rotation = Eigen::Quaterniond(2, 0, 0, 0);
  EXPECT_THROW(g.add_point_edge(0, 5, z, info, bad_offset), std::invalid_argument);
  EXPECT_THROW(g.set_poses({5}, {Pose3{}}), std::invalid_argument);
  EXPECT_THROW(g.set_points({0}, {z}), std::invalid_argument);
  EXPECT_THROW(g.set_points({5, 6}, {z, z}), std::invalid_argument);
  EXPECT_THROW(g.set_points({5}, {Eigen::Vector3d(NAN, 0, 0)}), std::invalid_argument);
  EXPECT_TRUE(same());
}

TEST(PoseGraph3DPoints, IncrementalOptimisationOfAnExactGraphIsExact) {
  std::mt19937 rng(25);
  const Truth t = random_truth(rng, 9, 6);
  const Pose3 offset = random_pose(rng, 0.3, 0.5);
  PoseGraph3D g = exact_graph(t, offset, rng);
  move_points_away(g, 6);
  IncrementalOptions options;
  options.poses_per_step = 2;
  const IncrementalReport report = optimize_incremental(g, options);
  EXPECT_EQ(report.steps, 5);
  EXPECT_LE(report.chi2, 1e-18);
  expect_at_truth(g, t);
}

TEST(PoseGraph3DPoints, APointSeenOnceFromAFixedPoseIsSolvedExactly) {
  // The smallest problem with a closed form: one held pose, one point, one edge: p = x * o * z.
  PoseGraph3D g;
  const Pose3 x{so3_exp(Eigen::Vector3d(0.1, -0.4, 0.7)), Eigen::Vector3d(1, 2, 3)};
  const Pose3 o{so3_exp(Eigen::Vector3d(0.3, 0.2, -0.1)), Eigen::Vector3d(0.1, 0, 0.2)};
  g.add_pose(0, x);
  g.add_point(1, Eigen::Vector3d::Zero());
  const Eigen::Vector3d z(2, -1, 4);
  g.add_point_edge(0, 1, z, Eigen::Matrix3d::Identity() * 4.0, o);
  const OptimizationReport report = optimize(g);
  EXPECT_LE(report.chi2, 1e-20);
  const Pose3 s = compose(x, o);
  EXPECT_LE((g.vertex(1).value.translation - (s.translation + s.rotation * z)).norm(), kExactTolerance);
  EXPECT_EQ(g.vertex(0).value.translation, x.translation);
  // Its marginal is the inverse information rotated into the world: R_s (4 I)^-1 R_s^T = I / 4.
  const Eigen::MatrixXd cov = marginal_covariances(g, {1})[0];
  EXPECT_LE((cov - Eigen::Matrix3d::Identity() / 4.0).norm(), 1e-12);
}

}  // namespace
}  // namespace probslam
