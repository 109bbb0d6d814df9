// slam2d/: the likelihood field's EDT against a brute-force loop, branch and bound against the
// brute-force search, pose recovery in a simulated room, the match covariance (positive definite,
// large along a corridor, the prior and the window when the scan says nothing), the scan
// filter, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "probslam/core/angle.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"
#include "probslam/slam2d/correlative_scan_matcher.hpp"
#include "probslam/slam2d/likelihood_field.hpp"
#include "probslam/slam2d/range_scan.hpp"
#include "probslam/slam2d/submap_slam.hpp"
#include "probslam/fastslam/grid_fast_slam.hpp"
#include "probslam/core/pose2.hpp"
#include "test_support.hpp"

using namespace probslam;
using probslam::test_support::expect_invalid;

namespace {

using test_support::Segment;
using test_support::cast;
using test_support::room_walls;

Eigen::VectorXd fan() { return Eigen::VectorXd::LinSpaced(181, -kPi / 2, kPi / 2); }

OccupancyGrid2D room_map() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-3, 3);
  OccupancyGrid2D g = OccupancyGrid2D::covering(-6.0123, -5.9871, 6, 6, 0.05);
  const auto walls = room_walls();
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d pose(u(rng), u(rng), u(rng));
    g.insert_rays(pose, cast(pose, fan(), walls), fan(), 30.0);
  }
  return g;
}

/// A true pose inside the room and outside the pillar [1, 2]^2 (a margin of 0.3 m).
Eigen::Vector3d random_truth(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  for (;;) {
    const Eigen::Vector3d x(2 * u(rng), 2 * u(rng), kPi * u(rng));
    if (!(x.x() > 0.7 && x.x() < 2.3 && x.y() > 0.7 && x.y() < 2.3)) return x;
  }
}

Points2 noisy_scan(std::mt19937& rng, const Eigen::Vector3d& pose, double noise) {
  std::normal_distribution<double> n(0.0, noise);
  Eigen::VectorXd r = cast(pose, fan(), room_walls());
  for (Eigen::Index i = 0; i < r.size(); ++i) r[i] += n(rng);
  return scan_hits(r, fan(), ScanFilter{});
}

/// Brute force: min over occupied cells (inside [r0, r1) x [c0, c1)) of centre distance - res/2.
double brute_distance(const OccupancyGrid2D& g, int r0, int r1, int c0, int c1, const Eigen::Vector2d& x,
                      double threshold, double cap) {
  double best = std::numeric_limits<double>::infinity();
  for (int r = r0; r < r1; ++r)
    for (int c = c0; c < c1; ++c)
      if (g.log_odds()(r, c) > threshold) best = std::min(best, (g.cell_center(r, c) - x).norm());
  return std::clamp(best - 0.5 * g.resolution(), 0.0, cap);
}

}  // namespace

TEST(Slam2dLikelihoodField, EdtEqualsBruteForceWithCropAndEmpty) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0, 1);
  OccupancyGrid2D g(0.1, 47, 33, {-2.03, 1.07});
  for (int r = 0; r < g.height(); ++r)
    for (int c = 0; c < g.width(); ++c) {
      const double x = u(rng);
      g.log_odds()(r, c) = x < 0.03 ? 2.0 : (x < 0.05 ? 0.3 : (x < 0.5 ? -1.0 : 0.0));
    }
  // 0.08 m sigma: 0.48 m truncation (the windowed transform); 4 m: 40 cells (the exact
  // transform of the whole lattice, see likelihood_field.cpp).
  for (const double occ : {0.5, 0.6})
    for (const double max_distance : {0.0, 4.0}) {
      LikelihoodFieldOptions o;
      o.sigma = 0.08;
      o.max_distance = max_distance;
      o.occupied_threshold = occ;
      const double thr = logit(occ);
      for (int crop = 0; crop < 2; ++crop) {
        const LikelihoodField f = crop ? LikelihoodField::from_grid(g, Eigen::Vector4d(-1.31, 1.52, 1.77, 3.0), o)
                                       : LikelihoodField::from_grid(g, o);
        const int c0 = static_cast<int>(std::lround((f.origin().x() - g.origin().x()) / g.resolution()));
        const int r0 = static_cast<int>(std::lround((f.origin().y() - g.origin().y()) / g.resolution()));
        if (crop) {
          EXPECT_EQ(c0, 7);
          EXPECT_EQ(r0, 4);
          EXPECT_EQ(f.width(), g.lattice().key(0, 1.77) + 1 - c0);
          EXPECT_EQ(f.height(), g.lattice().key(1, 3.0) + 1 - r0);
        } else {
          EXPECT_EQ(f.width(), g.width());
          EXPECT_EQ(f.height(), g.height());
        }
        int occupied = 0;
        for (int r = 0; r < f.height(); ++r)
          for (int c = 0; c < f.width(); ++c) {
            occupied += g.log_odds()(r + r0, c + c0) > thr;
            const double expected = brute_distance(g, r0, r0 + f.height(), c0, c0 + f.width(),
                                                   g.cell_center(r + r0, c + c0), thr, o.truncation());
            ASSERT_NEAR(f.distance()(r, c), expected, 1e-5) << r << " " << c << " crop " << crop;
            ASSERT_NEAR(f.log_likelihood()(r, c), f.log_likelihood_of_distance(expected), 1e-5);
          }
        EXPECT_EQ(f.num_occupied(), occupied);
        EXPECT_GT(occupied, 0);
      }
    }
  OccupancyGrid2D empty(0.1, 20, 10);
  LikelihoodFieldOptions o;
  o.max_distance = 0.37;
  const LikelihoodField f = LikelihoodField::from_grid(empty, o);
  EXPECT_EQ(f.num_occupied(), 0);
  EXPECT_EQ(f.distance().minCoeff(), static_cast<float>(0.37));
  EXPECT_EQ(f.distance().maxCoeff(), static_cast<float>(0.37));
}

