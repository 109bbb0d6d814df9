// The frontend's local optimiser (issue 54): CorrelativeScanMatcher::local_match against a
// brute-force maximisation of the same score over sampled poses, its gradient against finite
// differences of that score, and IncrementalScanMatcher's fallback to the correlative search
// when a scan's local match fails (a prediction far off), counted in its timings.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "probslam/core/angle.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"
#include "probslam/slam2d/correlative_scan_matcher.hpp"
#include "probslam/slam2d/incremental_scan_matcher.hpp"
#include "probslam/slam2d/likelihood_field.hpp"
#include "probslam/slam2d/range_scan.hpp"
#include "test_support.hpp"

using namespace probslam;

namespace {

using test_support::cast;
using test_support::room_walls;

Eigen::VectorXd fan() { return Eigen::VectorXd::LinSpaced(91, -kPi / 2, kPi / 2); }

/// The room of test_slam2d (walls, a pillar, a slanted wall) mapped from a few poses.
const LikelihoodField& room_field() {
  static const LikelihoodField field = [] {
    OccupancyGrid2D g = OccupancyGrid2D::covering(-6.0123, -5.9871, 6, 6, 0.05);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-3, 3);
    for (int i = 0; i < 20; ++i) {
      const Eigen::Vector3d pose(u(rng), u(rng), u(rng));
      g.insert_rays(pose, cast(pose, fan(), room_walls()), fan(), 30.0);
    }
    return LikelihoodField::from_grid(g);
  }();
  return field;
}

Points2 scan_at(std::mt19937& rng, const Eigen::Vector3d& pose, double noise) {
  std::normal_distribution<double> n(0.0, noise);
  Eigen::VectorXd r = cast(pose, fan(), room_walls());
  for (Eigen::Index i = 0; i < r.size(); ++i) r[i] += n(rng);
  return scan_hits(r, fan(), ScanFilter{});
}

/// Poses away from the pillar [1, 2]^2, inside the room.
Eigen::Vector3d random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  for (;;) {
    const Eigen::Vector3d x(2 * u(rng), 2 * u(rng), kPi * u(rng));
    if (!(x.x() > 0.6 && x.x() < 2.4 && x.y() > 0.6 && x.y() < 2.4)) return x;
  }
}

MatchOptions options_with_prior(bool use_prior) {
  MatchOptions o;
  o.use_prior = use_prior;
  // An odometry-like prior: 2 cm, 1 deg.
  o.prior_covariance = Eigen::Vector3d(4e-4, 4e-4, 3e-4).asDiagonal();
  return o;
}

}  // namespace

TEST(LocalMatch, MaximisesTheScoreAsABruteForceSearchOfSampledPoses) {
  const CorrelativeScanMatcher m(room_field(), 0);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  // Samples: a cube of +-kSpan around the optimiser's pose, kStep apart (m and rad alike).
  constexpr int kHalf = 8;
  constexpr double kStep = 1.5e-3;
  for (int trial = 0; trial < 6; ++trial) {
    const Eigen::Vector3d truth = random_pose(rng);
    const Points2 pts = scan_at(rng, truth, 0.01);
    // A prediction a few centimetres and a degree off: inside the basin.
    const Eigen::Vector3d prior = truth + Eigen::Vector3d(0.04 * u(rng), 0.04 * u(rng), 0.02 * u(rng));
    const MatchOptions o = options_with_prior(trial % 2 == 0);
    const MatchResult r = m.local_match(pts, prior, prior, o);
    ASSERT_TRUE(r.found) << trial;
    EXPECT_EQ(r.angular_steps, 0);
    EXPECT_NEAR(r.score, m.smooth_score(pts, r.pose, prior, o), 1e-9 * std::abs(r.score));
    double best = -std::numeric_limits<double>::infinity();
    Eigen::Vector3d argbest = r.pose;
    for (int i = -kHalf; i <= kHalf; ++i)
      for (int j = -kHalf; j <= kHalf; ++j)
        for (int k = -kHalf; k <= kHalf; ++k) {
          const Eigen::Vector3d p = r.pose + kStep * Eigen::Vector3d(i, j, k);
          const double s = m.smooth_score(pts, p, prior, o);
          if (s > best) best = s, argbest = p;
        }
    // No sampled pose scores above the optimiser's (beyond the sum's rounding), and the best
    // sample is the optimiser's pose to within one sample step per axis.
    EXPECT_GE(r.score, best - 1e-9 * std::abs(best)) << trial;
    EXPECT_LE((argbest - r.pose).cwiseAbs().maxCoeff(), kStep * 1.0001) << trial;
    // And it is the place the scan was taken from.
    EXPECT_LT((r.pose.head<2>() - truth.head<2>()).norm(), 0.02) << trial;
    // Its covariance is the refined pose's, as match() gives it at the same pose.
    const MatchResult searched = m.match(pts, prior, o);
    if ((searched.pose - r.pose).cwiseAbs().maxCoeff() < 1e-6) {
      EXPECT_LT((searched.covariance - r.covariance).norm(), 1e-4 * searched.covariance.norm()) << trial;
    }
  }
}

