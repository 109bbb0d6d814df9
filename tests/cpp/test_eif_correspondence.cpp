// Tables 11.8 and 11.9 against a dense inverse of Omega and against simulated ground truth.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <set>
#include <stdexcept>

#include "probslam/core/angle.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "probslam/graph/eif_correspondence.hpp"

namespace probslam {
namespace {

// Two dense double-precision inverses of systems with condition numbers near 1e6 agree to this.
constexpr double kDenseAgreement = 1e-9;

struct Problem {
  RowMatrixXd controls;
  Eigen::VectorXd dt;
  FeatureMeasurements meas;
  Eigen::VectorXi truth;  // true landmark of each measurement
  Eigen::Matrix3d R = Eigen::Vector3d(4e-4, 4e-4, 2.5e-5).asDiagonal();
  Eigen::Matrix2d Q = Eigen::Vector2d(2.5e-3, 1e-4).asDiagonal();
};

// A robot on an arc among landmarks at least 2 m apart, seeing those within 8 m.
Problem simulate(unsigned seed, int steps, int landmarks) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> ux(0.0, 25.0), uy(-4.0, 10.0);
  Problem p;
  p.controls = RowMatrixXd(steps, 2);
  p.controls.col(0).setConstant(1.0);
  p.controls.col(1).setConstant(0.04);
  p.dt = Eigen::VectorXd::Constant(steps, 0.5);
  std::vector<Eigen::Vector2d> world;
  while (static_cast<int>(world.size()) < landmarks) {
    const Eigen::Vector2d c(ux(rng), uy(rng));
    bool apart = true;
    for (const auto& w : world) apart = apart && (w - c).norm() > 2.0;
    if (apart) world.push_back(c);
  }
  std::vector<int> time, truth;
  std::vector<Eigen::Vector2d> z;
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  for (int t = 0; t <= steps; ++t) {
    if (t > 0) {
      x = velocity_motion(x, 1.0, 0.04, 0.5) + Eigen::Vector3d(0.02 * unit(rng), 0.02 * unit(rng), 0.005 * unit(rng));
      x[2] = wrap_angle(x[2]);
    }
    for (int j = 0; j < landmarks; ++j) {
      if ((world[j] - x.head<2>()).norm() > 8.0) continue;
      Eigen::Vector2d m = range_bearing(x, world[j]);
      m += Eigen::Vector2d(0.05 * unit(rng), 0.01 * unit(rng));
      m[1] = wrap_angle(m[1]);
      time.push_back(t), truth.push_back(j), z.push_back(m);
    }
  }
  const int count = static_cast<int>(z.size());
  p.meas.time = Eigen::Map<Eigen::VectorXi>(time.data(), count);
  p.truth = Eigen::Map<Eigen::VectorXi>(truth.data(), count);
  p.meas.z = RowMatrixXd(count, 2);
  for (int k = 0; k < count; ++k) p.meas.z.row(k) = z[k].transpose();
  return p;
}

// Features named 0 .. N-1 in order of first sighting, with landmark `split`'s later half of
// measurements given to a feature of its own (index N).
Eigen::VectorXi split_correspondences(const Eigen::VectorXi& truth, int split, int& split_feature) {
  std::vector<int> index(truth.maxCoeff() + 1, -1);
  int next = 0;
  for (Eigen::Index k = 0; k < truth.size(); ++k)
    if (index[truth[k]] < 0) index[truth[k]] = next++;
  split_feature = next;
  const long seen = (truth.array() == split).count();
  long count = 0;
  Eigen::VectorXi c(truth.size());
  for (Eigen::Index k = 0; k < truth.size(); ++k) {
    c[k] = index[truth[k]];
    if (truth[k] == split && ++count > seen / 2) c[k] = split_feature;
  }
  return c;
}

TEST(EifCorrespondence, DifferenceCovarianceEqualsTheDenseMarginal) {
  Problem p = simulate(3, 40, 6);
  int split = 0;
  p.meas.feature = split_correspondences(p.truth, p.truth[0], split);
  GraphSlamOptions options;
  options.path_covariances = false;
  SparseCholesky factor;
  InformationForm form;
  const int n = p.meas.feature.maxCoeff() + 1;
  Poses2 poses = eif_initialize(p.controls, p.dt);
  const GraphSlamResult slam = graph_slam_from(p.controls, p.dt, p.meas, p.R, p.Q, poses,
                                               eif_initial_features(poses, p.meas, n), options, factor, &form);
  const Eigen::MatrixXd sigma = Eigen::MatrixXd(form.omega).llt().solve(Eigen::MatrixXd::Identity(form.omega.rows(), form.omega.rows()));
  EifCorrespondenceTester tester(form, factor, slam.features);
  const int base = form.pose_dim();
  for (int j = 0; j < n; ++j)
    for (int k = j + 1; k < n; ++k) {
      const CorrespondenceTest t = tester.test(j, k);
      const Eigen::Matrix2d expected = sigma.block<2, 2>(base + 2 * j, base + 2 * j) +
                                       sigma.block<2, 2>(base + 2 * k, base + 2 * k) -
                                       sigma.block<2, 2>(base + 2 * j, base + 2 * k) -
                                       sigma.block<2, 2>(base + 2 * k, base + 2 * j);
      EXPECT_LT((t.covariance - expected).norm(), kDenseAgreement * expected.norm()) << j << " " << k;
      const Eigen::Vector2d delta = (slam.features.row(j) - slam.features.row(k)).transpose();
      const double d2 = delta.dot(expected.inverse() * delta);
      EXPECT_NEAR(t.distance2, d2, 1e-6 * d2);
      EXPECT_NEAR(t.probability, std::exp(-0.5 * d2) / (2.0 * kPi * std::sqrt(expected.determinant())),
                  1e-6 * t.probability + 1e-300);
    }
  // The split landmark's two halves are the one plausible pair.
  const int first_half = p.meas.feature[0];
  const CorrespondenceTest same = tester.test(first_half, split);
  EXPECT_LT(same.distance2, 13.8);  // the 0.999 quantile of chi-square(2)
  for (int k = 0; k < n; ++k)
    if (k != first_half && k != split) EXPECT_GT(same.probability, tester.test(first_half, k).probability);
}

TEST(EifCorrespondence, RejectsBadPairs) {
  Problem p = simulate(4, 10, 3);
  int split = 0;
  p.meas.feature = split_correspondences(p.truth, p.truth[0], split);
  SparseCholesky factor;
  InformationForm form;
  const int n = p.meas.feature.maxCoeff() + 1;
  Poses2 poses = eif_initialize(p.controls, p.dt);
  const auto slam = graph_slam_from(p.controls, p.dt, p.meas, p.R, p.Q, poses,
                                    eif_initial_features(poses, p.meas, n), {}, factor, &form);
  EifCorrespondenceTester tester(form, factor, slam.features);
  EXPECT_THROW(tester.test(0, 0), std::invalid_argument);
  EXPECT_THROW(tester.test(-1, 0), std::invalid_argument);
  EXPECT_THROW(tester.test(0, n), std::invalid_argument);
  SparseCholesky unfactored;
  EXPECT_THROW(EifCorrespondenceTester(form, unfactored, slam.features), std::invalid_argument);
  EXPECT_THROW(EifCorrespondenceTester(form, factor, slam.features.leftCols(1)), std::invalid_argument);
}

// Pairs of measurements: the share of pairs grouped together that belong together (precision)
// and of pairs that belong together that are grouped together (recall).
std::pair<double, double> pair_precision_recall(const Eigen::VectorXi& estimate, const Eigen::VectorXi& truth) {
  long tp = 0, fp = 0, fn = 0;
  for (Eigen::Index a = 0; a < truth.size(); ++a)
    for (Eigen::Index b = a + 1; b < truth.size(); ++b) {
      const bool e = estimate[a] == estimate[b], t = truth[a] == truth[b];
      tp += e && t, fp += e && !t, fn += !e && t;
    }
  return {tp / double(std::max(tp + fp, 1L)), tp / double(std::max(tp + fn, 1L))};
}

TEST(GraphSlamUnknown, RecoversTheCorrespondencesOfASimulatedRun) {
  Problem p = simulate(7, 120, 15);
  p.meas.feature = Eigen::VectorXi::Zero(p.meas.z.rows());
  const GraphSlamUnknownResult r = graph_slam_unknown(p.controls, p.dt, p.meas, p.R, p.Q);
  ASSERT_TRUE(r.converged);
  const auto [precision, recall] = pair_precision_recall(r.correspondences, p.truth);
  EXPECT_GE(precision, 0.99);
  EXPECT_GE(recall, 0.95);
  // No feature holds two measurements of one time step.
  std::set<std::pair<int, int>> seen;
  for (Eigen::Index k = 0; k < p.meas.time.size(); ++k)
    EXPECT_TRUE(seen.emplace(r.correspondences[k], p.meas.time[k]).second);
  EXPECT_EQ(static_cast<int>(r.slam.features.rows()), r.correspondences.maxCoeff() + 1);
  EXPECT_EQ(r.merges.size(), static_cast<size_t>(p.meas.z.rows() - r.slam.features.rows()));
}

TEST(GraphSlamUnknown, RejectsBadOptions) {
  Problem p = simulate(4, 10, 3);
  p.meas.feature = Eigen::VectorXi::Zero(p.meas.z.rows());
  CorrespondenceSearchOptions bad;
  bad.chi = -1.0;
  EXPECT_THROW(graph_slam_unknown(p.controls, p.dt, p.meas, p.R, p.Q, {}, bad), std::invalid_argument);
  bad = {};
  bad.search_radius = 0.0;
  EXPECT_THROW(graph_slam_unknown(p.controls, p.dt, p.meas, p.R, p.Q, {}, bad), std::invalid_argument);
  bad = {};
  bad.chi = std::nan("");
  EXPECT_THROW(graph_slam_unknown(p.controls, p.dt, p.meas, p.R, p.Q, {}, bad), std::invalid_argument);
}

}  // namespace
}  // namespace probslam