TEST(Slam2dMatcher, BranchAndBoundEqualsBruteForce) {
  const OccupancyGrid2D g = room_map();
  const LikelihoodField field = LikelihoodField::from_grid(g);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::Matrix3d L;
  L << 0.1, 0, 0, 0.05, 0.2, 0, 0.02, -0.03, 0.1;
  const Eigen::Matrix3d cov = L * L.transpose();
  for (const int level : {0, 1, 3, 6}) {
    const CorrelativeScanMatcher m(field, level);
    // A pyramid deepened after construction is the one built at once.
    CorrelativeScanMatcher deepened(field, 0);
    deepened.extend_levels(level);
    deepened.extend_levels(0);  // never shrinks
    ASSERT_EQ(deepened.max_level(), level);
    EXPECT_EQ(deepened.bytes(), CorrelativeScanMatcher::bytes_for(field.width(), field.height(), level));
    for (int trial = 0; trial < 8; ++trial) {
      const Eigen::Vector3d truth = random_truth(rng);
      Points2 full = noisy_scan(rng, truth, 0.01);
      Points2 pts(full.rows() / 3, 2);
      for (Eigen::Index i = 0; i < pts.rows(); ++i) pts.row(i) = full.row(3 * i);
      const Eigen::Vector3d prior = truth + 0.2 * Eigen::Vector3d(u(rng), u(rng), u(rng));
      MatchOptions o;
      o.window = {0.15 + 0.25 * (u(rng) + 1) / 2, 0.05 + 0.1 * (u(rng) + 1), 0.01 + 0.01 * (u(rng) + 1)};
      o.refine = false;
      o.use_prior = trial % 2;
      o.prior_covariance = cov;
      const MatchResult bb = m.match(pts, prior, o);
      const MatchResult bb_deepened = deepened.match(pts, prior, o);
      ASSERT_EQ(bb_deepened.search_score, bb.search_score);
      ASSERT_EQ(bb_deepened.search_pose, bb.search_pose);
      ASSERT_EQ(bb_deepened.candidates_scored, bb.candidates_scored);
      o.brute_force = true;
      const MatchResult bf = m.match(pts, prior, o);
      ASSERT_EQ(bb.search_score, bf.search_score) << "level " << level << " trial " << trial;
      EXPECT_LT(bb.candidates_scored, bf.candidates_scored + 1);
      // The pose B&B returns has that score on the lattice.
      const double res = field.resolution(), step = bb.angular_step;
      const int cx = static_cast<int>(std::lround((bb.search_pose.x() - prior.x()) / res));
      const int cy = static_cast<int>(std::lround((bb.search_pose.y() - prior.y()) / res));
      const double dth = wrap_angle(bb.search_pose.z() - prior.z());
      const int a = static_cast<int>(std::lround(dth / step));
      const double th = prior.z() + a * step;
      double s = 0.0;
      for (Eigen::Index i = 0; i < pts.rows(); ++i) {
        const double x = std::cos(th) * pts(i, 0) - std::sin(th) * pts(i, 1) + prior.x();
        const double y = std::sin(th) * pts(i, 0) + std::cos(th) * pts(i, 1) + prior.y();
        s += field.cell_value(field.row_of(y) + cy, field.col_of(x) + cx);
      }
      if (o.use_prior) {
        const Eigen::Vector3d d(cx * res, cy * res, a * step);
        s -= 0.5 * d.dot(cov.inverse() * d);
      }
      EXPECT_NEAR(s, bb.search_score, 1e-6 * std::abs(s));
    }
  }
}

TEST(Slam2dMatcher, LevelsForWindowAsTheSearchPicksItsTopLevel) {
  // +-0.3 m at 5 cm: 13 cells, spanned by a level-4 node (16); +-4 m: 161 cells, level 8 (256).
  EXPECT_EQ(CorrelativeScanMatcher::levels_for_window(0.3, 0.05), 4);
  EXPECT_EQ(CorrelativeScanMatcher::levels_for_window(4.0, 0.05), 8);
  EXPECT_EQ(CorrelativeScanMatcher::levels_for_window(0.0, 0.05), 0);
  EXPECT_EQ(CorrelativeScanMatcher::levels_for_window(1e6, 0.05), CorrelativeScanMatcher::kMaxLevel);
  EXPECT_THROW(CorrelativeScanMatcher::levels_for_window(-1.0, 0.05), std::invalid_argument);
  EXPECT_THROW(CorrelativeScanMatcher::levels_for_window(0.3, 0.0), std::invalid_argument);
  CorrelativeScanMatcher m(LikelihoodField::from_grid(room_map()), 2);
  EXPECT_THROW(m.extend_levels(CorrelativeScanMatcher::kMaxLevel + 1), std::invalid_argument);
  EXPECT_EQ(m.max_level(), 2);
}

