// MonteCarloLocalization (localization/) against references computed here: Fox 2003's bound by
// hand, the likelihood field against a brute-force nearest-obstacle search, the posterior of a
// one-dimensional corridor integrated on a grid, the requested initial distribution's moments,
// tracking and global localization in a simulated room, thread-count invariance, copies, and
// bad input (std::invalid_argument naming the argument, the filter unchanged).
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "probslam/core/angle.hpp"
#include "probslam/localization/monte_carlo_localization.hpp"
#include "test_support.hpp"

using namespace probslam;
using probslam::test_support::expect_invalid;

namespace {

const double kInf = std::numeric_limits<double>::infinity();
// Log-odds of the test maps' cells: p = 0.953 (above occupied_threshold 0.65) and 0.047 (below
// free_threshold 0.25), inside the grid's default clamp.
constexpr double kOccupiedLogOdds = 3.0;
constexpr double kFreeLogOdds = -3.0;

/// A free room of w x h cells (res m) with occupied cells on its border.
OccupancyGrid2D box_map(double res = 0.1, int w = 60, int h = 40) {
  OccupancyGrid2D g(res, w, h);
  auto lo = g.log_odds();
  lo.setConstant(kFreeLogOdds);
  lo.row(0).setConstant(kOccupiedLogOdds);
  lo.row(h - 1).setConstant(kOccupiedLogOdds);
  lo.col(0).setConstant(kOccupiedLogOdds);
  lo.col(w - 1).setConstant(kOccupiedLogOdds);
  return g;
}

/// Table 6.3 by brute force: each end point's cell, its centre's distance to every occupied
/// cell's centre less half a cell (the obstacle lies somewhere in its cell), capped at 6 sigma;
/// end points off the map score p_rand alone.
double brute_log_likelihood(const OccupancyGrid2D& g, const Eigen::Vector3d& pose, const Eigen::VectorXd& ranges,
                            const Eigen::VectorXd& angles, double sigma, double p_rand, double max_range) {
  const RowMatrixXd p = g.probability();
  std::vector<Eigen::Vector2i> occupied;
  for (int r = 0; r < g.height(); ++r)
    for (int c = 0; c < g.width(); ++c)
      if (p(r, c) > 0.65) occupied.push_back({r, c});
  double total = 0.0;
  for (Eigen::Index b = 0; b < ranges.size(); ++b) {
    if (!(ranges[b] > 0.0 && ranges[b] < max_range)) continue;
    const double x = pose.x() + ranges[b] * std::cos(pose.z() + angles[b]);
    const double y = pose.y() + ranges[b] * std::sin(pose.z() + angles[b]);
    const int col = static_cast<int>(std::floor((x - g.origin().x()) / g.resolution()));
    const int row = static_cast<int>(std::floor((y - g.origin().y()) / g.resolution()));
    if (row < 0 || row >= g.height() || col < 0 || col >= g.width()) {
      total += std::log(p_rand);
      continue;
    }
    double best = kInf;
    for (const auto& o : occupied) best = std::min(best, std::hypot(double(o[0] - row), double(o[1] - col)));
    const double d = std::min(6.0 * sigma, std::max(0.0, (best - 0.5) * g.resolution()));
    total += std::log((1.0 - p_rand) * std::exp(-d * d / (2.0 * sigma * sigma)) + p_rand);
  }
  return total;
}

// ---- the simulated room of test_support (10 x 8 m, a box and a slanted wall) ----

Eigen::VectorXd fan() { return Eigen::VectorXd::LinSpaced(181, -kPi / 2, kPi / 2); }
constexpr double kRoomMaxRange = 15.0;

/// A loop around the box: poses every 0.25 m, the heading along the path.
std::vector<Eigen::Vector3d> room_drive() {
  std::vector<Eigen::Vector3d> out;
  const double corners[][2] = {{-3.5, -1.0}, {3.5, -1.0}, {3.5, 3.0}, {-3.5, 3.0}, {-3.5, -1.0}};
  for (int s = 0; s < 4; ++s) {
    const Eigen::Vector2d a(corners[s][0], corners[s][1]), b(corners[s + 1][0], corners[s + 1][1]);
    const double heading = std::atan2(b.y() - a.y(), b.x() - a.x());
    const int n = static_cast<int>(std::round((b - a).norm() / 0.25));
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector2d p = a + (b - a) * (static_cast<double>(k) / n);
      out.push_back({p.x(), p.y(), heading});
    }
  }
  return out;
}

Eigen::VectorXd room_scan(const Eigen::Vector3d& pose) {
  return test_support::cast(pose, fan(), test_support::room_walls());
}