TEST(LocalMatch, GradientEqualsFiniteDifferencesOfTheScore) {
  const CorrelativeScanMatcher m(room_field(), 0);
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1, 1);
  // Central differences over 1e-5 (m, rad): well inside a 5 cm cell, and over about 1/10 of the
  // log p table's interval in distance, whose linear interpolation the score reads (the
  // gradient takes log p's slope from the model): the difference is the table's, a few 1e-3
  // of the gradient.
  constexpr double kH = 1e-5;
  constexpr double kRelative = 1e-2;
  for (int trial = 0; trial < 8; ++trial) {
    const Eigen::Vector3d truth = random_pose(rng);
    const Points2 pts = scan_at(rng, truth, 0.02);
    const Eigen::Vector3d prior = truth + Eigen::Vector3d(0.03 * u(rng), 0.03 * u(rng), 0.02 * u(rng));
    const Eigen::Vector3d pose = truth + Eigen::Vector3d(0.03 * u(rng), 0.03 * u(rng), 0.02 * u(rng));
    const MatchOptions o = options_with_prior(trial % 2 == 0);
    const CorrelativeScanMatcher::Linearization l = m.linearize(pts, pose, prior, o);
    EXPECT_NEAR(l.score, m.smooth_score(pts, pose, prior, o), 1e-12 * std::abs(l.score));
    Eigen::Vector3d fd;
    for (int i = 0; i < 3; ++i) {
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      e[i] = kH;
      fd[i] = -(m.smooth_score(pts, pose + e, prior, o) - m.smooth_score(pts, pose - e, prior, o)) / (2 * kH);
    }
    EXPECT_LT((l.gradient - fd).norm(), kRelative * fd.norm()) << trial << ": " << l.gradient.transpose()
                                                                  << " vs " << fd.transpose();
    // The Gauss-Newton Hessian is symmetric positive semi-definite.
    EXPECT_LT((l.hessian - l.hessian.transpose()).norm(), 1e-12 * l.hessian.norm());
  }
}

TEST(LocalMatch, NotFoundWhereTheScanFixesNothingWithoutAPrior) {
  // One wall (y = 1): the scan does not fix x; without a prior the Hessian is singular along
  // it and the local optimiser gives no match, with a prior it does.
  OccupancyGrid2D g = OccupancyGrid2D::covering(-8, -3, 8, 3, 0.05);
  const std::vector<test_support::Segment> wall{{Eigen::Vector2d(-8, 1), Eigen::Vector2d(8, 1)}};
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(91, 0.3, kPi - 0.3);
  for (double x = -4; x <= 4; x += 0.5) {
    const Eigen::Vector3d p(x, 0, 0);
    g.insert_rays(p, cast(p, angles, wall), angles, 30.0);
  }
  const CorrelativeScanMatcher m(LikelihoodField::from_grid(g), 0);
  const Eigen::Vector3d truth(0.3, 0.0, 0.0);
  const Points2 pts = scan_hits(cast(truth, angles, wall), angles, ScanFilter{});
  const Eigen::Vector3d prior = truth + Eigen::Vector3d(0.02, 0.01, 0.005);
  EXPECT_FALSE(m.local_match(pts, prior, prior, options_with_prior(false)).found);
  const MatchResult r = m.local_match(pts, prior, prior, options_with_prior(true));
  EXPECT_TRUE(r.found);
  EXPECT_NEAR(r.pose.y(), truth.y(), 0.03);  // the map holds the wall to its 5 cm cells
}