TEST(Slam2dMatcher, RecoversPoseInSimulatedRoom) {
  const CorrelativeScanMatcher m(LikelihoodField::from_grid(room_map()));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 12; ++trial) {
    const Eigen::Vector3d truth = random_truth(rng);
    const Points2 pts = noisy_scan(rng, truth, 0.01);
    const Eigen::Vector3d prior = truth + 0.2 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const MatchResult r = m.match(pts, prior);
    EXPECT_LE(std::abs(r.pose.x() - truth.x()), 0.025) << trial;
    EXPECT_LE(std::abs(r.pose.y() - truth.y()), 0.025) << trial;
    EXPECT_LE(std::abs(wrap_angle(r.pose.z() - truth.z())), std::max(r.angular_step, 0.01)) << trial;
    EXPECT_GT(r.match_quality, 0.5);
  }
}

/// Symmetric to rounding (the covariance is symmetrised explicitly) and positive definite.
void expect_spd(const Eigen::Matrix3d& c, const std::string& where) {
  EXPECT_TRUE(c.allFinite()) << where;
  EXPECT_EQ((c - c.transpose()).cwiseAbs().maxCoeff(), 0.0) << where;
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(c).eigenvalues().minCoeff(), 0.0) << where;
  EXPECT_EQ(Eigen::LLT<Eigen::Matrix3d>(c).info(), Eigen::Success) << where;
}

/// Variance of a uniform distribution over the search window's half-width w: (2 w)^2 / 12.
double window_variance(double w) { return w * w / 3.0; }

TEST(Slam2dCovariance, PositiveDefiniteInTheRoom) {
  const CorrelativeScanMatcher m(LikelihoodField::from_grid(room_map()));
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 12; ++trial) {
    const Eigen::Vector3d truth = random_truth(rng);
    const Points2 pts = noisy_scan(rng, truth, 0.01 + 0.02 * (u(rng) + 1));
    MatchOptions o;
    o.refine = trial % 3 != 0;
    o.use_prior = trial % 2;
    o.prior_covariance = Eigen::Vector3d(0.01, 0.02, 0.005).asDiagonal();
    const MatchResult r = m.match(pts, truth + 0.1 * Eigen::Vector3d(u(rng), u(rng), u(rng)), o);
    expect_spd(r.covariance, "trial " + std::to_string(trial));
    // Without refinement the pose is a lattice point: at least a uniform cell's variance.
    if (!o.refine) EXPECT_GE(r.covariance(0, 0), 0.05 * 0.05 / 12.0) << trial;
  }
}

/// A grid holding walls y = y_i for x in [-10, 10] (off the cell borders), mapped from below.
OccupancyGrid2D wall_map(const std::vector<double>& ys) {
  std::vector<Segment> walls;
  for (double y : ys) walls.push_back({{-10.0, y}, {10.0, y}});
  OccupancyGrid2D g = OccupancyGrid2D::covering(-11.0123, -2.9871, 11.0, 3.0, 0.05);
  const Eigen::VectorXd beams = Eigen::VectorXd::LinSpaced(241, -kPi, kPi);
  for (double x = -9.0; x <= 9.0; x += 0.5) {
    const Eigen::Vector3d pose(x, 0.0, 0.0);
    g.insert_rays(pose, cast(pose, beams, walls), beams, 30.0);
  }
  return g;
}

// A single wall or a corridor fixes y and theta but not x: along the wall the covariance must
// be about the window's (the search had nothing to choose x by), far above the other axes. The
// wall y = 1.0123 lies close to a row border, so the map draws it with cell-sized steps:
// texture that a local approximation would read as information along the wall.
TEST(Slam2dCovariance, LargeAlongAWallOrCorridor) {
  for (const std::vector<double>& ys : {std::vector<double>{1.0123}, std::vector<double>{-1.0123, 1.0123}}) {
    const CorrelativeScanMatcher m(LikelihoodField::from_grid(wall_map(ys)));
    std::vector<Segment> walls;
    for (double y : ys) walls.push_back({{-10.0, y}, {10.0, y}});
    // Beams within 60 degrees of the walls' normals: the walls' ends stay out of sight.
    Eigen::VectorXd beams(2 * 61);
    beams << Eigen::VectorXd::LinSpaced(61, kPi / 2 - kPi / 3, kPi / 2 + kPi / 3),
        Eigen::VectorXd::LinSpaced(61, -kPi / 2 - kPi / 3, -kPi / 2 + kPi / 3);
    std::mt19937 rng(4);
    std::normal_distribution<double> n(0.0, 0.01);
    for (const bool prior : {false, true}) {
      const Eigen::Vector3d truth(0.3, 0.0, 0.0);
      Eigen::VectorXd r = cast(truth, beams, walls);
      for (Eigen::Index i = 0; i < r.size(); ++i) r[i] += n(rng);
      MatchOptions o;
      o.use_prior = prior;
      o.prior_covariance = Eigen::Vector3d(1.0, 1.0, 1.0).asDiagonal();  // weaker than the window
      const MatchResult res = m.match(scan_hits(r, beams, ScanFilter{}), truth + Eigen::Vector3d(0.05, 0.02, 0.01), o);
      const std::string where = std::to_string(ys.size()) + " walls, prior " + std::to_string(prior);
      expect_spd(res.covariance, where);
      EXPECT_GE(res.covariance(0, 0), 0.5 * window_variance(o.window.linear)) << where;
      EXPECT_GT(res.covariance(0, 0), 50 * res.covariance(1, 1)) << where;
      EXPECT_LT(res.covariance(1, 1), 1e-3) << where;  // across the wall the scan decides
    }
  }
}