/// The room mapped from the drive's true poses.
OccupancyGrid2D room_map() {
  OccupancyGrid2D g = OccupancyGrid2D::covering(-5.5, -4.5, 5.5, 4.5, 0.05);
  for (const auto& x : room_drive()) {
    const Eigen::VectorXd r = room_scan(x).cwiseMin(kRoomMaxRange);
    for (int rep = 0; rep < 3; ++rep) g.insert_rays(x, r, fan(), kRoomMaxRange);
  }
  return g;
}

/// Odometry of the drive with a heading bias: each step's rotation is 3% too large and a
/// 0.01 rad drift is added per step, so that the odometry alone ends metres off.
std::vector<Eigen::Vector3d> drifting_odometry(const std::vector<Eigen::Vector3d>& truth) {
  std::vector<Eigen::Vector3d> out{truth[0]};
  for (std::size_t k = 1; k < truth.size(); ++k) {
    const Eigen::Vector3d& a = truth[k - 1];
    const Eigen::Vector3d& b = truth[k];
    const double c = std::cos(a.z()), s = std::sin(a.z());
    const Eigen::Vector3d d(c * (b.x() - a.x()) + s * (b.y() - a.y()), -s * (b.x() - a.x()) + c * (b.y() - a.y()),
                            wrap_angle(b.z() - a.z()) * 1.03 + 0.01);
    const Eigen::Vector3d& o = out.back();
    const double co = std::cos(o.z()), so = std::sin(o.z());
    out.push_back({o.x() + co * d.x() - so * d.y(), o.y() + so * d.x() + co * d.y(), wrap_angle(o.z() + d.z())});
  }
  return out;
}

/// The motion from odometry pose a to b in a's frame (what predict_odometry takes).
Eigen::Vector3d delta(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double c = std::cos(a.z()), s = std::sin(a.z());
  return {c * (b.x() - a.x()) + s * (b.y() - a.y()), -s * (b.x() - a.x()) + c * (b.y() - a.y()),
          wrap_angle(b.z() - a.z())};
}

double position_error(const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return (a - b).head<2>().norm(); }

/// Steps k = first .. last - 1 of a drive through the room: the odometry motion from odometry[k - 1]
/// to odometry[k] (none at step `first`), then the scan taken at truth[k] (its ranges below
/// kRoomMaxRange, the room's longest beam being 12.8 m); on_update(k, report) sees each update.
template <class OnUpdate>
void drive(MonteCarloLocalization& mcl, const std::vector<Eigen::Vector3d>& truth,
           const std::vector<Eigen::Vector3d>& odometry, std::size_t first, std::size_t last, OnUpdate on_update) {
  for (std::size_t k = first; k < last; ++k) {
    if (k > first) mcl.predict_odometry(delta(odometry[k - 1], odometry[k]));
    on_update(k, mcl.update(room_scan(truth[k]).cwiseMin(kRoomMaxRange), fan()));
  }
}

void drive(MonteCarloLocalization& mcl, const std::vector<Eigen::Vector3d>& truth,
           const std::vector<Eigen::Vector3d>& odometry, std::size_t first, std::size_t last) {
  drive(mcl, truth, odometry, first, last, [](std::size_t, const MclUpdate&) {});
}

/// Everything observable of a filter, for "unchanged" and "identical" checks.
struct State {
  Poses2 particles;
  Eigen::VectorXd weights;
  Eigen::Vector3d pose;
  Eigen::Matrix3d covariance;
  int updates;
  double w_slow, w_fast;
  explicit State(const MonteCarloLocalization& m)
      : particles(m.poses()), weights(m.weights()), pose(m.pose()), covariance(m.covariance()),
        updates(m.num_updates()), w_slow(m.w_slow()), w_fast(m.w_fast()) {}
  bool operator==(const State& o) const {
    return particles == o.particles && weights == o.weights && pose == o.pose && covariance == o.covariance &&
           updates == o.updates && w_slow == o.w_slow && w_fast == o.w_fast;
  }
};

}  // namespace

TEST(MonteCarloLocalization, KldBoundByHand) {
  // Fox 2003 for k = 10, epsilon = 0.05, z = 2.326: 9 / 0.1 (1 - 2/81 + sqrt(2/81) 2.326)^3 = 216.94.
  EXPECT_NEAR(MonteCarloLocalization::kld_bound(10, 0.05, 2.326), 216.94, 0.01);
  EXPECT_NEAR(MonteCarloLocalization::kld_bound(2, 0.05, 2.326),
              10.0 * std::pow(7.0 / 9.0 + std::sqrt(2.0 / 9.0) * 2.326, 3), 1e-9);
  EXPECT_EQ(MonteCarloLocalization::kld_bound(1, 0.05, 2.326), 0.0);
}

