// Issue 12 in the C++ EKF and core models: validation by the classes themselves (not only the
// bindings), messages that start with the argument's name, all-or-nothing calls.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

#include "probslam/core/pose2.hpp"
#include "probslam/core/spatial_hash_2d.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "probslam/ekf/ekf_slam.hpp"
#include "probslam/ekf/multi_hypothesis_ekf_slam.hpp"
#include "test_support.hpp"

using namespace probslam;

namespace {

using test_support::expect_invalid;

Eigen::MatrixXd diag(std::initializer_list<double> v) {
  Eigen::VectorXd d(v.size());
  int i = 0;
  for (double x : v) d[i++] = x;
  return d.asDiagonal();
}

EkfSlam make() {
  return EkfSlam(diag({0.01, 0.01, 0.001}), diag({0.01, 0.001}), false, Eigen::Vector3d::Zero(),
                 Eigen::Matrix3d::Identity() * 0.01);
}

RowMatrixXd rows(std::initializer_list<std::initializer_list<double>> r) {
  RowMatrixXd z(r.size(), r.begin()->size());
  int i = 0;
  for (const auto& row : r) {
    int j = 0;
    for (double x : row) z(i, j++) = x;
    ++i;
  }
  return z;
}

struct State {
  Eigen::VectorXd mean;
  Eigen::MatrixXd cov;
  std::vector<long> ids;
  explicit State(EkfSlam& e) : mean(e.mean()), cov(e.covariance()), ids(e.landmark_ids()) {}
  bool operator==(const State& o) const {
    return mean.size() == o.mean.size() && mean == o.mean && cov == o.cov && ids == o.ids;
  }
};

}  // namespace

TEST(ReliabilityEkf, ConstructorValidatesEveryMatrix) {
  const Eigen::Matrix3d p0 = Eigen::Matrix3d::Zero();
  const Eigen::Vector3d x0 = Eigen::Vector3d::Zero();
  const Eigen::MatrixXd q = diag({0.01, 0.001});
  expect_invalid([&] { EkfSlam(Eigen::MatrixXd(0, 0), q, false, x0, p0); }, "motion_noise");
  expect_invalid([&] { EkfSlam(Eigen::MatrixXd::Identity(1, 1), q, false, x0, p0); }, "motion_noise");
  expect_invalid([&] { EkfSlam(Eigen::MatrixXd::Identity(3, 3) * 1e300, q, false, x0, p0); }, "motion_noise");
  expect_invalid([&] { EkfSlam(Eigen::MatrixXd::Identity(3, 3), Eigen::MatrixXd(0, 0), false, x0, p0); },
                 "measurement_noise");
  expect_invalid([&] { EkfSlam(Eigen::MatrixXd::Identity(3, 3), q, false, Eigen::Vector3d(1e300, 0, 0), p0); },
                 "initial_pose");
  expect_invalid([&] { EkfSlam(Eigen::MatrixXd::Identity(3, 3), q, false, x0, Eigen::Matrix3d::Identity() * 1e200); },
                 "initial_pose_cov");
}

TEST(ReliabilityEkf, UpdateRefusesAWholeScanForOneBadRow) {
  EkfSlam ekf = make();
  ekf.update(rows({{2.0, 0.3}, {4.0, -1.0}}), {2, 5});
  const State before(ekf);
  expect_invalid([&] { ekf.update(rows({{2.1, 0.3}, {3.0, 0.2}, {1.0, 0.1}}), {2, 9, -1}); }, "ids");
  EXPECT_TRUE(State(ekf) == before);
  expect_invalid([&] { ekf.update(rows({{2.1, 0.3}, {3.0, 0.2}, {1e200, 0.1}}), {2, 9, 10}); }, "z");
  EXPECT_TRUE(State(ekf) == before);
  expect_invalid([&] { ekf.update_unknown(rows({{2.1, 0.3}, {1e200, 0.1}}), 5.99, 27.6); }, "z");
  EXPECT_TRUE(State(ekf) == before);
  expect_invalid([&] { ekf.predict(1e300, 0.0, 1e10); }, "v");
  expect_invalid([&] { ekf.predict(1.0, 0.0, 1.0, Eigen::MatrixXd::Identity(1, 1)); }, "noise");
  expect_invalid([&] { ekf.predict_odometry(Eigen::Vector3d(1e300, 0, 0), Eigen::Matrix3d::Identity()); }, "delta");
  EXPECT_TRUE(State(ekf) == before);
}