// Points far from every obstacle carry no information: the covariance is then the window's
// (uniform over the box the refinement may reach), or the prior cut by the window.
TEST(Slam2dCovariance, PriorAndWindowWhenTheScanSaysNothing) {
  const CorrelativeScanMatcher m(LikelihoodField::from_grid(room_map()));
  Points2 far(5, 2);
  far << 50, 0, 51, 1, 52, -1, 53, 2, 54, -2;  // outside the field
  const Eigen::Vector3d prior(0.2, -0.3, 0.4);
  MatchOptions o;
  const double res = 0.05;
  const MatchResult none = m.match(far, prior, o);
  expect_spd(none.covariance, "no prior");
  EXPECT_GE(none.covariance(0, 0), window_variance(o.window.linear)) << none.covariance;
  EXPECT_GE(none.covariance(2, 2), window_variance(o.window.angular)) << none.covariance;

  o.use_prior = true;
  Eigen::Matrix3d P;
  P << 0.01, 0.002, 0.001, 0.002, 0.02, -0.003, 0.001, -0.003, 0.005;
  o.prior_covariance = P;
  const MatchResult r = m.match(far, prior, o);
  expect_spd(r.covariance, "prior");
  // The window (+-0.35 m, rad) cuts the prior (std <= 0.15) beyond 2 std: the covariance lies
  // between the prior's and the prior fused with the window's Gaussian equivalent.
  const Eigen::Vector3d half(o.window.linear + res, o.window.linear + res, o.window.angular + r.angular_step);
  const Eigen::Matrix3d window_info = (half.cwiseAbs2() / 3.0).cwiseInverse().asDiagonal();
  const Eigen::Matrix3d fused = (P.inverse() + window_info).inverse();
  // Rounding of 3x3 inversions of matrices with entries ~1e-2: far below 1e-12.
  constexpr double kRounding = 1e-12;
  EXPECT_GE(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(r.covariance - fused).eigenvalues().minCoeff(), -kRounding)
      << r.covariance << "\n" << fused;
  EXPECT_GE(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(P - r.covariance).eigenvalues().minCoeff(), -kRounding)
      << r.covariance;
}

// A prior much sharper than the scan dominates; the user's floors are added on top.
TEST(Slam2dCovariance, SharpPriorAndUserFloors) {
  const CorrelativeScanMatcher m(LikelihoodField::from_grid(room_map()));
  std::mt19937 rng(9);
  const Eigen::Vector3d truth = random_truth(rng);
  const Points2 pts = noisy_scan(rng, truth, 0.01);
  MatchOptions o;
  o.use_prior = true;
  const Eigen::Vector3d prior_var(1e-8, 2e-8, 1e-9);
  o.prior_covariance = prior_var.asDiagonal();
  const MatchResult sharp = m.match(pts, truth, o);
  for (int j = 0; j < 3; ++j) EXPECT_NEAR(sharp.covariance(j, j), prior_var[j], 0.05 * prior_var[j]) << j;

  o.use_prior = false;
  const MatchResult base = m.match(pts, truth, o);
  o.min_translation_std = 0.2;
  o.min_rotation_std = 0.1;
  const MatchResult floored = m.match(pts, truth, o);
  expect_spd(floored.covariance, "floors");
  EXPECT_GE(floored.covariance(0, 0), 0.04);
  EXPECT_GE(floored.covariance(1, 1), 0.04);
  EXPECT_GE(floored.covariance(2, 2), 0.01);
  EXPECT_LT(floored.covariance(2, 2), 0.01 + 2 * base.covariance(2, 2));
}

