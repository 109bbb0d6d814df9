#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "probslam/core/range_bearing_model.hpp"
#include "probslam/ekf/ekf_slam.hpp"
#include "probslam/ekf/multi_hypothesis_ekf_slam.hpp"

using namespace probslam;

namespace {
EkfSlam make() {
  return EkfSlam(Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal().toDenseMatrix(),
                 Eigen::Vector2d(0.01, 0.001).asDiagonal().toDenseMatrix(), false, Eigen::Vector3d::Zero(),
                 Eigen::Matrix3d::Identity() * 0.01);
}
}  // namespace

TEST(EkfSlam, AugmentUpdateAndSymmetry) {
  EkfSlam ekf = make();
  ekf.predict(1.0, 0.2, 0.5);
  RowMatrixXd z(2, 2);
  z << 3.0, 0.4, 2.0, -1.0;
  const Eigen::Vector3d before = ekf.pose();
  ekf.update(z, {4, 9});
  EXPECT_EQ(ekf.num_landmarks(), 2);
  EXPECT_EQ(ekf.pose(), before);  // first sightings never move the robot
  EXPECT_LT((ekf.landmark(4) - landmark_from_range_bearing(before, Eigen::Vector2d(3.0, 0.4))).norm(), 1e-12);
  RowMatrixXd again(1, 2);
  again << 3.05, 0.41;
  const UpdateReport r = ekf.update(again, {4});
  EXPECT_TRUE(std::isfinite(r.nis[0]));
  const Eigen::MatrixXd p = ekf.covariance();
  EXPECT_EQ((p - p.transpose()).cwiseAbs().maxCoeff(), 0.0);
  ekf.remove_landmark(4);
  EXPECT_EQ(ekf.state_dim(), 5);
  EXPECT_THROW(ekf.landmark_covariance(4), std::invalid_argument);
}

TEST(EkfSlam, RejectsBadInputAndKeepsState) {
  EXPECT_THROW(EkfSlam(-Eigen::Matrix3d::Identity(), Eigen::Matrix2d::Identity(), false, Eigen::Vector3d::Zero(),
                       Eigen::Matrix3d::Zero()),
               std::invalid_argument);
  EXPECT_THROW(EkfSlam(Eigen::Matrix3d::Identity(), Eigen::Matrix2d::Identity(), true, Eigen::Vector3d::Zero(),
                       Eigen::Matrix3d::Zero()),
               std::invalid_argument);
  EkfSlam ekf = make();
  ekf.update(RowMatrixXd::Constant(1, 2, 1.0), {1});
  const Eigen::VectorXd mean = ekf.mean();
  EXPECT_THROW(ekf.predict(1.0, 0.0, 0.0), std::invalid_argument);
  RowMatrixXd bad(1, 2);
  bad << -1.0, 0.0;
  EXPECT_THROW(ekf.update(bad, {1}), std::invalid_argument);
  bad << NAN, 0.0;
  EXPECT_THROW(ekf.update(bad, {1}), std::invalid_argument);
  EXPECT_THROW(ekf.update(RowMatrixXd::Constant(2, 2, 1.0), {1}), std::invalid_argument);
  EXPECT_EQ(ekf.mean(), mean);
}

TEST(EkfSlam, PairingLikelihoodIsTheUpdatesNisAndACopyIsIndependent) {
  EkfSlam ekf = make();
  RowMatrixXd z(1, 2);
  z << 3.0, 0.4;
  ekf.update(z, {4});
  ekf.predict(0.5, 0.1, 1.0);
  z << 2.6, 0.35;
  const EkfSlam copy = ekf;
  const EkfSlam::PairingLikelihood p = ekf.pairing_likelihood(z.row(0).transpose(), 4);
  const UpdateReport r = ekf.update(z, {4});
  EXPECT_NEAR(p.nis, r.nis[0], 1e-12);
  EXPECT_TRUE(std::isfinite(p.log_det));
  EXPECT_NE(copy.pose(), ekf.pose());  // the update moved only the original
  EXPECT_THROW(ekf.pairing_likelihood(z.row(0).transpose(), 7), std::invalid_argument);
}