TEST(MonteCarloLocalization, LikelihoodFieldAgainstBruteForce) {
  OccupancyGrid2D g = box_map();
  g.log_odds().block(10, 20, 4, 3).setConstant(kOccupiedLogOdds);  // a pillar
  MonteCarloLocalizationOptions o;
  o.sigma = 0.15;
  o.p_rand = 0.05;
  o.max_beams = 1000;
  o.min_particles = 10;
  o.max_particles = 100;
  const MonteCarloLocalization mcl(g, o);
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(90, -kPi, kPi - 2 * kPi / 90);
  ParticleRng rng(3, 0);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::Vector3d pose(0.5 + 5.0 * rng.uniform(), 0.5 + 3.0 * rng.uniform(), kPi * (2 * rng.uniform() - 1));
    Eigen::VectorXd ranges(angles.size());
    for (Eigen::Index b = 0; b < ranges.size(); ++b) ranges[b] = 0.05 + 8.0 * rng.uniform();
    const double ref = brute_log_likelihood(g, pose, ranges, angles, 0.15, 0.05, o.max_range);
    // The field stores each cell's log p in float: a relative 1e-7 per beam, 90 beams.
    constexpr double kFloatStorage = 1e-5;
    EXPECT_NEAR(mcl.measurement_log_likelihood(pose, ranges, angles), ref, kFloatStorage * std::abs(ref) + 1e-4);
  }
}

TEST(MonteCarloLocalization, MaxBeamsSubsamplesEvenlyAndSkipsMaxReadings) {
  const OccupancyGrid2D g = box_map();
  MonteCarloLocalizationOptions all;
  all.max_beams = 1000;
  all.max_particles = 100;
  all.min_particles = 10;
  all.max_range = 5.0;
  MonteCarloLocalizationOptions few = all;
  few.max_beams = 3;
  const MonteCarloLocalization a(g, all), b(g, few);
  const Eigen::Vector3d pose(3.0, 2.0, 0.2);
  // Six usable beams and two max readings: three of the six, every other one (0, 2, 4 of the usable).
  const Eigen::VectorXd ranges = (Eigen::VectorXd(8) << 1.0, 9.0, 1.5, 2.0, 5.0, 0.7, 1.2, 2.5).finished();
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(8, -1.0, 1.0);
  auto one = [&](Eigen::Index k) {
    return a.measurement_log_likelihood(pose, ranges.segment(k, 1), angles.segment(k, 1));
  };
  EXPECT_NEAR(b.measurement_log_likelihood(pose, ranges, angles), one(0) + one(3) + one(6), 1e-9);
  EXPECT_NEAR(a.measurement_log_likelihood(pose, ranges, angles),
              one(0) + one(2) + one(3) + one(5) + one(6) + one(7), 1e-9);
  EXPECT_EQ(one(1), 0.0);  // 9 m >= max_range: skipped
}

TEST(MonteCarloLocalization, OneDimensionalCorridorPosterior) {
  // A corridor along x closed by a wall at x in [5.95, 6.10); y and theta known, x ~ N(2, 0.3^2);
  // one beam ahead reads 3.8 m. The posterior of x: prior times the brute-force likelihood,
  // integrated on a fine grid.
  const double res = 0.05, sigma = 0.2, p_rand = 0.05;
  OccupancyGrid2D g(res, 122, 40);
  g.log_odds().setConstant(kFreeLogOdds);
  g.log_odds().rightCols(3).setConstant(kOccupiedLogOdds);
  MonteCarloLocalizationOptions o;
  o.sigma = sigma;
  o.p_rand = p_rand;
  o.min_particles = o.max_particles = 40000;
  o.resample_threshold = 0.0;
  o.weight_scale = 1.0;
  o.seed = 7;
  MonteCarloLocalization mcl(g, o);
  mcl.initialize_pose({2.0, 1.0, 0.0}, Eigen::Vector3d(0.09, 0.0, 0.0).asDiagonal());
  const Eigen::VectorXd ranges = Eigen::VectorXd::Constant(1, 3.8), angles = Eigen::VectorXd::Zero(1);
  mcl.update(ranges, angles);
  const Poses2 p = mcl.poses();
  const Eigen::VectorXd w = mcl.weights();
  EXPECT_TRUE((p.col(1).array() == 1.0).all());  // a zero variance stays exact
  EXPECT_TRUE((p.col(2).array() == 0.0).all());
  double z = 0.0, m1 = 0.0, m2 = 0.0;
  const int n = 4001;
  for (int i = 0; i < n; ++i) {  // rectangle rule on [0, 4], the prior's mass outside negligible
    const double x = 4.0 * i / (n - 1);
    const double post = std::exp(brute_log_likelihood(g, {x, 1.0, 0.0}, ranges, angles, sigma, p_rand, 30.0) -
                                 0.5 * (x - 2.0) * (x - 2.0) / 0.09);
    z += post;
    m1 += x * post;
    m2 += x * x * post;
  }
  const double mean = m1 / z, var = m2 / z - mean * mean;
  const double est = w.dot(p.col(0));
  const double est_var = w.dot((p.col(0).array() - est).square().matrix());
  const double n_eff = 1.0 / w.squaredNorm();
  // Five standard errors of a weighted sample of n_eff effective draws (mean and variance).
  EXPECT_NEAR(est, mean, 5.0 * std::sqrt(var / n_eff));
  EXPECT_NEAR(est_var, var, 5.0 * var * std::sqrt(2.0 / n_eff));
  EXPECT_NEAR(mean, 2.15, 0.1);  // the wall pulls x towards 5.95 - 3.8
}