TEST(Slam2dScan, FilterAndInsertionSemantics) {
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  ScanFilter f;
  f.max_range = 10.0;
  f.min_range = 0.1;
  f.max_usable_range = 5.0;
  Eigen::VectorXd r(10), a = Eigen::VectorXd::LinSpaced(10, -1, 1);
  r << 1.0, nan, inf, 10.0, 12.0, -1.0, 0.05, 6.0, 2.0, -inf;
  const Points2 hits = scan_hits(r, a, f);
  ASSERT_EQ(hits.rows(), 2);
  EXPECT_NEAR(hits.row(0).norm(), 1.0, 1e-12);
  EXPECT_NEAR(hits(1, 0), 2.0 * std::cos(a[8]), 1e-12);
  Eigen::VectorXd ins = ranges_for_insertion(r, f);
  const double expect_clear[10] = {1.0, 5.0, 5.0, 5.0, 5.0, nan, nan, 5.0, 2.0, nan};
  for (int i = 0; i < 10; ++i) {
    if (std::isnan(expect_clear[i]))
      EXPECT_TRUE(std::isnan(ins[i])) << i;
    else
      EXPECT_EQ(ins[i], expect_clear[i]) << i;
  }
  f.clear_no_return = false;
  ins = ranges_for_insertion(r, f);
  for (int i = 0; i < 10; ++i) {
    if (i == 0 || i == 8)
      EXPECT_EQ(ins[i], r[i]);
    else
      EXPECT_TRUE(std::isnan(ins[i])) << i;
  }
  // Decimation: kept points are at least the spacing apart; each dropped one is within it of the
  // last kept point.
  ScanFilter d;
  d.min_point_spacing = 0.3;
  const Eigen::VectorXd ang = Eigen::VectorXd::LinSpaced(200, -2, 2);
  Eigen::VectorXd rr = Eigen::VectorXd::Constant(200, 3.0);
  const Points2 all = scan_hits(rr, ang, ScanFilter{}), kept = scan_hits(rr, ang, d);
  ASSERT_EQ(all.rows(), 200);
  ASSERT_LT(kept.rows(), 200);
  Eigen::Index k = 0;
  for (Eigen::Index i = 0; i < all.rows(); ++i) {
    if (k < kept.rows() && all.row(i) == kept.row(k)) {
      if (k > 0) EXPECT_GE((kept.row(k) - kept.row(k - 1)).norm(), 0.3);
      ++k;
    } else {
      ASSERT_GT(k, 0);
      EXPECT_LT((all.row(i) - kept.row(k - 1)).norm(), 0.3);
    }
  }
  EXPECT_EQ(k, kept.rows());
}

TEST(Slam2dBadInput, EachNamesItsArgument) {
  OccupancyGrid2D g(0.05, 40, 40, {-1.01, -0.99});
  g.log_odds()(20, 20) = 2.0;
  const LikelihoodField field = LikelihoodField::from_grid(g);
  const CorrelativeScanMatcher m(field);
  Points2 pts(2, 2);
  pts << 0.5, 0.0, 0.0, 0.5;
  const Eigen::Vector3d prior = Eigen::Vector3d::Zero();
  const double nan = std::nan("");
  expect_invalid([&] { m.match(Points2(0, 2), prior); }, "points");
  Points2 bad = pts;
  bad(1, 0) = nan;
  expect_invalid([&] { m.match(bad, prior); }, "points");
  expect_invalid([&] { m.match(pts, Eigen::Vector3d(0, nan, 0)); }, "prior");
  auto with = [&](auto change, const char* name) {
    MatchOptions o;
    change(o);
    expect_invalid([&] { m.match(pts, prior, o); }, name);
  };
  with([](MatchOptions& o) { o.window.linear = -0.1; }, "window.linear");
  with([](MatchOptions& o) { o.window.angular = -0.1; }, "window.angular");
  with([](MatchOptions& o) { o.window.angular = 3.2; }, "window.angular");
  with([&](MatchOptions& o) { o.window.angular_step = nan; }, "window.angular_step");
  with([](MatchOptions& o) { o.window = {2000.0, 0.0, 0.0}; }, "window");
  with([](MatchOptions& o) { o.window = {0.0, kPi, 1e-12}; }, "window");
  // Within the candidate limit, yet the rotated scans or the top-level nodes would fill memory.
  with([](MatchOptions& o) { o.window = {0.0, kPi, 1e-8}; }, "angular_step");
  const CorrelativeScanMatcher flat(field, 0);
  MatchOptions wide;
  wide.window = {100 * g.resolution(), 0.4, 1e-4};
  expect_invalid([&] { flat.match(pts, prior, wide); }, "max_level");
  with([](MatchOptions& o) { o.use_prior = true, o.prior_covariance = -Eigen::Matrix3d::Identity(); },
       "prior_covariance");
  with([](MatchOptions& o) { o.use_prior = true, o.prior_covariance(0, 1) = 0.5; }, "prior_covariance");
  with([&](MatchOptions& o) { o.use_prior = true, o.prior_covariance(2, 2) = nan; }, "prior_covariance");
  expect_invalid([&] { m.smooth_score(pts, Eigen::Vector3d(nan, 0, 0), prior, {}); }, "pose");
  expect_invalid([&] { CorrelativeScanMatcher(field, -1); }, "max_level");
  expect_invalid([&] { CorrelativeScanMatcher(field, CorrelativeScanMatcher::kMaxLevel + 1); }, "max_level");
  auto field_with = [&](auto change, const char* name) {
    LikelihoodFieldOptions o;
    change(o);
    expect_invalid([&] { LikelihoodField::from_grid(g, o); }, name);
  };
  field_with([](LikelihoodFieldOptions& o) { o.sigma = 0.0; }, "sigma");
  field_with([](LikelihoodFieldOptions& o) { o.sigma = -1.0; }, "sigma");
  field_with([&](LikelihoodFieldOptions& o) { o.sigma = nan; }, "sigma");
  field_with([](LikelihoodFieldOptions& o) { o.p_rand = 0.0; }, "p_rand");
  field_with([](LikelihoodFieldOptions& o) { o.p_rand = 1.0; }, "p_rand");
  field_with([&](LikelihoodFieldOptions& o) { o.p_rand = nan; }, "p_rand");
  field_with([&](LikelihoodFieldOptions& o) { o.occupied_threshold = nan; }, "occupied_threshold");
  field_with([&](LikelihoodFieldOptions& o) { o.max_distance = nan; }, "max_distance");
  expect_invalid([&] { LikelihoodField::from_grid(g, Eigen::Vector4d(0, nan, 1, 1)); }, "region");
  expect_invalid([&] { LikelihoodField::from_grid(g, Eigen::Vector4d(1, 1, 0, 0)); }, "region");
  auto filter_with = [&](auto change, const char* name) {
    ScanFilter f;
    change(f);
    expect_invalid([&] { scan_hits(Eigen::VectorXd::Ones(3), Eigen::VectorXd::Zero(3), f); }, name);
    expect_invalid([&] { ranges_for_insertion(Eigen::VectorXd::Ones(3), f); }, name);
  };
  filter_with([&](ScanFilter& f) { f.max_range = nan; }, "max_range");
  filter_with([](ScanFilter& f) { f.max_range = 0.0; }, "max_range");
  filter_with([](ScanFilter& f) { f.min_range = -1.0; }, "min_range");
  filter_with([&](ScanFilter& f) { f.min_range = nan; }, "min_range");
  filter_with([](ScanFilter& f) { f.min_range = 40.0; }, "min_range");
  filter_with([](ScanFilter& f) { f.max_usable_range = std::numeric_limits<double>::infinity(); },
              "max_usable_range");
  filter_with([](ScanFilter& f) { f.max_usable_range = 0.0; }, "max_usable_range");
  filter_with([](ScanFilter& f) { f.min_point_spacing = -0.1; }, "min_point_spacing");
  expect_invalid([&] { scan_hits(Eigen::VectorXd::Ones(3), Eigen::VectorXd::Zero(2), ScanFilter{}); },
                 "beam_angles");
  expect_invalid([&] { scan_hits(Eigen::VectorXd::Ones(2), Eigen::Vector2d(0, nan), ScanFilter{}); },
                 "beam_angles");
}

