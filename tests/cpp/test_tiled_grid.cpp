// TiledGrid2D: the copy-on-write tiled grid of grid-based FastSLAM against dense OccupancyGrid2D
// references (same rules, bit for bit) and deep copies (no aliasing between particles).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <thread>
#include <vector>

#include "probslam/fastslam/tiled_grid_2d.hpp"
#include "test_support.hpp"

namespace probslam {
namespace {

using test_support::expect_invalid;

// 100 x 70 cells of 0.1 m: tiles of 32 cells leave partial tiles on both axes.
OccupancyGrid2D prototype() { return OccupancyGrid2D(0.1, 100, 70, Eigen::Vector2d(-3.0, -2.0)); }

struct Scan {
  Eigen::Vector3d pose;
  Eigen::VectorXd ranges, angles;
  double max_range;
};

// A random scan from a pose inside (or just outside) the grid, with invalid readings, readings
// at and beyond the maximum and rays that leave the grid.
Scan random_scan(std::mt19937& rng) {
  std::uniform_real_distribution<double> ux(-4.0, 8.0), uy(-3.0, 6.0), ua(-M_PI, M_PI), ur(0.0, 9.0);
  std::uniform_int_distribution<int> kind(0, 19);
  Scan s;
  s.pose = {ux(rng), uy(rng), ua(rng)};
  s.max_range = 6.0;
  const int n = 60;
  s.ranges.resize(n);
  s.angles.resize(n);
  for (int i = 0; i < n; ++i) {
    s.angles[i] = -M_PI + 2.0 * M_PI * i / n;
    switch (kind(rng)) {
      case 0: s.ranges[i] = std::numeric_limits<double>::quiet_NaN(); break;
      case 1: s.ranges[i] = std::numeric_limits<double>::infinity(); break;
      case 2: s.ranges[i] = -1.0; break;
      case 3: s.ranges[i] = s.max_range; break;
      case 4: s.ranges[i] = 1e200; break;
      default: s.ranges[i] = ur(rng);
    }
  }
  return s;
}

void expect_same_cells(const TiledGrid2D& tiled, const OccupancyGrid2D& dense) {
  const OccupancyGrid2D g = tiled.to_grid();
  ASSERT_TRUE(g.same_geometry(dense));
  for (int r = 0; r < dense.height(); ++r)
    for (int c = 0; c < dense.width(); ++c) {
      const double want = dense.log_odds()(r, c);
      ASSERT_EQ(tiled.log_odds(r, c), want) << "cell " << r << ", " << c;
      ASSERT_EQ(g.log_odds()(r, c), want);
    }
}

TEST(TiledGrid2D, InsertRaysEqualsTheDenseGridBitForBit) {
  std::mt19937 rng(7);
  OccupancyGrid2D dense = prototype();
  TiledGrid2D tiled(dense);
  EXPECT_EQ(tiled.tiles_allocated(), 0u);
  EXPECT_EQ(tiled.tiles_x(), 4);
  EXPECT_EQ(tiled.tiles_y(), 3);
  for (int k = 0; k < 40; ++k) {
    const Scan s = random_scan(rng);
    EXPECT_EQ(tiled.insert_rays(s.pose, s.ranges, s.angles, s.max_range),
              dense.insert_rays(s.pose, s.ranges, s.angles, s.max_range));
  }
  expect_same_cells(tiled, dense);
  EXPECT_GT(tiled.tiles_allocated(), 0u);
}

TEST(TiledGrid2D, PrototypeCellsAreKeptAndOnlyTheirTilesAllocated) {
  OccupancyGrid2D dense = prototype();
  dense.log_odds()(5, 40) = 1.5;  // tile (0, 1)
  dense.log_odds()(69, 99) = -0.7;  // the last, partial tile
  TiledGrid2D tiled(dense);
  EXPECT_EQ(tiled.tiles_allocated(), 2u);
  expect_same_cells(tiled, dense);
}

// Particles, resampled and updated at random, against deep copies: no grid ever shows another
// grid's change, whatever the order of copies and updates.
TEST(TiledGrid2D, RandomResamplingAndUpdatesNeverAlias) {
  std::mt19937 rng(11);
  const int m = 6;
  std::vector<OccupancyGrid2D> dense(m, prototype());
  std::vector<TiledGrid2D> tiled(m, TiledGrid2D(prototype()));
  std::uniform_int_distribution<int> pick(0, m - 1), op(0, 2);
  for (int step = 0; step < 120; ++step) {
    switch (op(rng)) {
      case 0: {  // one particle's update
        const int i = pick(rng);
        const Scan s = random_scan(rng);
        tiled[i].insert_rays(s.pose, s.ranges, s.angles, s.max_range);
        dense[i].insert_rays(s.pose, s.ranges, s.angles, s.max_range);
        break;
      }
      case 1: {  // resampling: a random ancestor for every particle
        std::vector<int> parent(m);
        for (int& p : parent) p = pick(rng);
        std::vector<OccupancyGrid2D> d;
        std::vector<TiledGrid2D> t;
        for (int p : parent) {
          d.push_back(dense[p]);
          t.push_back(tiled[p]);
        }
        dense = std::move(d);
        tiled = std::move(t);
        break;
      }
      default: {  // one particle copied over another, then both updated
        const int i = pick(rng), j = pick(rng);
        tiled[j] = tiled[i];
        dense[j] = dense[i];
        for (int k : {i, j}) {
          const Scan s = random_scan(rng);
          tiled[k].insert_rays(s.pose, s.ranges, s.angles, s.max_range);
          dense[k].insert_rays(s.pose, s.ranges, s.angles, s.max_range);
        }
      }
    }
    for (int i = 0; i < m; ++i) expect_same_cells(tiled[i], dense[i]);
  }
}

TEST(TiledGrid2D, CopyingSharesEveryTileAndAnUpdateClonesOnlyTheTilesItTouches) {
  std::mt19937 rng(3);
  TiledGrid2D a(prototype());
  for (int k = 0; k < 20; ++k) {
    const Scan s = random_scan(rng);
    a.insert_rays(s.pose, s.ranges, s.angles, s.max_range);
  }
  const std::size_t held = a.tiles_allocated();
  ASSERT_GT(held, 3u);
  TiledGrid2D b = a;
  TileSharing s = TiledGrid2D::sharing({&a, &b});
  EXPECT_EQ(s.references, 2 * held);
  EXPECT_EQ(s.distinct, held);  // the copy allocated no tile, copied no cell
  EXPECT_EQ(s.bytes, held * sizeof(TiledGrid2D::Tile));

  // One short ray from the centre of tile (1, 1): only that tile is cloned.
  const double res = a.resolution();
  const Eigen::Vector2d centre = a.origin() + Eigen::Vector2d(48.5 * res, 48.5 * res);
  Eigen::VectorXd range(1), angle(1);
  range << 0.5;
  angle << 0.0;
  b.insert_rays(Eigen::Vector3d(centre.x(), centre.y(), 0.0), range, angle, 10.0);
  s = TiledGrid2D::sharing({&a, &b});
  const std::size_t touched = static_cast<std::size_t>(1 * a.tiles_x() + 1);
  EXPECT_EQ(s.distinct, held + 1);  // a clone of a's tile, or a new one where a has none
  for (std::size_t t = 0; t < static_cast<std::size_t>(a.tiles_x() * a.tiles_y()); ++t)
    if (t != touched && a.shares_tile(a, t)) {
      EXPECT_TRUE(a.shares_tile(b, t)) << "tile " << t;
    }
  EXPECT_FALSE(a.shares_tile(b, touched));
}

TEST(TiledGrid2D, BadInputRaisesAndChangesNothing) {
  TiledGrid2D g(prototype());
  Eigen::VectorXd r = Eigen::VectorXd::Constant(3, 1.0), a = Eigen::VectorXd::LinSpaced(3, -1.0, 1.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  expect_invalid([&] { g.insert_rays(Eigen::Vector3d(nan, 0, 0), r, a, 5.0); }, "pose");
  expect_invalid([&] { g.insert_rays(Eigen::Vector3d::Zero(), r, Eigen::VectorXd::Zero(2), 5.0); }, "beam_angles");
  expect_invalid([&] { g.insert_rays(Eigen::Vector3d::Zero(), Eigen::VectorXd(0), Eigen::VectorXd(0), 5.0); }, "ranges");
  expect_invalid([&] { g.insert_rays(Eigen::Vector3d::Zero(), r, a, 0.0); }, "max_range");
  expect_invalid([&] { g.insert_rays(Eigen::Vector3d::Zero(), r, a, nan); }, "max_range");
  Eigen::VectorXd bad_angles = a;
  bad_angles[1] = nan;
  expect_invalid([&] { g.insert_rays(Eigen::Vector3d::Zero(), r, bad_angles, 5.0); }, "beam_angles");
  EXPECT_EQ(g.tiles_allocated(), 0u);
  expect_invalid([&] { TiledGrid2D::sharing({&g, nullptr}); }, "grids");
}

// Particles that share tiles, updated on two threads at once (the filter's parallel step):
// each ends as it would alone.
TEST(TiledGrid2D, ConcurrentUpdatesOfGridsSharingTiles) {
  std::mt19937 rng(5);
  TiledGrid2D base(prototype());
  for (int k = 0; k < 10; ++k) {
    const Scan s = random_scan(rng);
    base.insert_rays(s.pose, s.ranges, s.angles, s.max_range);
  }
  std::vector<std::vector<Scan>> scans(4);
  for (auto& list : scans)
    for (int k = 0; k < 15; ++k) list.push_back(random_scan(rng));
  std::vector<TiledGrid2D> sequential(4, base), parallel(4, base);
  for (int i = 0; i < 4; ++i)
    for (const Scan& s : scans[i]) sequential[i].insert_rays(s.pose, s.ranges, s.angles, s.max_range);
  auto work = [&](int first) {
    for (int i = first; i < 4; i += 2)
      for (const Scan& s : scans[i]) parallel[i].insert_rays(s.pose, s.ranges, s.angles, s.max_range);
  };
  std::thread t0(work, 0), t1(work, 1);
  t0.join();
  t1.join();
  for (int i = 0; i < 4; ++i) expect_same_cells(parallel[i], sequential[i].to_grid());
}

}  // namespace
}  // namespace probslam
