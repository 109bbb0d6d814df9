#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "probslam/core/chi_square.hpp"
#include "probslam/ekf/ekf_slam.hpp"
#include "probslam/ekf/joint_compatibility.hpp"

using namespace probslam;

TEST(ChiSquare, KnownQuantilesAndCdf) {
  // Reference values from published chi-square tables.
  EXPECT_NEAR(chi_square_quantile(0.95, 1), 3.841458820694124, 1e-9);
  EXPECT_NEAR(chi_square_quantile(0.99, 2), 9.210340371976182, 1e-9);
  EXPECT_NEAR(chi_square_quantile(0.99, 3), 11.344866730144373, 1e-9);
  EXPECT_NEAR(chi_square_quantile(0.99, 14), 29.141237740672796, 1e-9);
  EXPECT_NEAR(chi_square_quantile(1.0 - 1e-6, 2), 27.631021115928547, 1e-8);
  EXPECT_NEAR(chi_square_cdf(2.0, 2), 1.0 - std::exp(-1.0), 1e-14);  // 2 dof: 1 - exp(-x/2)
  EXPECT_EQ(chi_square_cdf(-1.0, 3), 0.0);
  EXPECT_EQ(chi_square_cdf(std::numeric_limits<double>::infinity(), 3), 1.0);
  for (int dof : {1, 2, 5, 20})
    for (double p : {0.01, 0.5, 0.99, 0.999999}) EXPECT_NEAR(chi_square_cdf(chi_square_quantile(p, dof), dof), p, 1e-12);
  EXPECT_THROW(chi_square_quantile(1.0, 2), std::invalid_argument);
  EXPECT_THROW(chi_square_quantile(0.5, 0), std::invalid_argument);
  EXPECT_THROW(chi_square_cdf(std::nan(""), 2), std::invalid_argument);
}

namespace {
// Measurement i of target j with a 2x2 identity Jacobian on state columns (2j, 2j+1).
Pairing pair(int i, int j, double nu0, double nu1) {
  Pairing p;
  p.measurement = i;
  p.target = j;
  p.innovation = Eigen::Vector2d(nu0, nu1);
  p.jacobian = Eigen::Matrix2d::Identity();
  p.columns = {2 * j, 2 * j + 1};
  p.noise = Eigen::Matrix2d::Identity() * 0.01;
  return p;
}
}  // namespace

TEST(JointCompatibility, CorrelatedErrorsPickTheConsistentPairing) {
  // Two targets whose errors are almost perfectly correlated (a shared pose error): both
  // measurements shifted by the same 0.9 fit (0 -> 0, 1 -> 1) jointly, although measurement 0
  // alone is closer to target 1.
  Eigen::MatrixXd p = Eigen::MatrixXd::Zero(4, 4);
  p.topLeftCorner(2, 2) = p.bottomRightCorner(2, 2) = p.topRightCorner(2, 2) = p.bottomLeftCorner(2, 2) =
      Eigen::Matrix2d::Identity();
  const std::vector<Pairing> pairings = {pair(0, 0, 0.9, 0.0), pair(0, 1, -0.1, 0.0), pair(1, 1, 0.9, 0.0),
                                         pair(1, 0, 1.9, 0.0)};
  std::vector<double> gates(3);
  for (int n = 1; n <= 2; ++n) gates[n] = chi_square_quantile(0.99, 2 * n);
  const JointAssociation a = joint_compatibility(2, pairings, p, gates);
  EXPECT_EQ(a.pairings, 2);
  EXPECT_EQ(a.target, (std::vector<int>{0, 1}));
  // The common shift costs what one shift of the shared error costs: nu^T S^-1 nu with
  // S = [[1.01, 1], [1, 1.01]] along x and nu = (0.9, 0.9).
  EXPECT_NEAR(a.nis, 2 * 0.81 / 2.01, 1e-12);
  // With no compatible pairing the empty hypothesis comes back.
  const JointAssociation none = joint_compatibility(2, {}, p, gates);
  EXPECT_EQ(none.pairings, 0);
  EXPECT_EQ(none.target, (std::vector<int>{-1, -1}));
}

TEST(JointCompatibility, RejectsInconsistentInput) {
  const Eigen::MatrixXd p = Eigen::MatrixXd::Identity(4, 4);
  const std::vector<double> gates(3, 10.0);
  EXPECT_THROW(joint_compatibility(2, {pair(2, 0, 0, 0)}, p, gates), std::invalid_argument);  // measurement
  EXPECT_THROW(joint_compatibility(2, {pair(0, 2, 0, 0)}, p, gates), std::invalid_argument);  // column 4
  EXPECT_THROW(joint_compatibility(2, {pair(0, 0, 0, 0)}, p, std::vector<double>(2, 1.0)), std::invalid_argument);
  Pairing bad = pair(0, 0, 0, 0);
  bad.noise = Eigen::Matrix3d::Identity();
  EXPECT_THROW(joint_compatibility(2, {bad}, p, gates), std::invalid_argument);
  bad = pair(0, 0, std::nan(""), 0);
  EXPECT_THROW(joint_compatibility(2, {bad}, p, gates), std::invalid_argument);
}

TEST(EkfSlam, JointCompatibilityTellsSwappedNeighboursApart) {
  // Two landmarks 0.3 m apart across the line of sight; the robot's heading is uncertain
  // (0.1 rad, i.e. 0.3 m at 3 m), so each sighting alone fits either landmark.
  Eigen::Matrix3d pose_cov = Eigen::Vector3d(1e-6, 1e-6, 0.01).asDiagonal();
  const Eigen::MatrixXd q = Eigen::Vector2d(1e-4, 1e-5).asDiagonal();
  for (const Association method : {Association::kMaximumLikelihood, Association::kJointCompatibility}) {
    EkfSlam ekf(Eigen::Matrix3d::Identity() * 1e-6, q, false, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero());
    RowMatrixXd first(2, 2);
    first << 3.0, 0.05, 3.0, -0.05;
    ekf.update(first, {0, 1});
    ekf.covariance().topLeftCorner<3, 3>() += pose_cov;  // the heading becomes uncertain
    // Seen again with the heading 0.09 rad off: landmark 1 now appears where 0 was.
    RowMatrixXd z(2, 2);
    z << 3.0, 0.05 + 0.09, 3.0, -0.05 + 0.09;
    const AssociationReport r = ekf.update_unknown(z, chi_square_quantile(0.99, 2), chi_square_quantile(1 - 1e-6, 2),
                                                  method);
    if (method == Association::kJointCompatibility) {
      EXPECT_EQ(r.ids, (std::vector<long>{0, 1}));
    } else {  // one at a time, the nearer landmark wins and the other measurement goes astray
      EXPECT_NE(r.ids, (std::vector<long>{0, 1}));
    }
  }
}

TEST(EkfSlam, UnknownAssociationMethodIsRejected) {
  EkfSlam ekf(Eigen::Matrix3d::Identity() * 1e-3, Eigen::Matrix2d::Identity() * 1e-3, false, Eigen::Vector3d::Zero(),
              Eigen::Matrix3d::Zero());
  RowMatrixXd z(1, 2);
  z << 2.0, 0.1;
  ekf.update(z, {3});
  const Eigen::VectorXd mean = ekf.mean();
  EXPECT_THROW(ekf.update_unknown(z, 9.0, 30.0, static_cast<Association>(7)), std::invalid_argument);
  EXPECT_EQ(Eigen::VectorXd(ekf.mean()), mean);
}