namespace {

// Two laps around the room's box with odometry whose heading drifts 0.003 rad per 0.2 m step.
struct LoopDrive {
  std::vector<Eigen::Vector3d> truth, odometry;
  std::vector<Eigen::VectorXd> ranges;
};

LoopDrive loop_drive(int steps) {
  std::mt19937 rng(17);
  std::normal_distribution<double> noise(0.0, 0.01);
  LoopDrive d;
  for (int k = 0; k < steps; ++k) {
    const double s = 4.0 * kPi * k / steps;
    d.truth.emplace_back(1.5 + 2.6 * std::cos(s), 1.5 + 2.6 * std::sin(s), wrap_angle(s + kPi / 2));
  }
  d.odometry.push_back(d.truth[0]);
  for (int k = 1; k < steps; ++k) {
    Eigen::Vector3d step = Pose2::from_vector(d.truth[k - 1]).between(Pose2::from_vector(d.truth[k])).vector();
    step.z() += 0.003;
    d.odometry.push_back(Pose2::from_vector(d.odometry.back()).compose(Pose2::from_vector(step)).vector());
  }
  for (const Eigen::Vector3d& p : d.truth) {
    Eigen::VectorXd r = cast(p, fan(), room_walls());
    for (Eigen::Index b = 0; b < r.size(); ++b) r[b] += noise(rng);
    d.ranges.push_back(r);
  }
  return d;
}

double end_error(const std::vector<Eigen::Vector3d>& poses, const std::vector<Eigen::Vector3d>& truth) {
  return (poses.back().head<2>() - truth.back().head<2>()).norm();
}

}  // namespace

TEST(Slam2dSubmapSlam, LoopClosuresRemoveTheOdometryDrift) {
  const LoopDrive d = loop_drive(160);
  SubmapSlamOptions o;
  o.frontend.filter.max_range = 30.0;
  o.frontend.min_match_quality = 1.0;  // the frontend keeps the odometry: only closures can help
  o.frontend.submap_distance = 4.0;
  SubmapSlam2D slam(o);
  for (std::size_t k = 0; k < d.truth.size(); ++k) slam.add_scan(d.ranges[k], fan(), d.odometry[k], double(k));
  slam.finish();
  const SubmapSlamSummary s = slam.summary();
  EXPECT_GE(s.closures_accepted, 2);
  EXPECT_GT(end_error(d.odometry, d.truth), 1.0);
  // Each submap's origin (its node) is back on the truth; scans inside a submap keep the
  // odometry's drift since its origin (0.06 rad over a 4 m submap here), so only their median is.
  for (int j = 0; j < slam.num_submaps(); ++j) {
    const int origin_scan = slam.frontend().submaps()[j].scans.front();
    EXPECT_LT((slam.submap_poses()[j].head<2>() - d.truth[origin_scan].head<2>()).norm(), 0.1) << "submap " << j;
  }
  std::vector<double> errors;
  const std::vector<Eigen::Vector3d> poses = slam.scan_poses();
  for (std::size_t k = 0; k < poses.size(); ++k) errors.push_back((poses[k] - d.truth[k]).head<2>().norm());
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.1);
  EXPECT_TRUE(std::isfinite(s.final_chi2));
  const PoseGraph2D g = slam.graph();
  EXPECT_EQ(g.num_vertices(), slam.num_submaps());
  for (const SubmapConstraint& c : slam.constraints()) {
    EXPECT_LT((c.covariance - c.covariance.transpose()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(c.covariance).eigenvalues().minCoeff(), 0.0);
  }
}