TEST(MonteCarloLocalization, InitialPoseMomentsAndGlobalSpread) {
  const OccupancyGrid2D g = box_map();
  MonteCarloLocalizationOptions o;
  o.max_particles = 50000;
  o.min_particles = 10;
  MonteCarloLocalization mcl(g, o);
  // Global: uniform over the free cells (rows 1..38, cols 1..58 of 0.1 m), headings uniform.
  Poses2 p = mcl.poses();
  const int m = static_cast<int>(p.rows());
  ASSERT_EQ(m, 50000);
  // Five standard errors of uniform means: sd of U[a, b] is (b - a) / sqrt(12).
  EXPECT_NEAR(p.col(0).mean(), 3.0, 5.0 * 5.8 / std::sqrt(12.0 * m));
  EXPECT_NEAR(p.col(1).mean(), 2.0, 5.0 * 3.8 / std::sqrt(12.0 * m));
  EXPECT_NEAR(p.col(2).mean(), 0.0, 5.0 * 2.0 * kPi / std::sqrt(12.0 * m));
  EXPECT_GE(p.col(0).minCoeff(), 0.1);
  EXPECT_LE(p.col(0).maxCoeff(), 5.9);
  EXPECT_GT(p.col(2).minCoeff(), -kPi);
  EXPECT_LE(p.col(2).maxCoeff(), kPi);
  // From a pose: the sample covariance against the one asked for (correlated x, y).
  Eigen::Matrix3d cov;
  cov << 0.04, 0.01, 0.0, 0.01, 0.02, 0.0, 0.0, 0.0, 0.01;
  const Eigen::Vector3d mu(3.0, 2.0, kPi - 0.05);  // the heading's cloud straddles +-pi
  mcl.initialize_pose(mu, cov);
  p = mcl.poses();
  Eigen::MatrixXd d = p.rowwise() - mu.transpose();
  for (Eigen::Index j = 0; j < d.rows(); ++j) d(j, 2) = wrap_angle(d(j, 2));
  const Eigen::Vector3d mean = d.colwise().mean();
  const Eigen::Matrix3d sample = (d.rowwise() - mean.transpose()).transpose() * (d.rowwise() - mean.transpose()) / m;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(mean[i], 0.0, 5.0 * std::sqrt(cov(i, i) / m));
    for (int k = 0; k < 3; ++k)  // var of a product of normals <= 2 sd_i^2 sd_k^2 for |rho| <= 1
      EXPECT_NEAR(sample(i, k), cov(i, k), 5.0 * std::sqrt(2.0 * cov(i, i) * cov(k, k) / m));
  }
  EXPECT_LE(p.col(2).cwiseAbs().maxCoeff(), kPi);
  EXPECT_EQ(mcl.num_updates(), 0);
}