// A copy (constructor or assignment) holds everything the original held, in its own storage:
// the implicit copy used to share it, so an update of one moved the other's mean too.
TEST(EkfSlam, CopiesAreDeep) {
  EkfSlam ekf = make();
  MapManagement mm;
  mm.provisional = true;
  ekf.set_map_management(mm);
  RowMatrixXd z(2, 2);
  z << 3.0, 0.4, 2.0, -1.0;
  ekf.update(z, {4, 9});
  ekf.update_unknown(z, 0.5, 0.9);
  ekf.predict(0.5, 0.1, 1.0);
  EkfSlam assigned = make();
  assigned = ekf;
  for (const EkfSlam* c : {&assigned}) {
    const EkfSlam copy = ekf;
    for (const EkfSlam& x : {copy, *c}) {
      EXPECT_NE(x.storage(), ekf.storage());
      EXPECT_EQ(x.state_dim(), ekf.state_dim());
      EXPECT_EQ(x.landmark_ids(), ekf.landmark_ids());
      EXPECT_EQ(x.num_provisional(), ekf.num_provisional());
      EXPECT_EQ(x.map_management().provisional, ekf.map_management().provisional);
      EXPECT_EQ(x.gate_distance(), ekf.gate_distance());
      EXPECT_EQ(x.measurement_noise(), ekf.measurement_noise());
      EXPECT_EQ(Eigen::VectorXd(x.storage()->mean.head(x.state_dim())),
                Eigen::VectorXd(ekf.storage()->mean.head(ekf.state_dim())));
      for (const long id : ekf.landmark_ids()) EXPECT_EQ(x.existence(id), ekf.existence(id));
      EXPECT_EQ(x.signatures(), ekf.signatures());
      EXPECT_EQ(x.signature_variances(), ekf.signature_variances());
    }
  }
  // The same calls on a copy and on the original give the same results; neither moves the other.
  EkfSlam copy = ekf;
  const Eigen::Vector3d before = ekf.pose();
  copy.predict(1.0, 0.2, 1.0);
  EXPECT_EQ(ekf.pose(), before);
  ekf.predict(1.0, 0.2, 1.0);
  EXPECT_EQ(ekf.pose(), copy.pose());
  const AssociationReport a = ekf.update_unknown(z, 0.5, 0.9), b = copy.update_unknown(z, 0.5, 0.9);
  EXPECT_EQ(a.ids, b.ids);
  EXPECT_EQ(Eigen::VectorXd(ekf.mean()), Eigen::VectorXd(copy.mean()));
}

TEST(MultiHypothesisEkfSlam, KeepsTheCheapestBranchAndValidates) {
  MultiHypothesisOptions o;
  EkfSlam ekf = make();
  MultiHypothesisEkfSlam mht(ekf, o);
  RowMatrixXd z(2, 2);
  z << 3.0, 0.4, 2.0, -1.0;
  mht.update(z);
  mht.predict(0.2, 0.0, 0.5);  // to (0.1, 0, 0)
  RowMatrixXd again(2, 2);     // both seen again, exactly, from there
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector2d m = landmark_from_range_bearing(Eigen::Vector3d::Zero(), z.row(i).transpose());
    again(i, 0) = std::hypot(m.x() - 0.1, m.y());
    again(i, 1) = std::atan2(m.y(), m.x() - 0.1);
  }
  const std::vector<long> ids = mht.update(again);
  const std::vector<std::vector<long>> history = mht.history();
  EXPECT_EQ(history.size(), 2u);
  for (int i = 0; i < 2; ++i) EXPECT_EQ(ids[i], history[0][i]);  // re-seen, not new or clutter
  EXPECT_GE(ids[0], 0);
  EXPECT_NE(ids[0], ids[1]);
  EXPECT_LE(mht.num_hypotheses(), o.max_hypotheses);
  EXPECT_EQ(mht.costs().front(), 0.0);
  RowMatrixXd bad(1, 2);
  bad << -1.0, 0.0;
  EXPECT_THROW(mht.update(bad), std::invalid_argument);
  EXPECT_EQ(mht.history().size(), 2u);
  o.max_hypotheses = 0;
  EXPECT_THROW(MultiHypothesisEkfSlam(ekf, o), std::invalid_argument);
  o = MultiHypothesisOptions{};
  o.clutter_cost = -1.0;
  EXPECT_THROW(MultiHypothesisEkfSlam(ekf, o), std::invalid_argument);
}