TEST(Slam2dSubmapSlam, CopyIsDeepAndContinuesAsTheOriginalDoes) {
  // A copy made halfway (two submaps closed, one open) and the original, fed the same scans and
  // finished, end with the same graph; the copy's scans never reach the original.
  const LoopDrive d = loop_drive(80);
  SubmapSlamOptions o;
  o.frontend.filter.max_range = 30.0;
  o.frontend.submap_distance = 4.0;
  SubmapSlam2D original(o);
  IncrementalScanMatcher frontend(o.frontend);
  const std::size_t half = d.truth.size() / 2;
  for (std::size_t k = 0; k < half; ++k) {
    original.add_scan(d.ranges[k], fan(), d.odometry[k], double(k));
    frontend.add_scan(d.ranges[k], fan(), d.odometry[k], double(k));
  }
  SubmapSlam2D copy(original);
  IncrementalScanMatcher frontend_copy(frontend);
  ASSERT_GE(copy.num_submaps(), 2);
  for (std::size_t k = half; k < d.truth.size(); ++k) {
    copy.add_scan(d.ranges[k], fan(), d.odometry[k], double(k));
    frontend_copy.add_scan(d.ranges[k], fan(), d.odometry[k], double(k));
  }
  EXPECT_EQ(original.num_scans(), static_cast<int>(half));
  EXPECT_EQ(frontend.num_scans(), static_cast<int>(half));
  for (std::size_t k = half; k < d.truth.size(); ++k) {
    original.add_scan(d.ranges[k], fan(), d.odometry[k], double(k));
    frontend.add_scan(d.ranges[k], fan(), d.odometry[k], double(k));
  }
  original.finish();
  copy.finish();
  EXPECT_EQ(copy.scan_poses(), original.scan_poses());
  EXPECT_EQ(copy.submap_poses(), original.submap_poses());
  ASSERT_EQ(copy.constraints().size(), original.constraints().size());
  for (std::size_t c = 0; c < copy.constraints().size(); ++c)
    EXPECT_TRUE(copy.constraints()[c].measurement == original.constraints()[c].measurement) << "constraint " << c;
  EXPECT_EQ(copy.summary().closures_accepted, original.summary().closures_accepted);
  for (int k = 0; k < frontend.num_scans(); ++k)
    EXPECT_TRUE(frontend_copy.estimates()[k].pose == frontend.estimates()[k].pose) << "scan " << k;
}

TEST(Slam2dSubmapSlam, BadOptionsAndEmptyInput) {
  SubmapSlamOptions o;
  o.closures.scans_per_submap = 0;
  expect_invalid([&] { SubmapSlam2D s(o); }, "closures.scans_per_submap");
  o = SubmapSlamOptions();
  o.closures.max_angular_window = 4.0;
  expect_invalid([&] { SubmapSlam2D s(o); }, "closures.max_angular_window");
  o = SubmapSlamOptions();
  o.max_rounds = 0;
  expect_invalid([&] { SubmapSlam2D s(o); }, "max_rounds");
  SubmapSlam2D empty;
  empty.finish();
  EXPECT_EQ(empty.num_scans(), 0);
  expect_invalid([&] { empty.map(); }, "scans");
}

TEST(Slam2dSubmapSlam, StartsFromASavedMapInTheMapsFrame) {
  // The loop drive with its odometry in a frame of its own (rotated and shifted from the
  // room's): started on the room's map with a start pose 0.1 m and 0.03 rad off, the scans land
  // in the map's frame, near the truth.
  const LoopDrive d = loop_drive(80);
  const Pose2 odom_frame(5.0, -3.0, 1.0);
  SubmapSlamOptions o;
  o.frontend.filter.max_range = 30.0;
  o.frontend.submap_distance = 4.0;
  SubmapSlam2D slam(o);
  const OccupancyGrid2D room = room_map();
  slam.start_from_map(room, d.truth[0] + Eigen::Vector3d(0.1, -0.1, 0.03));
  for (std::size_t k = 0; k < d.truth.size(); ++k)
    slam.add_scan(d.ranges[k], fan(), odom_frame.compose(Pose2::from_vector(d.odometry[k])).vector(), double(k));
  slam.finish();
  // Scan matching in a known room: each pose within this of the truth (the matcher's accuracy
  // at 5 cm cells with 1 cm range noise is a cell or two; the odometry's drift is removed).
  constexpr double kOnTheMap = 0.1;
  const std::vector<Eigen::Vector3d> poses = slam.scan_poses();
  for (std::size_t k = 0; k < poses.size(); ++k)
    EXPECT_LT((poses[k] - d.truth[k]).head<2>().norm(), kOnTheMap) << "scan " << k;
  EXPECT_EQ(slam.submap_poses()[0], Eigen::Vector3d::Zero());  // the map's node stays at its origin
  ASSERT_NE(slam.start_map(), nullptr);
  EXPECT_TRUE(slam.start_map()->same_geometry(room));  // the saved map itself is not changed
  EXPECT_EQ(Eigen::MatrixXd(slam.start_map()->log_odds()), Eigen::MatrixXd(room.log_odds()));
  const OccupancyGrid2D drawn = slam.map();
  EXPECT_EQ(drawn.resolution(), room.resolution());
  // Drawn on the map's lattice: the same cell centres.
  const Eigen::Vector2d shift = (drawn.origin() - room.origin()) / room.resolution();
  EXPECT_LT((shift - shift.array().round().matrix()).norm(), 1e-9);
  // Saved and loaded (a copy too) it continues as the original.
  SubmapSlam2D copy(slam);
  EXPECT_EQ(copy.scan_poses(), slam.scan_poses());
  ASSERT_NE(copy.start_map(), nullptr);
}

