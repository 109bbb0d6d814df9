// PoseGraph3D: the edge's Jacobians against central finite differences, optima known in closed
// form (exact loops), the chordal initialisation on noise-free graphs, and bad input.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>

#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_3d.hpp"
#include "probslam/graph/pose_graph_3d_initialization.hpp"
#include "pose3_test_support.hpp"

namespace probslam {
namespace {

using namespace test_support;  // the SE(3) helpers of pose3_test_support.hpp

double rotation_distance(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return so3_log(a.conjugate() * b).norm();
}

TEST(So3, ExpAndLogAreInverse) {
  std::mt19937 rng(1);
  std::normal_distribution<double> normal;
  for (const double scale : {1e-9, 1e-5, 0.1, 1.0}) {
    for (int k = 0; k < 20; ++k) {
      Eigen::Vector3d w(normal(rng), normal(rng), normal(rng));
      w *= scale;
      if (w.norm() >= M_PI) continue;
      EXPECT_LE((so3_log(so3_exp(w)) - w).norm(), 1e-12 * std::max(1.0, w.norm()));
      // Against Eigen's own angle-axis rotation matrix.
      const Eigen::Matrix3d expected =
          w.norm() > 0 ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() : Eigen::Matrix3d::Identity();
      EXPECT_LE((so3_exp(w).toRotationMatrix() - expected).norm(), 1e-14);
    }
  }
}

TEST(PoseGraph3D, EdgeJacobiansMatchCentralDifferences) {
  std::mt19937 rng(2);
  for (int trial = 0; trial < 50; ++trial) {
    // Errors from small to large (rotation errors up to about 2 rad).
    const double angle = trial < 25 ? 0.05 : 0.6;
    const Pose3 from = random_pose(rng, 3.0, 1.0), to = random_pose(rng, 3.0, 1.0);
    const Pose3 z = compose(between(from, to), random_pose(rng, 0.5, angle));
    const Pose3EdgeLinearization lin = linearize_pose3_edge(from, to, z);
    Matrix6d d_from, d_to;
    for (int k = 0; k < 6; ++k) {
      const Vector6d h = kFiniteDifferenceStep * Vector6d::Unit(k);
      d_from.col(k) = (linearize_pose3_edge(retract(from, h), to, z).error -
                       linearize_pose3_edge(retract(from, -h), to, z).error) /
                      (2.0 * kFiniteDifferenceStep);
      d_to.col(k) = (linearize_pose3_edge(from, retract(to, h), z).error -
                     linearize_pose3_edge(from, retract(to, -h), z).error) /
                    (2.0 * kFiniteDifferenceStep);
    }
    EXPECT_LE((lin.d_from - d_from).cwiseAbs().maxCoeff(), kJacobianTolerance) << "trial " << trial;
    EXPECT_LE((lin.d_to - d_to).cwiseAbs().maxCoeff(), kJacobianTolerance) << "trial " << trial;
  }
}

TEST(PoseGraph3D, PriorJacobianMatchesCentralDifferences) {
  std::mt19937 rng(12);
  for (int trial = 0; trial < 50; ++trial) {
    const double angle = trial < 25 ? 0.05 : 0.6;
    const Pose3 x = random_pose(rng, 3.0, 1.0);
    const Pose3 z = compose(x, random_pose(rng, 0.5, angle));
    const Pose3PriorLinearization lin = linearize_pose3_prior(x, z);
    // The prior is the edge from the world origin: the same error as that edge's.
    EXPECT_LE((lin.error - linearize_pose3_edge(Pose3{}, x, z).error).norm(), 1e-12) << "trial " << trial;
    Matrix6d d_pose;
    for (int k = 0; k < 6; ++k) {
      const Vector6d h = kFiniteDifferenceStep * Vector6d::Unit(k);
      d_pose.col(k) = (linearize_pose3_prior(retract(x, h), z).error - linearize_pose3_prior(retract(x, -h), z).error) /
                      (2.0 * kFiniteDifferenceStep);
    }
    EXPECT_LE((lin.d_pose - d_pose).cwiseAbs().maxCoeff(), kJacobianTolerance) << "trial " << trial;
  }
}

TEST(PoseGraph3D, PriorsHoldTheGraphInsteadOfTheFirstPose) {
  // Two poses, an edge saying they coincide, priors at z = 0 and z = 2 (identity rotations, unit
  // information): the optimum of a^2 + (b - a)^2 + (b - 2)^2 is a = 2/3, b = 4/3, chi2 = 4/3; the
  // first pose moves (it is not held when there are priors).
  for (const auto algorithm : {OptimizerAlgorithm::kGaussNewton, OptimizerAlgorithm::kLevenbergMarquardt}) {
    PoseGraph3D g;
    g.add_pose(0, {});
    g.add_pose(1, {});
    g.add_pose_edge(0, 1, {}, Matrix6d::Identity());
    Pose3 up;
    up.translation.z() = 2.0;
    g.add_pose_prior(0, {}, Matrix6d::Identity());
    g.add_pose_prior(1, up, Matrix6d::Identity());
    EXPECT_NEAR(g.chi2(), 4.0, 1e-15);
    ASSERT_EQ(g.prior_chi2().size(), 2);
    const OptimizationReport report = converged_optimum(g, algorithm);
    EXPECT_NEAR(report.chi2, 4.0 / 3.0, kExactTolerance);
    EXPECT_LE((g.vertex(0).value.translation - Eigen::Vector3d(0, 0, 2.0 / 3.0)).norm(), kExactTolerance);
    EXPECT_LE((g.vertex(1).value.translation - Eigen::Vector3d(0, 0, 4.0 / 3.0)).norm(), kExactTolerance);
    EXPECT_LE(rotation_distance(g.vertex(1).value.rotation, Eigen::Quaterniond::Identity()), kExactTolerance);
  }
}

TEST(PoseGraph3D, PriorBadInputIsRefused) {
  PoseGraph3D g;
  g.add_pose(0, {});
  EXPECT_THROW(g.add_pose_prior(3, {}, Matrix6d::Identity()), std::invalid_argument);  // unknown id
  Matrix6d indefinite = Matrix6d::Identity();
  indefinite(5, 5) = -1.0;
  EXPECT_THROW(g.add_pose_prior(0, {}, indefinite), std::invalid_argument);
  Pose3 bad;
  bad.rotation = Eigen::Quaterniond(2.0, 0, 0, 0);
  EXPECT_THROW(g.add_pose_prior(0, bad, Matrix6d::Identity()), std::invalid_argument);
  EXPECT_TRUE(g.pose_priors().empty());
}

// A loop of n poses with a few chords, edges the exact relative poses of `truth`.
PoseGraph3D exact_graph(const std::vector<Pose3>& truth, std::mt19937& rng) {
  PoseGraph3D g;
  const int n = static_cast<int>(truth.size());
  for (int i = 0; i < n; ++i) g.add_pose(10 + i, truth[i]);
  auto edge = [&](int i, int j) { g.add_pose_edge(10 + i, 10 + j, between(truth[i], truth[j]), random_information<6>(rng)); };
  for (int i = 0; i < n; ++i) edge(i, (i + 1) % n);
  for (int i = 0; i + 3 < n; i += 3) edge(i, i + 3);
  return g;
}

std::vector<Pose3> random_trajectory(std::mt19937& rng, int n) {
  std::vector<Pose3> truth = {random_pose(rng, 1.0, 1.0)};
  for (int i = 1; i < n; ++i) truth.push_back(compose(truth.back(), random_pose(rng, 1.0, 0.4)));
  return truth;
}

void perturb(PoseGraph3D& g, std::mt19937& rng, double translation, double angle) {
  std::vector<int> ids;
  std::vector<Pose3> poses;
  for (int v = 1; v < g.num_vertices(); ++v) {  // the first, held, keeps its value
    ids.push_back(g.vertex(v).id);
    poses.push_back(compose(g.vertex(v).value, random_pose(rng, translation, angle)));
  }
  g.set_poses(ids, poses);
}

TEST(PoseGraph3D, ExactLoopOptimisesToChi2Zero) {
  for (const auto algorithm : {OptimizerAlgorithm::kGaussNewton, OptimizerAlgorithm::kLevenbergMarquardt}) {
    std::mt19937 rng(3);
    const std::vector<Pose3> truth = random_trajectory(rng, 12);
    PoseGraph3D g = exact_graph(truth, rng);
    EXPECT_LE(g.chi2(), 1e-20);
    perturb(g, rng, 0.3, 0.2);
    EXPECT_GT(g.chi2(), 1.0);
    const OptimizationReport report = converged_optimum(g, algorithm);
    EXPECT_LE(report.chi2, 1e-18);
    for (int v = 0; v < g.num_vertices(); ++v) {
      EXPECT_LE((g.vertex(v).value.translation - truth[v].translation).norm(), kExactTolerance);
      EXPECT_LE(rotation_distance(g.vertex(v).value.rotation, truth[v].rotation), kExactTolerance);
    }
  }
}

TEST(PoseGraph3D, ChordalInitialisationIsExactWithoutNoise) {
  std::mt19937 rng(4);
  const std::vector<Pose3> truth = random_trajectory(rng, 30);
  PoseGraph3D g = exact_graph(truth, rng);
  perturb(g, rng, 5.0, 2.0);  // far from the truth: chordal does not use the stored values
  initialize_chordal(g);
  for (int v = 0; v < g.num_vertices(); ++v) {
    EXPECT_LE(rotation_distance(g.vertex(v).value.rotation, truth[v].rotation), kExactTolerance) << v;
    EXPECT_LE((g.vertex(v).value.translation - truth[v].translation).norm(), kExactTolerance) << v;
  }
  EXPECT_LE(g.chi2(), 1e-16);
}

TEST(PoseGraph3D, OdometryInitialisationComposesTheSpanningTree) {
  std::mt19937 rng(5);
  const std::vector<Pose3> truth = random_trajectory(rng, 10);
  PoseGraph3D g = exact_graph(truth, rng);
  perturb(g, rng, 5.0, 2.0);
  initialize_odometry(g);
  EXPECT_LE(g.chi2(), 1e-16);
}

TEST(PoseGraph3D, BadInputIsRefusedAndLeavesTheGraphUnchanged) {
  PoseGraph3D g;
  g.add_pose(0, {});
  g.add_pose(1, {});
  const Matrix6d info = Matrix6d::Identity();
  Pose3 z;
  z.translation.x() = 1.0;
  g.add_pose_edge(0, 1, z, info);
  const auto same = [&] { return g.num_vertices() == 2 && g.pose_edges().size() == 1; };

  EXPECT_THROW(g.add_pose(1, {}), std::invalid_argument);  // duplicate id
  Pose3 bad;
  bad.rotation = Eigen::Quaterniond(1.1, 0, 0, 0);
  EXPECT_THROW(g.add_pose(2, bad), std::invalid_argument);  // not unit
  bad.rotation = Eigen::Quaterniond(NAN, 0, 0, 0);
  EXPECT_THROW(g.add_pose(2, bad), std::invalid_argument);
  bad = {};
  bad.translation.x() = INFINITY;
  EXPECT_THROW(g.add_pose(2, bad), std::invalid_argument);
  EXPECT_TRUE(same());
  EXPECT_FALSE(g.has_vertex(2));

  EXPECT_THROW(g.add_pose_edge(0, 7, z, info), std::invalid_argument);  // unknown id
  EXPECT_THROW(g.add_pose_edge(0, 0, z, info), std::invalid_argument);
  Matrix6d nan_info = info;
  nan_info(2, 3) = NAN;
  EXPECT_THROW(g.add_pose_edge(0, 1, z, nan_info), std::invalid_argument);
  Matrix6d asymmetric = info;
  asymmetric(0, 5) = 0.5;
  EXPECT_THROW(g.add_pose_edge(0, 1, z, asymmetric), std::invalid_argument);
  Matrix6d indefinite = info;
  indefinite(4, 4) = -1.0;
  EXPECT_THROW(g.add_pose_edge(0, 1, z, indefinite), std::invalid_argument);
  Pose3 bad_z = z;
  bad_z.rotation = Eigen::Quaterniond(0.5, 0, 0, 0);
  EXPECT_THROW(g.add_pose_edge(0, 1, bad_z, info), std::invalid_argument);
  EXPECT_TRUE(same());

  // set_poses is all or nothing.
  Pose3 moved;
  moved.translation.x() = 5.0;
  EXPECT_THROW(g.set_poses({1, 9}, {moved, moved}), std::invalid_argument);
  EXPECT_THROW(g.set_poses({1, 0}, {moved, bad}), std::invalid_argument);
  EXPECT_EQ(g.vertex(1).value.translation.x(), 0.0);

  // A part not connected to the held first pose: refused by name, values unchanged.
  g.add_pose(5, moved);
  g.add_pose(6, {});
  g.add_pose_edge(5, 6, z, info);
  try {
    optimize(g);
    FAIL() << "a floating part was optimised";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("5, 6"), std::string::npos) << e.what();
  }
  EXPECT_THROW(initialize_chordal(g), std::invalid_argument);
  EXPECT_EQ(g.vertex(g.index_of(5)).value.translation.x(), 5.0);
  EXPECT_EQ(g.vertex(1).value.translation.x(), 0.0);
}

TEST(PoseGraph3D, MarginalsOfAChainAddUp) {
  // Two poses, the first fixed, one edge with information Omega: the second pose's covariance in
  // its own tangent is (J^T Omega J)^-1 with J = d e / d x_to.
  std::mt19937 rng(6);
  PoseGraph3D g;
  const Pose3 a = random_pose(rng, 1.0, 1.0), b = random_pose(rng, 1.0, 1.0);
  g.add_pose(0, a);
  g.add_pose(1, b);
  g.set_fixed(0);
  const Matrix6d info = random_information<6>(rng);
  g.add_pose_edge(0, 1, between(a, b), info);
  const Matrix6d j = linearize_pose3_edge(a, b, between(a, b)).d_to;
  const Matrix6d expected = (j.transpose() * info * j).inverse();
  const auto cov = marginal_covariances(g, {0, 1});
  EXPECT_EQ(cov[0].norm(), 0.0);
  EXPECT_LE((cov[1] - expected).norm(), 1e-10 * expected.norm());
}

// sphere2500 (g2o EDGE_SE3:QUAT) with a minimal parser for this test only: chi2 reached from
// odometry and from the chordal initialisation, printed for the record.
bool read_g2o_3d(const std::string& path, PoseGraph3D& g) {
  std::ifstream in(path);
  if (!in) return false;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "VERTEX_SE3:QUAT") {
      int id;
      double x, y, z, qx, qy, qz, qw;
      s >> id >> x >> y >> z >> qx >> qy >> qz >> qw;
      Pose3 p{Eigen::Quaterniond(qw, qx, qy, qz).normalized(), {x, y, z}};
      g.add_pose(id, p);
    } else if (tag == "EDGE_SE3:QUAT") {
      int a, b;
      double x, y, z, qx, qy, qz, qw;
      s >> a >> b >> x >> y >> z >> qx >> qy >> qz >> qw;
      Matrix6d info;
      for (int r = 0; r < 6; ++r)
        for (int c = r; c < 6; ++c) {
          s >> info(r, c);
          info(c, r) = info(r, c);
        }
      g.add_pose_edge(a, b, {Eigen::Quaterniond(qw, qx, qy, qz).normalized(), {x, y, z}}, info);
    }
  }
  return true;
}

