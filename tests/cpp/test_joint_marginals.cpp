// joint_marginal_covariances against the dense inverse of an information matrix built here from
// the edge errors alone (numerical Jacobians of errors written out in this file), so neither the
// optimiser's assembly nor its analytic Jacobians are the reference.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>
#include <vector>

#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_2d.hpp"

namespace probslam {
namespace {

// Central differences with this step have a truncation error ~ step^2 and a rounding error ~
// 1e-16 / step: about 1e-10 in each Jacobian entry, ~1e-8 relative in a covariance entry of this
// well-conditioned graph. Agreement is required to this fraction of the largest entry compared.
constexpr double kDifferenceStep = 1e-6;
constexpr double kTolerance = 1e-6;

Eigen::Matrix2d rotation(double theta) {
  Eigen::Matrix2d r;
  r << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta);
  return r;
}

double wrapped(double a) { return std::atan2(std::sin(a), std::cos(a)); }

// t2v(z^-1 x_from^-1 x_to), written from the definition.
Eigen::Vector3d pose_error(const Eigen::Vector3d& from, const Eigen::Vector3d& to, const Eigen::Vector3d& z) {
  const Eigen::Vector2d rel = rotation(from[2]).transpose() * (to.head<2>() - from.head<2>());
  const Eigen::Vector2d e = rotation(z[2]).transpose() * (rel - z.head<2>());
  return {e[0], e[1], wrapped(to[2] - from[2] - z[2])};
}

// The point in the pose's frame minus the measurement.
Eigen::Vector2d point_error(const Eigen::Vector3d& pose, const Eigen::Vector2d& point, const Eigen::Vector2d& z) {
  return rotation(pose[2]).transpose() * (point - pose.head<2>()) - z;
}

// A loop of six poses, three points each seen from three or four poses, values off the optimum
// (the marginals are those of the information at the current values, not only at a minimum).
PoseGraph2D test_graph(std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, 0.05);
  PoseGraph2D g;
  const double step = 2.0 * M_PI / 6.0;
  for (int k = 0; k < 6; ++k) {
    const double a = k * step;
    g.add_pose(k, {3.0 * std::cos(a) + noise(rng), 3.0 * std::sin(a) + noise(rng), a + M_PI / 2 + noise(rng)});
  }
  Eigen::Matrix3d odometry_information = Eigen::Vector3d(100.0, 60.0, 400.0).asDiagonal();
  odometry_information(0, 1) = odometry_information(1, 0) = 20.0;
  for (int k = 0; k < 6; ++k) {
    const int next = (k + 1) % 6;  // the last edge closes the loop
    g.add_pose_edge(k, next, {3.0 * std::sin(step) * 1.0, 3.0 * (1.0 - std::cos(step)), step},
                    odometry_information);
  }
  const std::vector<Eigen::Vector2d> points = {{0.5, 0.2}, {4.5, 1.0}, {-2.0, -4.0}};
  const std::vector<std::vector<int>> seen_from = {{0, 1, 2, 3}, {0, 1, 5}, {3, 4, 5}};
  Eigen::Matrix2d point_information;
  point_information << 50.0, -10.0, -10.0, 30.0;
  for (int p = 0; p < 3; ++p) {
    g.add_point(10 + p, points[p] + Eigen::Vector2d(noise(rng), noise(rng)));
    for (const int k : seen_from[p]) {
      const Eigen::Vector3d x = g.vertex(g.index_of(k)).value;
      const Eigen::Vector2d z = rotation(x[2]).transpose() * (points[p] - x.head<2>());
      g.add_point_edge(k, 10 + p, z + Eigen::Vector2d(noise(rng), noise(rng)), point_information);
    }
  }
  return g;
}

// The dense covariance of the free variables (every vertex but `held`), in vertex order, and
// each vertex's first row in it (-1 for the held vertex).
Eigen::MatrixXd dense_covariance(const PoseGraph2D& g, int held, std::vector<int>& row_of) {
  row_of.assign(g.num_vertices(), -1);
  int n = 0;
  for (int v = 0; v < g.num_vertices(); ++v) {
    if (v == held) continue;
    row_of[v] = n;
    n += g.vertex(v).kind == VertexKind::kPose ? 3 : 2;
  }
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(n, n);
  // One edge: the error as a function of the stacked (a, b) values, differenced numerically.
  auto add = [&](int a, int b, int dim, const Eigen::MatrixXd& information,
                 const std::function<Eigen::VectorXd(const Eigen::Vector3d&, const Eigen::Vector3d&)>& error) {
    const int da = g.vertex(a).kind == VertexKind::kPose ? 3 : 2, db = g.vertex(b).kind == VertexKind::kPose ? 3 : 2;
    Eigen::MatrixXd j(dim, da + db);
    for (int c = 0; c < da + db; ++c) {
      Eigen::Vector3d xa = g.vertex(a).value, xb = g.vertex(b).value;
      double& entry = c < da ? xa[c] : xb[c - da];
      entry += kDifferenceStep;
      const Eigen::VectorXd plus = error(xa, xb);
      entry -= 2.0 * kDifferenceStep;
      const Eigen::VectorXd minus = error(xa, xb);
      j.col(c) = (plus - minus) / (2.0 * kDifferenceStep);
    }
    const Eigen::MatrixXd jtoj = j.transpose() * information * j;
    const int rows[2] = {row_of[a], row_of[b]}, dims[2] = {da, db};
    for (int s = 0; s < 2; ++s)
      for (int t = 0; t < 2; ++t)
        if (rows[s] >= 0 && rows[t] >= 0)
          h.block(rows[s], rows[t], dims[s], dims[t]) += jtoj.block(s ? da : 0, t ? da : 0, dims[s], dims[t]);
  };
  for (const PoseEdge& e : g.pose_edges())
    add(e.from, e.to, 3, e.information, [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) -> Eigen::VectorXd {
      return pose_error(a, b, e.measurement);
    });
  for (const PointEdge& e : g.point_edges())
    add(e.pose, e.point, 2, e.information, [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) -> Eigen::VectorXd {
      return point_error(a, b.head<2>(), e.measurement);
    });
  return h.inverse();
}