TEST(Slam2dSubmapSlam, StartFromMapRefusesBadInput) {
  SubmapSlamOptions o;
  o.frontend.filter.max_range = 30.0;
  const OccupancyGrid2D room = room_map();
  const LoopDrive d = loop_drive(10);
  {
    SubmapSlam2D s(o);
    s.add_scan(d.ranges[0], fan(), d.odometry[0], 0.0);
    expect_invalid([&] { s.start_from_map(room, Eigen::Vector3d::Zero()); }, "map");
  }
  SubmapSlam2D s(o);
  const OccupancyGrid2D unknown = OccupancyGrid2D::covering(-1, -1, 1, 1, 0.05);
  expect_invalid([&] { s.start_from_map(unknown, Eigen::Vector3d::Zero()); }, "map");
  const OccupancyGrid2D coarse = OccupancyGrid2D::covering(-1, -1, 1, 1, 0.1);
  expect_invalid([&] { s.start_from_map(coarse, Eigen::Vector3d::Zero()); }, "map");
  expect_invalid([&] { s.start_from_map(room, Eigen::Vector3d(40.0, 0.0, 0.0)); }, "initial_pose");
  expect_invalid([&] { s.start_from_map(room, Eigen::Vector3d(0.0, std::nan(""), 0.0)); }, "initial_pose");
  EXPECT_EQ(s.start_map(), nullptr);  // nothing changed by the refusals
  s.start_from_map(room, Eigen::Vector3d::Zero());
  expect_invalid([&] { s.start_from_map(room, Eigen::Vector3d::Zero()); }, "map");
  s.add_scan(d.ranges[0], fan(), d.odometry[0], 0.0);
  expect_invalid([&] { s.map(0.1); }, "resolution");
}

TEST(Slam2dGridFastSlam, StartsFromASavedMapInTheMapsFrame) {
  // The loop drive's odometry in a frame of its own; started on the room's map 0.1 m and 0.03
  // rad off the truth, every particle's map is the room's and the best path lies in its frame.
  const LoopDrive d = loop_drive(80);
  const Pose2 odom_frame(5.0, -3.0, 1.0);
  GridFastSlamOptions o;
  o.num_particles = 5;
  o.filter.max_range = 30.0;
  GridFastSlam rbpf(o);
  const OccupancyGrid2D room = room_map();
  rbpf.start_from_map(room, d.truth[0] + Eigen::Vector3d(0.1, -0.1, 0.03));
  expect_invalid([&] { rbpf.start_from_map(room, d.truth[0]); }, "map");
  for (std::size_t k = 0; k < d.truth.size(); ++k)
    rbpf.add_scan(d.ranges[k], fan(), odom_frame.compose(Pose2::from_vector(d.odometry[k])).vector(), double(k));
  // The first scan is matched against the room's map, the rest against maps that hold it:
  // within two cells of the truth, as the graph run above.
  constexpr double kOnTheMap = 0.1;
  const Poses2 poses = rbpf.scan_poses(rbpf.best_index());
  for (Eigen::Index k = 0; k < poses.rows(); ++k)
    EXPECT_LT((poses.row(k).head<2>().transpose() - d.truth[k].head<2>()).norm(), kOnTheMap) << "scan " << k;
  ASSERT_NE(rbpf.start_map(), nullptr);
  const OccupancyGrid2D drawn = rbpf.map(rbpf.best_index());
  const Eigen::Vector2d shift = (drawn.origin() - room.origin()) / room.resolution();
  EXPECT_LT((shift - shift.array().round().matrix()).norm(), 1e-9);  // on the map's lattice
  GridFastSlam refused(o);
  expect_invalid([&] { refused.start_from_map(room, Eigen::Vector3d(40.0, 0.0, 0.0)); }, "initial_pose");
  expect_invalid([&] { refused.start_from_map(OccupancyGrid2D::covering(-1, -1, 1, 1, 0.05), Eigen::Vector3d::Zero()); },
                 "map");
  EXPECT_EQ(refused.start_map(), nullptr);
}