TEST(MonteCarloLocalization, KldCountAfterResamplingMatchesItsBins) {
  const OccupancyGrid2D g = box_map();
  MonteCarloLocalizationOptions o;
  o.min_particles = 10;
  o.max_particles = 5000;
  o.resample_threshold = 1.0;
  o.alpha_slow = o.alpha_fast = 0.0;
  MonteCarloLocalization mcl(g, o);
  mcl.initialize_pose({3.0, 2.0, 0.0}, Eigen::Vector3d(0.3, 0.3, 0.3).asDiagonal());
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(36, -kPi, kPi - 2 * kPi / 36);
  const MclUpdate u = mcl.update(Eigen::VectorXd::Constant(36, 2.0), angles);
  ASSERT_TRUE(u.resampled);
  const Poses2 p = mcl.poses();
  std::vector<std::array<long, 3>> bins;
  for (Eigen::Index j = 0; j < p.rows(); ++j) {
    const std::array<long, 3> b{static_cast<long>(std::floor(p(j, 0) / o.bin_xy)),
                                static_cast<long>(std::floor(p(j, 1) / o.bin_xy)),
                                static_cast<long>(std::floor((p(j, 2) + kPi) / o.bin_theta))};
    if (std::find(bins.begin(), bins.end(), b) == bins.end()) bins.push_back(b);
  }
  const double bound = MonteCarloLocalization::kld_bound(static_cast<int>(bins.size()), o.kld_epsilon, o.kld_z);
  EXPECT_EQ(static_cast<Eigen::Index>(u.num_particles), p.rows());
  EXPECT_GT(p.rows(), 10);
  EXPECT_LT(p.rows(), 5000);
  // Sampling stops at the first count that reaches the bound of the bins filled so far.
  EXPECT_GE(static_cast<double>(p.rows()), bound);
  EXPECT_LT(static_cast<double>(p.rows()), bound + 1.0);
}

TEST(MonteCarloLocalization, UpdatesOnlyAfterMinimumTravel) {
  const OccupancyGrid2D g = box_map();
  MonteCarloLocalizationOptions o;
  o.max_particles = 300;
  o.min_particles = 100;
  MonteCarloLocalization mcl(g, o);
  mcl.initialize_pose({3.0, 2.0, 0.0}, Eigen::Matrix3d::Identity() * 0.01);
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(5, -1.0, 1.0), ranges = Eigen::VectorXd::Constant(5, 2.0);
  EXPECT_TRUE(mcl.update(ranges, angles).updated);  // the first scan
  mcl.predict_odometry({0.15, 0.0, 0.0});
  const Poses2 before = mcl.poses();
  EXPECT_FALSE(mcl.update(ranges, angles).updated);  // 0.15 m < update.distance
  EXPECT_EQ(mcl.poses(), before);
  mcl.predict_odometry({0.06, 0.0, 0.0});
  EXPECT_TRUE(mcl.update(ranges, angles).updated);  // 0.21 m
  mcl.predict_odometry({0.0, 0.0, 0.5});
  EXPECT_FALSE(mcl.update(ranges, angles).updated);  // 0.5 rad = 28.6 deg < update.angle
  mcl.predict_odometry({0.0, 0.0, 0.03});
  EXPECT_TRUE(mcl.update(ranges, angles).updated);   // 30.4 deg
  EXPECT_TRUE(mcl.update(ranges, angles, true).updated);  // forced
  EXPECT_EQ(mcl.num_updates(), 4);
}

TEST(MonteCarloLocalization, TracksTheRoomWithDriftingOdometry) {
  const OccupancyGrid2D g = room_map();
  const std::vector<Eigen::Vector3d> truth = room_drive();
  const std::vector<Eigen::Vector3d> odo = drifting_odometry(truth);
  ASSERT_GT(position_error(odo.back(), truth.back()), 1.0);  // the odometry alone is lost
  MonteCarloLocalizationOptions o;
  o.max_range = kRoomMaxRange;
  o.max_particles = 3000;
  o.seed = 2;
  MonteCarloLocalization mcl(g, o);
  mcl.initialize_pose(truth[0], Eigen::Vector3d(0.04, 0.04, 0.01).asDiagonal());
  double worst = 0.0;
  drive(mcl, truth, odo, 0, truth.size(), [&](std::size_t k, const MclUpdate&) {
    if (k >= 5) worst = std::max(worst, position_error(mcl.pose(), truth[k]));
  });
  // The map's cells are 0.05 m: within a few cells throughout, once the first scans settled it.
  EXPECT_LT(worst, 0.2);
  EXPECT_LT(std::abs(wrap_angle(mcl.pose().z() - truth.back().z())), 0.05);
  EXPECT_LT(mcl.num_particles(), 3000);  // KLD shrank the cloud
}

TEST(MonteCarloLocalization, GlobalLocalizationInTheRoom) {
  const OccupancyGrid2D g = room_map();
  const std::vector<Eigen::Vector3d> truth = room_drive();
  MonteCarloLocalizationOptions o;
  o.max_range = kRoomMaxRange;
  o.seed = 5;
  MonteCarloLocalization mcl(g, o);
  drive(mcl, truth, truth, 0, truth.size());
  EXPECT_LT(position_error(mcl.pose(), truth.back()), 0.15);
  EXPECT_LT(mcl.covariance().trace() - mcl.covariance()(2, 2), 0.05);
  EXPECT_LT(mcl.num_particles(), 2000);
}