// The dense reference's joint covariance of a group (zero rows and columns for the held vertex).
Eigen::MatrixXd dense_joint(const PoseGraph2D& g, const Eigen::MatrixXd& cov, const std::vector<int>& row_of,
                            const std::vector<int>& ids) {
  std::vector<int> rows;
  for (const int id : ids) {
    const int v = g.index_of(id);
    const int dim = g.vertex(v).kind == VertexKind::kPose ? 3 : 2;
    for (int c = 0; c < dim; ++c) rows.push_back(row_of[v] < 0 ? -1 : row_of[v] + c);
  }
  const int n = static_cast<int>(rows.size());
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(n, n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c)
      if (rows[r] >= 0 && rows[c] >= 0) out(r, c) = cov(rows[r], rows[c]);
  return out;
}

const std::vector<std::vector<int>> kGroups = {
    {10, 11},         // a landmark pair (ch. 11.6's test), seen from shared poses
    {11, 12},         // a pair with no pose in common: the cross block lies outside the pattern
    {3, 12},          // a pose and a landmark it sees
    {12, 0, 10, 4},   // mixed, with the held first pose inside
    {5},              // one vertex: marginal_covariances' block
};

TEST(JointMarginalCovariances, EqualTheDenseInverseIncludingCrossBlocks) {
  std::mt19937 rng(3);
  const PoseGraph2D g = test_graph(rng);
  std::vector<int> row_of;
  const Eigen::MatrixXd cov = dense_covariance(g, 0, row_of);  // nothing fixed: the first pose is held
  const std::vector<Eigen::MatrixXd> joint = joint_marginal_covariances(g, kGroups);
  ASSERT_EQ(joint.size(), kGroups.size());
  for (size_t k = 0; k < kGroups.size(); ++k) {
    const Eigen::MatrixXd expected = dense_joint(g, cov, row_of, kGroups[k]);
    ASSERT_EQ(joint[k].rows(), expected.rows()) << "group " << k;
    EXPECT_LT((joint[k] - expected).cwiseAbs().maxCoeff(), kTolerance * expected.cwiseAbs().maxCoeff())
        << "group " << k << "\n" << joint[k] << "\nexpected\n" << expected;
    EXPECT_LT((joint[k] - joint[k].transpose()).cwiseAbs().maxCoeff(), 1e-12 * expected.cwiseAbs().maxCoeff());
  }
  // The cross-covariance matters: the pair's difference has a smaller variance than the sum of
  // the marginals' (the shared poses' error cancels), which is why ch. 11.6 needs the joint.
  const Eigen::Matrix<double, 2, 4> d = (Eigen::Matrix<double, 2, 4>() << Eigen::Matrix2d::Identity(),
                                         -Eigen::Matrix2d::Identity()).finished();
  const Eigen::Matrix2d with_cross = d * joint[0] * d.transpose();
  const Eigen::Matrix2d without = joint[0].topLeftCorner<2, 2>() + joint[0].bottomRightCorner<2, 2>();
  EXPECT_LT(with_cross.trace(), without.trace());
}

TEST(JointMarginalCovariances, HonourAFixedVertexAndAgreeWithMarginalCovariances) {
  std::mt19937 rng(5);
  PoseGraph2D g = test_graph(rng);
  g.set_fixed(2);
  std::vector<int> row_of;
  const Eigen::MatrixXd cov = dense_covariance(g, g.index_of(2), row_of);
  const std::vector<std::vector<int>> groups = {{2, 11}, {0, 10}, {12}};
  const std::vector<Eigen::MatrixXd> joint = joint_marginal_covariances(g, groups);
  for (size_t k = 0; k < groups.size(); ++k) {
    const Eigen::MatrixXd expected = dense_joint(g, cov, row_of, groups[k]);
    EXPECT_LT((joint[k] - expected).cwiseAbs().maxCoeff(), kTolerance * expected.cwiseAbs().maxCoeff()) << k;
  }
  EXPECT_EQ(joint[0].topLeftCorner(3, 3).cwiseAbs().maxCoeff(), 0.0);  // the fixed pose
  EXPECT_EQ(joint[0].topRightCorner(3, 2).cwiseAbs().maxCoeff(), 0.0);
  const std::vector<Eigen::MatrixXd> single = marginal_covariances(g, {0, 10, 12, 2});
  EXPECT_TRUE(single[0].isApprox(joint[1].topLeftCorner(3, 3), 1e-12));
  EXPECT_TRUE(single[1].isApprox(joint[1].bottomRightCorner(2, 2), 1e-12));
  EXPECT_TRUE(single[2].isApprox(joint[2], 1e-12));
  EXPECT_EQ(single[3].cwiseAbs().maxCoeff(), 0.0);
}

TEST(JointMarginalCovariances, RefuseUnknownAndRepeatedIdsBeforeAnyWork) {
  std::mt19937 rng(7);
  const PoseGraph2D g = test_graph(rng);
  EXPECT_THROW(joint_marginal_covariances(g, {{10, 99}}), std::invalid_argument);
  try {
    joint_marginal_covariances(g, {{10, 11}, {11, 3, 11}});
    FAIL() << "a repeated id was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("groups"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("group 1"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(joint_marginal_covariances(g, {}).empty());
  EXPECT_EQ(joint_marginal_covariances(g, {{}}).at(0).size(), 0);
}

}  // namespace
}  // namespace probslam
