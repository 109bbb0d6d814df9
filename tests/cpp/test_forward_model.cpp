// The forward beam model (ch. 6.3) and Table 9.3 MAP occupancy grid mapping.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "probslam/core/angle.hpp"
#include "probslam/grid/beam_sensor_model.hpp"
#include "probslam/grid/map_occupancy_mapping.hpp"
#include "test_support.hpp"

namespace probslam {
namespace {

using test_support::expect_invalid;

BeamMixture mixture(double max_range = 4.0) {
  BeamMixture m;
  m.z_hit = 0.7, m.z_short = 0.1, m.z_max = 0.1, m.z_rand = 0.1;
  m.sigma_hit = 0.1, m.lambda_short = 0.8, m.max_range = max_range;
  return m;
}

// Midpoint-rule step for the normalisation integral: the hit Gaussian (sigma 0.1 m) spans 100 steps.
constexpr double kIntegrationStep = 1e-4;
// Midpoint rule on a smooth density with 4e4 steps: error ~1e-7; the kinks of the truncations add ~step.
constexpr double kIntegralTolerance = 5e-4;

TEST(BeamMixture, IntegratesToOneWithTheMaxMass) {
  const BeamMixture m = mixture();
  for (const double zs : {0.0, 0.05, 1.3, 3.95, 4.0}) {
    double integral = 0.0;
    for (double z = 0.5 * kIntegrationStep; z < m.max_range; z += kIntegrationStep)
      integral += m.probability(z, zs) * kIntegrationStep;
    // The point masses: p_max at max_range (eq. 6.10) and, for z* = 0, p_short's at 0.
    integral += m.z_max + (zs == 0.0 ? m.z_short : 0.0);
    EXPECT_NEAR(integral, 1.0, kIntegralTolerance) << "z* = " << zs;
  }
}

TEST(BeamMixture, RejectsBadParameters) {
  BeamMixture m = mixture();
  m.z_hit = -0.1, m.z_rand = 0.3;
  expect_invalid([&] { m.validate(); }, "z_hit");
  m = mixture();
  m.z_rand = 0.2;  // sum 1.1
  expect_invalid([&] { m.validate(); }, "z_hit");
  m = mixture();
  m.z_rand += 2 * BeamMixture::kWeightSumTolerance;
  expect_invalid([&] { m.validate(); }, "z_hit");
  m = mixture();
  m.sigma_hit = 0.0;
  expect_invalid([&] { m.validate(); }, "sigma_hit");
  m = mixture();
  m.lambda_short = -1.0;
  expect_invalid([&] { m.validate(); }, "lambda_short");
  m = mixture();
  m.max_range = NAN;
  expect_invalid([&] { m.validate(); }, "max_range");
  expect_invalid([&] { BeamSensorModel(mixture(), BeamShape::kSonar, 0.0); }, "beta");
  expect_invalid([&] { BeamSensorModel(mixture(), BeamShape::kSonar, -0.2); }, "beta");
  EXPECT_NO_THROW(BeamSensorModel(mixture(), BeamShape::kLaser, 0.0));
}

// A 40 x 30 grid of 0.1 m cells with a wall along column 30 (x in [3.0, 3.1)).
OccupancyGrid2D geometry() { return OccupancyGrid2D(0.1, 40, 30); }
BinaryMap2D wall_map() {
  const OccupancyGrid2D g = geometry();
  std::vector<std::uint8_t> occ(40 * 30, 0);
  for (int row = 0; row < 30; ++row) occ[row * 40 + 30] = 1;
  return BinaryMap2D(g, occ);
}

TEST(BeamSensorModel, LaserExpectedRangeIsWhereTheRayEntersTheWall) {
  const BeamSensorModel model(mixture(), BeamShape::kLaser);
  const Eigen::Vector3d pose(0.53, 1.47, 0.1);
  Eigen::VectorXd angles(4);
  angles << -0.3, 0.0, 0.25, kPi;  // the last points away from the wall, off the grid
  const Eigen::VectorXd z = model.expected_ranges(pose, angles, wall_map());
  for (int k = 0; k < 3; ++k) {
    const double a = pose[2] + angles[k];
    const double expected = (3.0 - pose[0]) / std::cos(a);
    EXPECT_NEAR(z[k], expected, 1e-12) << k;
  }
  EXPECT_EQ(z[3], 4.0);  // nothing within max_range
}

TEST(BeamSensorModel, SonarExpectedRangeIsTheNearestOccupiedCentreInTheCone) {
  const double beta = 0.4;
  const BeamSensorModel model(mixture(), BeamShape::kSonar, beta);
  const BinaryMap2D map = wall_map();
  const Eigen::Vector3d pose(1.02, 1.51, -0.2);
  Eigen::VectorXd angles(3);
  angles << 0.2, 0.5, 1.7;
  const Eigen::VectorXd z = model.expected_ranges(pose, angles, map);
  for (int k = 0; k < 3; ++k) {
    double nearest = 4.0;
    for (int row = 0; row < 30; ++row) {
      const double cx = 3.05, cy = 0.05 + 0.1 * row;
      const double r = std::hypot(cx - pose[0], cy - pose[1]);
      const double off = std::fabs(wrap_angle(std::atan2(cy - pose[1], cx - pose[0]) - pose[2] - angles[k]));
      if (off <= beta / 2 && r < nearest) nearest = r;
    }
    EXPECT_DOUBLE_EQ(z[k], nearest) << k;
  }
  EXPECT_EQ(z[2], 4.0);  // the third cone looks up, away from the wall
}

TEST(BeamSensorModel, RejectsNanAndNegativeReadings) {
  const BeamSensorModel model(mixture(), BeamShape::kLaser);
  const Eigen::Vector3d pose(0.5, 1.5, 0.0);
  Eigen::VectorXd angles(2), z(2);
  angles << 0.0, 0.1;
  z << 1.0, NAN;
  expect_invalid([&] { model.log_likelihoods(z, pose, angles, wall_map()); }, "ranges");
  z << -0.5, 1.0;
  expect_invalid([&] { model.log_likelihoods(z, pose, angles, wall_map()); }, "ranges");
  z << std::numeric_limits<double>::infinity(), 1.0;  // a max reading
  EXPECT_TRUE(model.log_likelihoods(z, pose, angles, wall_map()).allFinite());
}

// A small sonar scenario: a robot in a 16 x 12 room of 0.25 m cells with a box inside.
struct Scenario {
  OccupancyGrid2D grid{0.25, 16, 12};
  Poses2 poses;
  RowMatrixXd ranges, angles;
  RowMatrixXd prior;
  BeamSensorModel model{mixture(3.0), BeamShape::kSonar, 0.35};
};

Scenario sonar_scenario() {
  Scenario s;
  std::vector<std::uint8_t> truth(16 * 12, 0);
  for (int c = 0; c < 16; ++c) truth[c] = truth[11 * 16 + c] = 1;
  for (int r = 0; r < 12; ++r) truth[r * 16] = truth[r * 16 + 15] = 1;
  truth[6 * 16 + 9] = truth[6 * 16 + 10] = 1;
  const BinaryMap2D map(s.grid, truth);
  const int T = 6, B = 8;
  s.poses.resize(T, 3);
  s.angles.resize(1, B);
  for (int b = 0; b < B; ++b) s.angles(0, b) = wrap_angle(b * kTwoPi / B);
  s.ranges.resize(T, B);
  std::mt19937_64 rng(7);
  for (int t = 0; t < T; ++t) {
    s.poses.row(t) << 0.9 + 0.35 * t, 1.1 + 0.1 * t, 0.2 * t;
    s.ranges.row(t) = s.model.sample(s.poses.row(t).transpose(), s.angles.row(0).transpose(), map, rng).transpose();
  }
  s.prior = RowMatrixXd::Constant(12, 16, 0.3);
  return s;
}

TEST(MapOccupancyGridMapping, ReachesALocalMaximumCheckedByBruteForce) {
  const Scenario s = sonar_scenario();
  const MapMappingResult r = map_occupancy_grid_mapping(s.grid, s.poses, s.ranges, s.angles, s.model, s.prior);
  ASSERT_TRUE(r.converged);
  EXPECT_GT(r.flips, 0u);
  BinaryMap2D map(s.grid, r.occupied);
  const double best = map_log_posterior(map, s.poses, s.ranges, s.angles, s.model, s.prior);
  // The scorer's running objective against a re-evaluation from scratch: sums of ~50 terms.
  EXPECT_NEAR(r.objective, best, 1e-9 * std::fabs(best));
  for (std::size_t c = 0; c < r.occupied.size(); ++c) {
    map.set(c, !r.occupied[c]);
    const double flipped = map_log_posterior(map, s.poses, s.ranges, s.angles, s.model, s.prior);
    map.set(c, r.occupied[c] != 0);
    EXPECT_LE(flipped - best, MapMappingOptions::kMinGain) << "cell " << c;
    // Fig. 9.8d's sensitivity is that same change.
    EXPECT_NEAR(r.sensitivity[c], flipped - best, 1e-9 * std::fabs(best)) << "cell " << c;
  }
}

TEST(MapOccupancyGridMapping, IncrementalObjectiveMatchesFullReEvaluationAfterEveryFlip) {
  const Scenario s = sonar_scenario();
  MapMappingOptions o;
  o.record_trace = true;
  const MapMappingResult r = map_occupancy_grid_mapping(s.grid, s.poses, s.ranges, s.angles, s.model, s.prior, o);
  ASSERT_EQ(r.trace_cells.size(), r.flips);
  std::vector<std::uint8_t> occ(16 * 12, 0);  // all free: the prior 0.3 leaves unseen cells free
  BinaryMap2D map(s.grid, occ);
  for (std::size_t k = 0; k < r.flips; ++k) {
    const auto c = static_cast<std::size_t>(r.trace_cells[k]);
    map.set(c, !map.occupied(c));
    const double full = map_log_posterior(map, s.poses, s.ranges, s.angles, s.model, s.prior);
    EXPECT_NEAR(r.trace_objective[k], full, 1e-9 * std::fabs(full)) << "flip " << k;
  }
  EXPECT_EQ(map.cells(), r.occupied);
  // The literal scorer makes the same flips.
  o.scoring = FlipScoring::kFull;
  const MapMappingResult f = map_occupancy_grid_mapping(s.grid, s.poses, s.ranges, s.angles, s.model, s.prior, o);
  EXPECT_EQ(f.trace_cells, r.trace_cells);
  EXPECT_EQ(f.occupied, r.occupied);
}

TEST(MapOccupancyGridMapping, RejectsBadInput) {
  const Scenario s = sonar_scenario();
  const auto run = [&](const Poses2& poses, const RowMatrixXd& ranges, const RowMatrixXd& angles, const RowMatrixXd& prior) {
    map_occupancy_grid_mapping(s.grid, poses, ranges, angles, s.model, prior);
  };
  expect_invalid([&] { run(s.poses.topRows(5), s.ranges, s.angles, s.prior); }, "scans");
  RowMatrixXd bad = s.ranges;
  bad(2, 3) = NAN;
  expect_invalid([&] { run(s.poses, bad, s.angles, s.prior); }, "scans");
  expect_invalid([&] { run(s.poses, s.ranges, s.angles.leftCols(5), s.prior); }, "beam_angles");
  expect_invalid([&] { run(s.poses, s.ranges, s.angles, RowMatrixXd::Constant(12, 16, 1.0)); }, "prior");
  expect_invalid([&] { run(s.poses, s.ranges, s.angles, RowMatrixXd::Constant(3, 3, 0.3)); }, "prior");
  BeamMixture no_rand = mixture(3.0);
  no_rand.z_hit += no_rand.z_rand;
  no_rand.z_rand = 0.0;
  const BeamSensorModel m(no_rand, BeamShape::kSonar, 0.35);
  expect_invalid([&] { map_occupancy_grid_mapping(s.grid, s.poses, s.ranges, s.angles, m, s.prior); }, "z_rand");
}

// beam_footprint_visits bounds the work before it starts: it must never be below the cells the
// footprint really holds (lasers, and sonar cones of any width, on and off the grid).
TEST(BeamFootprint, VisitsBoundTheFootprint) {
  const OccupancyGrid2D grid(0.1, 50, 40);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> x(-1.0, 6.0), y(-1.0, 5.0), a(-kPi, kPi), beta(0.01, kTwoPi);
  std::vector<FootprintCell> cells;
  for (int k = 0; k < 400; ++k) {
    const Eigen::Vector3d pose(x(rng), y(rng), a(rng));
    const BeamGeometry g =
        k % 2 ? BeamGeometry{BeamShape::kLaser, 3.0, 0.0} : BeamGeometry{BeamShape::kSonar, 3.0, beta(rng)};
    const double angle = a(rng);
    beam_footprint(grid.lattice(), grid.width(), grid.height(), pose, angle, g, cells);
    EXPECT_GE(beam_footprint_visits(grid.lattice(), grid.width(), grid.height(), pose, angle, g),
              static_cast<double>(cells.size())) << k;
  }
}

TEST(BeamFootprint, AWholeDiscSonarOverALargeGridIsRefusedBeforeTheWork) {
  const OccupancyGrid2D grid(0.05, 4000, 4000);
  const BinaryMap2D map(grid, std::vector<std::uint8_t>(4000u * 4000u, 0));
  BeamMixture m = mixture(200.0);
  const BeamSensorModel sonar(m, BeamShape::kSonar, kTwoPi);
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(1000, -3.0, 3.0);
  expect_invalid([&] { sonar.expected_ranges(Eigen::Vector3d(100.0, 100.0, 0.0), angles, map); }, "beam_angles");
  const Poses2 poses = Eigen::RowVector3d(100.0, 100.0, 0.0);
  const RowMatrixXd ranges = RowMatrixXd::Constant(1, 1000, 5.0);
  const RowMatrixXd prior = RowMatrixXd::Constant(4000, 4000, 0.3);
  expect_invalid([&] { map_occupancy_grid_mapping(grid, poses, ranges, angles.transpose(), sonar, prior); }, "scans");
}

// The interrupt hook is called during the climb, and what it throws leaves the call.
TEST(MapOccupancyGridMapping, InterruptHookStopsTheClimb) {
  const Scenario s = sonar_scenario();
  struct Stop {};
  for (const FlipScoring scoring : {FlipScoring::kIncremental, FlipScoring::kFull}) {
    MapMappingOptions o;
    o.scoring = scoring;
    int calls = 0;
    o.interrupt = [&] {
      if (++calls == 2) throw Stop{};
    };
    EXPECT_THROW(map_occupancy_grid_mapping(s.grid, s.poses, s.ranges, s.angles, s.model, s.prior, o), Stop);
    EXPECT_EQ(calls, 2);
    o.interrupt = [&] { ++calls; };
    calls = 0;
    const MapMappingResult r = map_occupancy_grid_mapping(s.grid, s.poses, s.ranges, s.angles, s.model, s.prior, o);
    EXPECT_GT(calls, 0);
    EXPECT_TRUE(r.converged);
  }
}

}  // namespace
}  // namespace probslam