TEST(MonteCarloLocalization, ThreadCountDoesNotChangeTheResult) {
  const OccupancyGrid2D g = room_map();
  const std::vector<Eigen::Vector3d> truth = room_drive();
  const std::vector<Eigen::Vector3d> odo = drifting_odometry(truth);
  std::vector<State> out;
  for (int threads : {1, 2, 3}) {
    MonteCarloLocalizationOptions o;
    o.max_range = kRoomMaxRange;
    o.max_particles = 4000;
    o.seed = 11;
    o.threads = threads;
    MonteCarloLocalization mcl(g, o);  // global: 4000 particles, split over the workers
    drive(mcl, truth, odo, 0, 25);
    out.emplace_back(mcl);
  }
  EXPECT_TRUE(out[0] == out[1]);
  EXPECT_TRUE(out[0] == out[2]);
}

TEST(MonteCarloLocalization, CopyIsIndependentAndContinuesIdentically) {
  const OccupancyGrid2D g = room_map();
  const std::vector<Eigen::Vector3d> truth = room_drive();
  MonteCarloLocalizationOptions o;
  o.max_range = kRoomMaxRange;
  o.max_particles = 1000;
  o.threads = 2;
  MonteCarloLocalization a(g, o);
  a.initialize_pose(truth[0], Eigen::Matrix3d::Identity() * 0.01);
  a.update(room_scan(truth[0]), fan());
  MonteCarloLocalization b(a);
  for (MonteCarloLocalization* m : {&a, &b}) {
    m->predict_odometry(delta(truth[0], truth[2]));
    m->update(room_scan(truth[2]), fan());
  }
  EXPECT_TRUE(State(a) == State(b));
  a.predict_odometry(delta(truth[2], truth[4]));
  a.update(room_scan(truth[4]), fan());
  EXPECT_FALSE(State(a) == State(b));
  EXPECT_EQ(b.num_updates(), 2);
}

TEST(MonteCarloLocalization, BeamModelTracksTheRoom) {
  const OccupancyGrid2D g = room_map();
  const std::vector<Eigen::Vector3d> truth = room_drive();
  MonteCarloLocalizationOptions o;
  o.sensor_model = MclSensorModel::kBeam;
  o.beam.sigma_hit = 0.1;
  o.max_range = kRoomMaxRange;
  o.max_beams = 30;
  o.max_particles = 1000;
  MonteCarloLocalization mcl(g, o);
  mcl.initialize_pose(truth[0], Eigen::Vector3d(0.04, 0.04, 0.01).asDiagonal());
  double worst = 0.0;
  drive(mcl, truth, truth, 0, 40, [&](std::size_t k, const MclUpdate&) {
    if (k >= 5) worst = std::max(worst, position_error(mcl.pose(), truth[k]));
  });
  EXPECT_LT(worst, 0.2);
}

TEST(MonteCarloLocalization, KidnappingInjectsRandomParticlesAndRecovers) {
  // Tracked along the first side, then the robot is carried to the opposite side while the
  // odometry goes on as if it had not moved: augmented MCL must notice and find it again. In
  // this small room a wrong pose still explains many beams, so the likelihood falls by less
  // than half: recovery_ratio 0.7, and injected particles drawn where the scan fits (uniform
  // ones, 1 in ~10^4 near the right pose and heading, did not find it within the drive).
  const OccupancyGrid2D g = room_map();
  const std::vector<Eigen::Vector3d> truth = room_drive();
  MonteCarloLocalizationOptions o;
  o.max_range = kRoomMaxRange;
  o.recovery_ratio = 0.7;
  o.recovery_updates = 3;
  o.recovery_candidates = 20000;
  o.seed = 9;
  MonteCarloLocalization mcl(g, o);
  mcl.initialize_pose(truth[0], Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal());
  double injected_while_tracking = 0.0;
  drive(mcl, truth, truth, 0, 20, [&](std::size_t, const MclUpdate& u) {
    injected_while_tracking = std::max(injected_while_tracking, u.random_fraction);
  });
  EXPECT_EQ(injected_while_tracking, 0.0);
  ASSERT_LT(position_error(mcl.pose(), truth[19]), 0.1);
  const std::size_t jump = truth.size() / 2 + 4;  // the top side, heading opposite
  ASSERT_GT(position_error(truth[jump], truth[19]), 3.0);
  double injected = 0.0;
  mcl.predict_odometry(delta(truth[19], truth[20]));
  drive(mcl, truth, truth, jump, truth.size(),
        [&](std::size_t, const MclUpdate& u) { injected = std::max(injected, u.random_fraction); });
  EXPECT_GT(injected, 0.0);
  EXPECT_LT(position_error(mcl.pose(), truth.back()), 0.15);
  // The candidates are scored over the worker threads: the same run on three threads.
  o.threads = 3;
  MonteCarloLocalization par(g, o);
  par.initialize_pose(truth[0], Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal());
  drive(par, truth, truth, 0, 20);
  par.predict_odometry(delta(truth[19], truth[20]));
  drive(par, truth, truth, jump, truth.size());
  EXPECT_TRUE(State(par) == State(mcl));
}