TEST(PoseGraph3D, Sphere2500FromOdometryAndFromChordal) {
  const std::string path = std::string(PROBSLAM_SHARED_DATA) + "/pose_graphs/sphere2500/sphere2500.g2o";
  PoseGraph3D g;
  if (!read_g2o_3d(path, g)) GTEST_SKIP() << path << " not found";
  ASSERT_EQ(g.num_vertices(), 2500);
  PoseGraph3D chordal = g;
  initialize_odometry(g);
  const double odometry_chi2 = g.chi2();
  const OptimizationReport from_odometry = optimize(g);
  initialize_chordal(chordal);
  const double chordal_chi2 = chordal.chi2();
  const OptimizationReport from_chordal = optimize(chordal);
  std::cout << "sphere2500: odometry chi2 " << odometry_chi2 << " -> " << from_odometry.chi2 << " in "
            << from_odometry.iterations << " iterations (" << from_odometry.stop_reason << "); chordal chi2 "
            << chordal_chi2 << " -> " << from_chordal.chi2 << " in " << from_chordal.iterations << " iterations ("
            << from_chordal.stop_reason << ")\n";
  EXPECT_LT(chordal_chi2, odometry_chi2);
  EXPECT_LE(from_chordal.chi2, from_odometry.chi2 * (1.0 + 1e-6));
}

}  // namespace
}  // namespace probslam