TEST(LocalMatch, FrontendFallsBackToTheSearchWhenThePredictionIsFarOff) {
  // A robot driving through the room with the truth as odometry, then one scan whose odometry
  // is 0.2 m and 0.15 rad off (inside the search window, far outside the odometry prior): the
  // local match fails its gates and the search finds the scan's place; every other scan is
  // matched locally, at the pose the search gives.
  IncrementalScanMatcherOptions o;
  o.submap_distance = 0.0;
  std::vector<Eigen::Vector3d> truth;
  for (int k = 0; k < 12; ++k) truth.emplace_back(-3.0 + 0.1 * k, -1.0 + 0.03 * k, 0.4 + 0.02 * k);
  IncrementalScanMatcherOptions always = o;
  always.search = FrontendSearch::kAlways;
  IncrementalScanMatcher local(o), searched(always);
  const int off = 10;
  // A slip before scan `off`: its odometry and every later one moved by one rigid transform.
  const Pose2 slip = Pose2::from_vector(truth[off] + Eigen::Vector3d(0.2, -0.1, 0.15))
                         .compose(Pose2::from_vector(truth[off]).inverse());
  for (int k = 0; k < static_cast<int>(truth.size()); ++k) {
    const Eigen::VectorXd r = cast(truth[k], fan(), room_walls());
    const Eigen::Vector3d odometry = k < off ? truth[k] : slip.compose(Pose2::from_vector(truth[k])).vector();
    const long searches = local.timings().searches, locals = local.timings().local_matches;
    const ScanEstimate a = local.add_scan(r, fan(), odometry, k);
    const ScanEstimate b = searched.add_scan(r, fan(), odometry, k);
    if (k == 0) continue;
    ASSERT_TRUE(a.matched) << k;
    // Within the map's own error (5 cm cells, 91 beams: both matchers alike), where the far-off
    // scan's odometry is 0.22 m and 0.15 rad from the truth.
    EXPECT_LT((a.pose.head<2>() - truth[k].head<2>()).norm(), 0.06) << k;
    EXPECT_LT(std::abs(wrap_angle(a.pose.z() - truth[k].z())), 0.02) << k;
    EXPECT_LT((a.pose - b.pose).cwiseAbs().maxCoeff(), 0.01) << k;
    if (k == off) {
      EXPECT_EQ(local.timings().searches, searches + 1) << "the far-off prediction is searched";
      EXPECT_EQ(local.timings().local_matches, locals);
    }
  }
  // Most scans are matched locally.
  EXPECT_GT(local.timings().local_matches, 2 * local.timings().searches);
  EXPECT_EQ(local.timings().local_matches + local.timings().searches, static_cast<long>(truth.size()) - 1);
  EXPECT_EQ(searched.timings().local_matches, 0);
  EXPECT_EQ(searched.timings().searches, static_cast<long>(truth.size()) - 1);
}

// The covariance's profile skips a pose once its score is certain to fall below a floor
// (smooth_score's floor): a pose kept scores bit for bit as without the floor, a pose given up
// on scores below it, and far poses are given up on (else the floor saves nothing).
TEST(LocalMatch, ScoreFloorGivesUpOnlyOnPosesCertainlyBelowIt) {
  const CorrelativeScanMatcher m(room_field(), 0);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  int given_up = 0, kept = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::Vector3d truth = random_pose(rng);
    const Points2 pts = scan_at(rng, truth, 0.01);
    const MatchOptions o = options_with_prior(trial % 2 == 0);
    // Poses from on the truth to a window's width off it, floors from far below to far above.
    const double off = 0.3 * (trial % 5) / 4.0;
    const Eigen::Vector3d pose = truth + Eigen::Vector3d(off * u(rng), off * u(rng), off * u(rng));
    const double full = m.smooth_score(pts, pose, truth, o);
    for (const double gap : {-200.0, -20.0, -1.0, 0.0, 1.0, 20.0, 200.0}) {
      const double floor = full + gap;
      const double s = m.smooth_score(pts, pose, truth, o, floor);
      if (std::isinf(s)) {
        EXPECT_LT(s, 0.0);
        EXPECT_LT(full, floor) << "trial " << trial << " gap " << gap;
        ++given_up;
      } else {
        EXPECT_EQ(s, full) << "trial " << trial << " gap " << gap;  // bit for bit
        ++kept;
      }
    }
  }
  EXPECT_GT(given_up, 20);
  EXPECT_GT(kept, 100);
  EXPECT_THROW(m.smooth_score(scan_at(rng, Eigen::Vector3d::Zero(), 0.0), Eigen::Vector3d::Zero(),
                              Eigen::Vector3d::Zero(), MatchOptions{}, std::nan("")),
               std::invalid_argument);
}