TEST(MonteCarloLocalization, BadOptionsAndMapsNameTheArgument) {
  const OccupancyGrid2D g = box_map();
  auto with = [&](auto edit) {
    MonteCarloLocalizationOptions o;
    edit(o);
    return [&g, o] { MonteCarloLocalization m(g, o); };
  };
  expect_invalid([] { MonteCarloLocalization m(OccupancyGrid2D(0.1, 10, 10)); }, "map");  // all unknown
  expect_invalid(with([](auto& o) { o.min_particles = 100, o.max_particles = 50; }), "max_particles");
  expect_invalid(with([](auto& o) { o.min_particles = 0; }), "min_particles");
  expect_invalid(with([](auto& o) { o.min_range = 40.0; }), "min_range");
  expect_invalid(with([](auto& o) { o.alpha_slow = 0.5, o.alpha_fast = 0.1; }), "alpha_fast");
  expect_invalid(with([](auto& o) { o.free_threshold = 0.9; }), "free_threshold");
  expect_invalid(with([](auto& o) { o.weight_scale = 0.0; }), "weight_scale");
  expect_invalid(with([](auto& o) { o.recovery_ratio = 1.5; }), "recovery_ratio");
  expect_invalid(with([](auto& o) { o.sigma = std::nan(""); }), "sigma");
  expect_invalid(with([](auto& o) { o.bin_theta = 7.0; }), "bin_theta");
  expect_invalid(with([](auto& o) { o.threads = 0; }), "threads");
  expect_invalid(with([](auto& o) { o.recovery_updates = 0; }), "recovery_updates");
  expect_invalid(with([](auto& o) { o.recovery_candidates = -1; }), "recovery_candidates");
  expect_invalid(with([](auto& o) { o.odometry.alpha2 = -1.0; }), "odometry.alpha2");
  expect_invalid(with([](auto& o) { o.beam.sigma_hit = std::nan(""); }), "beam.sigma_hit");
}

TEST(MonteCarloLocalization, BadCallsThrowAndChangeNothing) {
  const OccupancyGrid2D g = box_map();
  MonteCarloLocalizationOptions o;
  o.min_particles = 100;
  o.max_particles = 300;
  o.seed = 1;
  MonteCarloLocalization mcl(g, o);
  mcl.initialize_pose({3.0, 2.0, 0.0}, Eigen::Matrix3d::Identity() * 0.01);
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(5, -1.0, 1.0);
  mcl.update(Eigen::VectorXd::Constant(5, 2.0), angles);
  mcl.predict_odometry({0.1, 0.0, 0.0});  // pending odometry, part of the state
  const State before(mcl);
  auto scan = [](double bad) { return (Eigen::VectorXd(5) << 1.0, 2.0, bad, 1.0, 1.0).finished(); };
  expect_invalid([&] { mcl.update(scan(std::nan("")), angles); }, "ranges");
  expect_invalid([&] { mcl.update(scan(kInf), angles); }, "ranges");
  expect_invalid([&] { mcl.update(scan(-1.0), angles); }, "ranges");
  expect_invalid([&] { mcl.update(Eigen::VectorXd(0), Eigen::VectorXd(0)); }, "ranges");
  expect_invalid([&] { mcl.update(Eigen::VectorXd::Ones(5), Eigen::VectorXd::Ones(4)); }, "angles");
  expect_invalid([&] { mcl.update(Eigen::VectorXd::Ones(5), scan(std::nan(""))); }, "angles");
  expect_invalid([&] { mcl.predict_odometry({0.0, std::nan(""), 0.0}); }, "delta");
  expect_invalid([&] { mcl.initialize_pose({100.0, 0.0, 0.0}, Eigen::Matrix3d::Identity()); }, "pose");
  expect_invalid([&] { mcl.initialize_pose({0.05, 0.05, 0.0}, Eigen::Matrix3d::Identity()); }, "pose");  // wall
  expect_invalid([&] { mcl.initialize_pose({3.0, 2.0, kInf}, Eigen::Matrix3d::Identity()); }, "pose");
  expect_invalid([&] { mcl.initialize_pose({3.0, 2.0, 0.0}, -Eigen::Matrix3d::Identity()); }, "covariance");
  Eigen::Matrix3d asym = Eigen::Matrix3d::Identity();
  asym(0, 1) = 0.5;
  expect_invalid([&] { mcl.initialize_pose({3.0, 2.0, 0.0}, asym); }, "covariance");
  expect_invalid([&] { (void)mcl.measurement_log_likelihood({kInf, 0.0, 0.0}, scan(1.0), angles); }, "pose");
  EXPECT_TRUE(State(mcl) == before);
  // And the filter goes on as a twin that never saw the bad calls.
  MonteCarloLocalization twin(g, o);
  twin.initialize_pose({3.0, 2.0, 0.0}, Eigen::Matrix3d::Identity() * 0.01);
  twin.update(Eigen::VectorXd::Constant(5, 2.0), angles);
  twin.predict_odometry({0.1, 0.0, 0.0});
  for (MonteCarloLocalization* m : {&mcl, &twin}) {
    m->predict_odometry({0.15, 0.0, 0.0});
    m->update(Eigen::VectorXd::Constant(5, 1.8), angles);
  }
  EXPECT_TRUE(State(mcl) == State(twin));
}