// A call that sees the same landmarks more often than the state has dimensions runs in chunks
// on a saved state; it must equal the same measurements applied one call at a time.
TEST(ReliabilityEkf, LongCallsEqualOneMeasurementAtATime) {
  EkfSlam chunked = make(), single = make();
  RowMatrixXd z(40, 2);
  std::vector<long> ids(40);
  for (int i = 0; i < 40; ++i) {
    z(i, 0) = 2.0 + 0.01 * std::sin(i);
    z(i, 1) = 0.3 + 0.01 * std::cos(i) + (i % 2) * 1.5;
    ids[i] = 4 + i % 2;
  }
  const UpdateReport r = chunked.update(z, ids);
  for (int i = 0; i < 40; ++i) {
    const UpdateReport one = single.update(z.row(i), {ids[i]});
    EXPECT_TRUE(std::isnan(r.nis[i]) ? std::isnan(one.nis[0]) : std::fabs(r.nis[i] - one.nis[0]) < 1e-9) << i;
  }
  EXPECT_LT((chunked.mean() - single.mean()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((chunked.covariance() - single.covariance()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(ReliabilityEkf, StateSizeAndOptionsAreBounded) {
  EkfSlam ekf = make();
  RowMatrixXd z(10000, 2);
  z.col(0).setConstant(2.0);
  z.col(1) = Eigen::VectorXd::LinSpaced(10000, -3.0, 3.0);
  std::vector<long> ids(10000);
  for (int i = 0; i < 10000; ++i) ids[i] = i;
  expect_invalid([&] { ekf.update(z, ids); }, "z");  // 20003 > kEkfMaxStateDimension
  EXPECT_EQ(ekf.state_dim(), 3);
  MapManagement m;
  m.existence_hit = 1e300;
  expect_invalid([&] { ekf.set_map_management(m); }, "existence_hit");
  m = MapManagement{};
  m.min_observations = -4;
  expect_invalid([&] { ekf.set_map_management(m); }, "min_observations");
  expect_invalid([&] { ekf.set_gate_distance(std::nan("")); }, "gate_distance");
  MultiHypothesisOptions o;
  o.max_children = 1 << 30;
  expect_invalid([&] { MultiHypothesisEkfSlam(ekf, o); }, "max_children");
  o = MultiHypothesisOptions{};
  o.gate = std::nan("");
  expect_invalid([&] { MultiHypothesisEkfSlam(ekf, o); }, "gate");
  o = MultiHypothesisOptions{};
  o.bearing_offset_sigma = -1e-3;
  expect_invalid([&] { MultiHypothesisEkfSlam(ekf, o); }, "bearing_offset_sigma");
  o.bearing_offset_sigma = 0.05;
  o.bearing_offset_correlation = 1.0;
  expect_invalid([&] { MultiHypothesisEkfSlam(ekf, o); }, "bearing_offset_correlation");
}

TEST(ReliabilityEkf, MultiHypothesisMotionIsAllOrNothing) {
  EkfSlam ekf = make();
  MultiHypothesisOptions with_offset;  // the offset's state must be left as unchanged as the beam
  with_offset.bearing_offset_sigma = 0.05;
  with_offset.bearing_offset_correlation = 0.8;
  MultiHypothesisEkfSlam mht(ekf, with_offset);
  mht.update(rows({{2.0, 0.3}, {4.0, -1.0}}));
  const Eigen::Vector3d pose = mht.best().pose();
  const double cost = mht.total_cost();
  expect_invalid([&] { mht.predict(1.0, 0.0, 1.0, Eigen::MatrixXd::Identity(3, 3) * 1e300); }, "noise");
  expect_invalid([&] { mht.update(rows({{2.0, 0.3}, {1e200, 0.1}})); }, "z");
  EXPECT_EQ(mht.best().pose(), pose);
  EXPECT_EQ(mht.total_cost(), cost);
}

TEST(ReliabilityCore, OverflowRaisesInsteadOfReturningInf) {
  expect_invalid([] { velocity_motion(Eigen::Vector3d::Zero(), 1e308, 0.0, 1e308); }, "v");
  expect_invalid([] { velocity_motion(Eigen::Vector3d(1e308, 0, 0), 1e308, 0.0, 1.0); }, "v");
  expect_invalid([] { velocity_motion_control_jacobian(Eigen::Vector3d::Zero(), 1e300, 1.0, 1e10); }, "v");
  expect_invalid([] { Pose2(1e308, 0, 0).compose(Pose2(1e308, 0, 0)); }, "pose");
  expect_invalid([] { Pose2(1e308, 0, 0).transform_from(Eigen::Vector2d(1e308, 0)); }, "point");
}

// Far points used to overflow the cell index conversion (undefined behaviour): now clamped.
TEST(ReliabilityCore, SpatialHashTakesFarPoints) {
  SpatialHash2D hash(1e-6);
  hash.insert(0, 1e300, -1e300);
  hash.insert(1, 0.0, 0.0);
  Points2 points(2, 2);
  points << 1e300, -1e300, 0.0, 0.0;
  std::vector<int> out;
  hash.query(1e300, -1e300, 1.0, points, out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0], 0);
  out.clear();
  hash.query(0.0, 0.0, 1e-7, points, out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0], 1);
}
