// Issue 12 in the graph area, for C++ callers: singularity judged per variable (not by a
// condition-number cut), anchoring judged by the graph's structure, all-or-nothing optimisation,
// and iSAM's two id spaces through parse_pose_graph / write_isam.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <sstream>
#include <stdexcept>
#include <string>

#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/sparse_cholesky.hpp"
#include "probslam/io/pose_graph_file.hpp"

namespace probslam {
namespace {

SparseMatrixd upper_of(const Eigen::MatrixXd& dense) {
  SparseMatrixd a(dense.rows(), dense.cols());
  for (Eigen::Index c = 0; c < dense.cols(); ++c)
    for (Eigen::Index r = 0; r <= c; ++r)
      if (dense(r, c) != 0.0) a.insert(r, c) = dense(r, c);
  a.makeCompressed();
  return a;
}

TEST(ReliabilityGraph, InformationSpanningTwentyFourDecadesIsFactorised) {
  // A chain whose first variable is tied by 1e12 and the rest by 1e-12: condition ~1e24, and
  // every pivot exact to rounding, so the solve is as good as the data.
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(3, 3);
  h(0, 0) = 1e12 + 1e-12;
  h(1, 1) = 2e-12;
  h(2, 2) = 1e-12;
  h(0, 1) = h(1, 0) = -1e-12;
  h(1, 2) = h(2, 1) = -1e-12;
  SparseCholesky cholesky;
  ASSERT_NO_THROW(cholesky.factorize(upper_of(h)));
  // The anchor pulls x0 to 1, the weak chain's right-hand side makes each step 1: x = (1, 2, 3).
  const Eigen::VectorXd x = cholesky.solve(Eigen::VectorXd(Eigen::Vector3d(1e12, 0.0, 1e-12)));
  EXPECT_LT((x - Eigen::Vector3d(1.0, 2.0, 3.0)).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(ReliabilityGraph, APivotLostInRoundingIsRefusedAtItsColumn) {
  // Two variables tied by 1e12 whose common motion has information 1e-12: in double precision
  // 1e12 + 1e-12 == 1e12, so the pair is singular to working precision.
  Eigen::MatrixXd h(2, 2);
  h << 1e12 + 1e-12, -1e12, -1e12, 1e12 + 1e-12;
  SparseCholesky cholesky;
  EXPECT_THROW(cholesky.factorize(upper_of(h)), std::invalid_argument);
  EXPECT_GE(cholesky.singular_column(), 0);
}

PoseGraph2D two_parts() {
  PoseGraph2D g;
  for (int i = 0; i < 3; ++i) g.add_pose(i, Eigen::Vector3d(i, 0.0, 0.0));
  g.add_pose(7, Eigen::Vector3d(0.0, 5.0, 0.0));
  g.add_pose(8, Eigen::Vector3d(1.0, 5.0, 0.0));
  g.add_pose_edge(0, 1, Eigen::Vector3d(1.0, 0.1, 0.0), Eigen::Matrix3d::Identity());
  g.add_pose_edge(1, 2, Eigen::Vector3d(1.0, 0.1, 0.0), Eigen::Matrix3d::Identity());
  g.add_pose_edge(7, 8, Eigen::Vector3d(1.0, 0.2, 0.0), Eigen::Matrix3d::Identity());
  return g;
}

TEST(ReliabilityGraph, AFloatingPartIsRefusedByNameUnderBothAlgorithms) {
  for (const auto algorithm : {OptimizerAlgorithm::kGaussNewton, OptimizerAlgorithm::kLevenbergMarquardt}) {
    PoseGraph2D g = two_parts();
    const std::vector<Eigen::Vector3d> before = g.values();
    OptimizerOptions options;
    options.algorithm = algorithm;
    try {
      optimize(g, options);
      FAIL() << "a floating part was optimised";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("vertices 7, 8 "), std::string::npos) << e.what();
    }
    EXPECT_EQ(g.values(), before);
  }
}

TEST(ReliabilityGraph, SetValuesIsAllOrNothing) {
  PoseGraph2D g = two_parts();
  const std::vector<Eigen::Vector3d> before = g.values();
  EXPECT_THROW(g.set_values({1, 2, 99}, {Eigen::Vector3d::Ones(), Eigen::Vector3d::Ones(), Eigen::Vector3d::Ones()},
                            VertexKind::kPose),
               std::invalid_argument);
  EXPECT_EQ(g.values(), before);
}

TEST(ReliabilityGraph, IsamLandmarkIdsLiveApartFromPoseIds) {
  const std::string text =
      "ODOMETRY 0 1 1 0.1 0.2 10 0 0 10 0 20\n"
      "ODOMETRY 1 2 1 -0.1 0.3 10 0 0 10 0 20\n"
      "LANDMARK 0 1 2 1 3 0 3\n"
      "LANDMARK 2 1 0.2 -0.8 3 0 3\n"
      "LANDMARK 1 2 0.5 0.5 3 0 3\n";
  std::istringstream in(text);
  const PoseGraph2D g = parse_pose_graph(in);
  ASSERT_EQ(g.num_vertices(), 5);
  EXPECT_EQ(g.vertex(3).kind, VertexKind::kPoint);
  EXPECT_EQ(g.vertex(3).landmark_id, 1);
  EXPECT_EQ(g.vertex(4).landmark_id, 2);
  EXPECT_NE(g.vertex(3).id, 1);  // moved past the pose ids: the graph has one id space
  std::ostringstream out;
  write_isam(out, g);
  std::istringstream written(out.str()), original(text);
  std::string a, b;
  while (std::getline(original, a)) {
    ASSERT_TRUE(std::getline(written, b));
    std::istringstream fa(a), fb(b);
    std::string ta, tb;
    for (int k = 0; k < 3; ++k) {  // tag and both ids
      fa >> ta;
      fb >> tb;
      EXPECT_EQ(ta, tb);
    }
  }
}

}  // namespace
}  // namespace probslam