TEST(MonteCarloLocalization, AnInterruptedUpdateChangesNothingAndTheFilterGoesOn) {
  // The interrupt hook throws at its third call (mid-way through the particles, after some have
  // moved and been weighed): the filter is as before, and then continues as a twin that never
  // saw the interrupted call.
  const OccupancyGrid2D g = box_map();
  MonteCarloLocalizationOptions o;
  o.min_particles = 20000;
  o.max_particles = 20000;
  o.max_beams = 500;  // 500 look-ups a particle: ~2000 particles between two interrupt checks
  o.seed = 4;
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(500, -1.5, 1.5);
  const Eigen::VectorXd z = Eigen::VectorXd::Constant(500, 2.0);
  MonteCarloLocalization mcl(g, o), twin(g, o);
  for (MonteCarloLocalization* m : {&mcl, &twin}) m->predict_odometry({0.3, 0.0, 0.1});
  const State before(mcl);
  int calls = 0;
  struct Stop {};
  EXPECT_THROW(mcl.update(z, angles, false, [&] {
    if (++calls == 3) throw Stop{};
  }), Stop);
  EXPECT_EQ(calls, 3);
  EXPECT_TRUE(State(mcl) == before);
  int checks = 0;
  for (MonteCarloLocalization* m : {&mcl, &twin}) m->update(z, angles, false, [&] { ++checks; });
  EXPECT_GE(checks, 2 * 5);  // 20000 particles x 500 look-ups: several checks an update
  EXPECT_TRUE(State(mcl) == State(twin));
}

TEST(MonteCarloLocalization, MotionsAndOptionsThatCannotBeRepresentedAreRefused) {
  const OccupancyGrid2D g = box_map();
  MonteCarloLocalizationOptions o;
  o.min_particles = o.max_particles = 200;
  MonteCarloLocalization mcl(g, o);
  mcl.initialize_pose({3.0, 2.0, 0.0}, Eigen::Matrix3d::Identity() * 0.01);
  const State before(mcl);
  expect_invalid([&] { mcl.predict_odometry({1e300, 0.0, 0.0}); }, "delta");
  EXPECT_TRUE(State(mcl) == before);  // pose() includes the pending odometry
  mcl.predict_odometry({6e5, 0.0, 0.0});
  const State pending(mcl);
  expect_invalid([&] { mcl.predict_odometry({6e5, 0.0, 0.0}); }, "delta");  // the pending sum
  EXPECT_TRUE(State(mcl) == pending);
  expect_invalid([] { (void)MonteCarloLocalization::kld_bound(2, 1e-309, 1.0); }, "epsilon");
  for (double sigma : {1e-301, 2e300, kInf}) {
    MonteCarloLocalizationOptions bad = o;
    bad.sigma = sigma;
    expect_invalid([&] { MonteCarloLocalization(g, bad); }, "sigma");
  }
  for (double sigma : {1e-200, 1e300}) {  // the extremes accepted give finite weights and poses
    MonteCarloLocalizationOptions extreme = o;
    extreme.sigma = sigma;
    MonteCarloLocalization m(g, extreme);
    m.initialize_pose({3.0, 2.0, 0.0}, Eigen::Matrix3d::Identity() * 0.01);
    m.update(Eigen::VectorXd::Constant(5, 2.0), Eigen::VectorXd::LinSpaced(5, -1.0, 1.0), true);
    EXPECT_TRUE(m.poses().allFinite() && m.weights().allFinite() && m.pose().allFinite()) << sigma;
  }
}
