// TiledGrid2D: the copy-on-write tiled grid of grid-based FastSLAM against dense OccupancyGrid2D
// references (same rules, bit for bit) and deep copies (no aliasing between particles).
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <thread>
#include <vector>

#include "probslam/core/angle.hpp"
#include "probslam/grid/log_odds.hpp"
#include "probslam/fastslam/grid_fast_slam.hpp"
#include "probslam/fastslam/scan_proposal.hpp"
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

// n random scans inserted into g, one after another.
void insert_random_scans(TiledGrid2D& g, std::mt19937& rng, int n) {
  for (int k = 0; k < n; ++k) {
    const Scan s = random_scan(rng);
    g.insert_rays(s.pose, s.ranges, s.angles, s.max_range);
  }
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
  insert_random_scans(a, rng, 20);
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

TEST(TiledGrid2D, DeepCopySharesNothingWithTheOriginalsAndKeepsTheirSharing) {
  std::mt19937 rng(5);
  auto a = std::make_shared<TiledGrid2D>(prototype());
  insert_random_scans(*a, rng, 20);
  auto b = std::make_shared<TiledGrid2D>(*a);  // shares every tile of a
  const Scan extra = random_scan(rng);
  b->insert_rays(extra.pose, extra.ranges, extra.angles, extra.max_range);  // clones a few
  const std::int64_t live_before = a->live_tiles();

  // a listed twice (two particles holding one grid), a null slot (a particle before its first scan).
  const std::vector<std::shared_ptr<TiledGrid2D>> copies = TiledGrid2D::deep_copy({a, b, a, nullptr});
  ASSERT_EQ(copies.size(), 4u);
  EXPECT_EQ(copies[0], copies[2]);
  EXPECT_EQ(copies[3], nullptr);
  const TiledGrid2D &ca = *copies[0], &cb = *copies[1];
  expect_same_cells(ca, a->to_grid());
  expect_same_cells(cb, b->to_grid());
  const auto slots = static_cast<std::size_t>(a->tiles_x() * a->tiles_y());
  for (std::size_t t = 0; t < slots; ++t) {
    EXPECT_FALSE(ca.shares_tile(*a, t) || ca.shares_tile(*b, t) || cb.shares_tile(*a, t) || cb.shares_tile(*b, t))
        << "tile " << t;
    EXPECT_EQ(ca.shares_tile(cb, t), a->shares_tile(*b, t)) << "tile " << t;
  }
  // The copies count their own tiles: the distinct tiles of the two grids, and the originals' count
  // is unchanged.
  EXPECT_EQ(static_cast<std::size_t>(ca.live_tiles()), TiledGrid2D::sharing({a.get(), b.get()}).distinct);
  EXPECT_EQ(a->live_tiles(), live_before);
  // Writing to a copy leaves the originals alone.
  const OccupancyGrid2D before = a->to_grid();
  copies[0]->insert_rays(extra.pose, extra.ranges, extra.angles, extra.max_range);
  expect_same_cells(*a, before);
}

TEST(TiledGrid2D, GrowingKeepsCellsAndSharingAndMatchesTheDenseGrid) {
  std::mt19937 rng(9);
  OccupancyGrid2D dense = prototype();
  TiledGrid2D a(dense);
  for (int k = 0; k < 10; ++k) {
    const Scan s = random_scan(rng);
    a.insert_rays(s.pose, s.ranges, s.angles, s.max_range);
    dense.insert_rays(s.pose, s.ranges, s.angles, s.max_range);
  }
  TiledGrid2D b = a;
  const std::size_t held = a.tiles_allocated();
  b.grow_to_include(-12.0, -9.5, 15.0, 11.0);
  EXPECT_LE(b.origin().x(), -12.0);
  EXPECT_LE(b.origin().y(), -9.5);
  EXPECT_GE(b.origin().x() + b.width() * b.resolution(), 15.0);
  EXPECT_GE(b.origin().y() + b.height() * b.resolution(), 11.0);
  EXPECT_EQ(TiledGrid2D::sharing({&a, &b}).distinct, held);  // no tile copied
  // Same cells at the same coordinates; then both take the same scans as a dense grid grown alike.
  OccupancyGrid2D big = dense.grown_to_include(b.origin().x() + 1e-9, b.origin().y() + 1e-9,
                                               b.origin().x() + (b.width() - 0.5) * b.resolution(),
                                               b.origin().y() + (b.height() - 0.5) * b.resolution());
  ASSERT_EQ(big.width(), b.width());
  ASSERT_EQ(big.height(), b.height());
  ASSERT_LT((big.origin() - b.origin()).norm(), 1e-9);
  for (int k = 0; k < 10; ++k) {
    Scan s = random_scan(rng);
    s.pose.head<2>() *= 2.0;
    b.insert_rays(s.pose, s.ranges, s.angles, s.max_range);
    big.insert_rays(s.pose, s.ranges, s.angles, s.max_range);
  }
  expect_same_cells(b, big);
  expect_same_cells(a, dense);  // the original is untouched
  expect_invalid([&] { b.grow_to_include(-1e12, 0, 1e12, 1); }, "xmax");
  expect_invalid([&] { b.grow_to_include(std::nan(""), 0, 1, 1); }, "xmin");
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
  insert_random_scans(base, rng, 10);
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


// --- the measurement likelihood and the improved proposal -------------------------------------

// A 8 x 6 m room (0.05 m cells) with a pillar, mapped by noise-free scans from a few poses.
struct Room {
  OccupancyGrid2D dense = OccupancyGrid2D(0.05, 200, 160, Eigen::Vector2d(-1.0, -1.0));
  Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(181, -M_PI / 2, M_PI / 2);

  // Range to the walls x in [0, 8], y in [0, 6] and the pillar [5, 5.6] x [2, 2.6] (ray casting).
  double cast(const Eigen::Vector3d& pose, double a) const {
    const double dx = std::cos(pose.z() + a), dy = std::sin(pose.z() + a);
    double t = std::numeric_limits<double>::infinity();
    auto slab = [&](double x0, double x1, double y0, double y1, bool inside) {
      // Exit (inside) or entry (outside) distance of an axis-aligned box.
      double lo = 0.0, hi = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 2; ++k) {
        const double o = k == 0 ? pose.x() : pose.y(), d = k == 0 ? dx : dy;
        const double a0 = k == 0 ? x0 : y0, a1 = k == 0 ? x1 : y1;
        if (std::fabs(d) < 1e-12) {
          if (o < a0 || o > a1) return;
          continue;
        }
        double t0 = (a0 - o) / d, t1 = (a1 - o) / d;
        if (t0 > t1) std::swap(t0, t1);
        lo = std::max(lo, t0);
        hi = std::min(hi, t1);
      }
      if (lo <= hi) t = std::min(t, inside ? hi : (lo > 0 ? lo : t));
    };
    slab(0.0, 8.0, 0.0, 6.0, true);
    slab(5.0, 5.6, 2.0, 2.6, false);
    return t;
  }
  Eigen::VectorXd scan(const Eigen::Vector3d& pose) const {
    Eigen::VectorXd r(angles.size());
    for (Eigen::Index i = 0; i < r.size(); ++i) r[i] = cast(pose, angles[i]);
    return r;
  }
  Points2 points(const Eigen::Vector3d& pose) const {
    const Eigen::VectorXd r = scan(pose);
    Points2 p(r.size(), 2);
    for (Eigen::Index i = 0; i < r.size(); ++i) p.row(i) << r[i] * std::cos(angles[i]), r[i] * std::sin(angles[i]);
    return p;
  }
  TiledGrid2D mapped() const {
    TiledGrid2D g(dense);
    for (const Eigen::Vector3d& x : {Eigen::Vector3d(2, 3, 0), Eigen::Vector3d(4, 1.5, 1.2), Eigen::Vector3d(6, 4.5, -2.5),
                                     Eigen::Vector3d(3, 4, 3.0), Eigen::Vector3d(7, 1, 2.2)})
      for (int k = 0; k < 3; ++k) g.insert_rays(x, scan(x), angles, 20.0);
    return g;
  }
};

// Brute force: the nearest occupied cell centre over the whole grid, for every point.
double brute_force_log_likelihood(const TiledGrid2D& g, const EndpointLikelihoodOptions& o, const Eigen::Vector3d& pose,
                                  const Points2& pts) {
  double sum = 0.0;
  for (Eigen::Index i = 0; i < pts.rows(); ++i) {
    const double x = pose.x() + std::cos(pose.z()) * pts(i, 0) - std::sin(pose.z()) * pts(i, 1);
    const double y = pose.y() + std::sin(pose.z()) * pts(i, 0) + std::cos(pose.z()) * pts(i, 1);
    double best = std::numeric_limits<double>::infinity();
    for (int r = 0; r < g.height(); ++r)
      for (int c = 0; c < g.width(); ++c)
        if (g.log_odds(r, c) > logit(o.occupied_threshold)) {
          const double cx = g.origin().x() + (c + 0.5) * g.resolution(), cy = g.origin().y() + (r + 0.5) * g.resolution();
          best = std::min(best, (x - cx) * (x - cx) + (y - cy) * (y - cy));
        }
    sum += best <= o.search_radius * o.search_radius
               ? std::log((1 - o.p_rand) * std::exp(-best / (2 * o.sigma * o.sigma)) + o.p_rand)
               : std::log(o.p_rand);
  }
  return sum;
}

TEST(EndpointLikelihood, EqualsABruteForceNearestObstacleSearch) {
  // The search against the whole grid's nearest occupied cell; the memo (one over many poses
  // around each truth, cells met again and again as in a climb, and over two grids in turn: a
  // memo that sees another grid starts afresh) against the search, bit for bit, quality too.
  const Room room;
  const TiledGrid2D g = room.mapped();
  TiledGrid2D other = g;
  const Eigen::Vector3d elsewhere(4.5, 4.5, 0.7);
  const Eigen::VectorXd shorter = 0.8 * room.scan(elsewhere);  // obstacles where g has none
  other.insert_rays(elsewhere, shorter, room.angles, 20.0);
  std::mt19937 rng(2);
  std::normal_distribution<double> n(0.0, 0.08);
  for (double radius : {0.0, 0.12, 0.3}) {
    EndpointLikelihoodOptions o;
    o.search_radius = radius;
    const EndpointLikelihood lik(o, g.resolution());
    EndpointLikelihood::Memo memo;
    for (int k = 0; k < 5; ++k) {
      const Eigen::Vector3d truth(2.0 + k, 2.5, 0.4 * k);
      const Points2 pts = room.points(truth);
      const Eigen::Vector3d pose = truth + Eigen::Vector3d(n(rng), n(rng), n(rng));
      EXPECT_NEAR(lik.log_likelihood(g, pose, pts), brute_force_log_likelihood(g, o, pose, pts), 1e-9)
          << "radius " << radius << " pose " << k;
      for (const TiledGrid2D* grid : {&g, static_cast<const TiledGrid2D*>(&other)})
        for (int j = 0; j < 30; ++j) {
          const Eigen::Vector3d near = truth + 0.6 * Eigen::Vector3d(n(rng), n(rng), n(rng));
          double q_search = 0.0, q_memo = 0.0;
          const double search = lik.log_likelihood(*grid, near, pts, &q_search);
          EXPECT_EQ(lik.log_likelihood(*grid, near, pts, memo, &q_memo), search) << "radius " << radius;
          EXPECT_EQ(q_memo, q_search);
        }
    }
  }
}

// Brute force of the derivatives: each point's nearest occupied centre over the whole grid, its
// hit probability w and Jacobian J = d(end point)/d(x, y, theta): gradient -sum w / sigma^2 J^T e,
// information sum w / sigma^2 J^T J (e = end point - centre).
void brute_force_derivatives(const TiledGrid2D& g, const EndpointLikelihoodOptions& o, const Eigen::Vector3d& pose,
                             const Points2& pts, Eigen::Vector3d& gradient, Eigen::Matrix3d& information) {
  gradient.setZero();
  information.setZero();
  for (Eigen::Index i = 0; i < pts.rows(); ++i) {
    const Eigen::Vector2d r(std::cos(pose.z()) * pts(i, 0) - std::sin(pose.z()) * pts(i, 1),
                            std::sin(pose.z()) * pts(i, 0) + std::cos(pose.z()) * pts(i, 1));
    const Eigen::Vector2d p = pose.head<2>() + r;
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector2d e;
    for (int row = 0; row < g.height(); ++row)
      for (int c = 0; c < g.width(); ++c)
        if (g.log_odds(row, c) > logit(o.occupied_threshold)) {
          const Eigen::Vector2d centre = g.origin() + g.resolution() * Eigen::Vector2d(c + 0.5, row + 0.5);
          if ((p - centre).squaredNorm() < best) best = (p - centre).squaredNorm(), e = p - centre;
        }
    if (!(best <= o.search_radius * o.search_radius)) continue;
    const double h = std::exp(-best / (2 * o.sigma * o.sigma));
    const double w = (1 - o.p_rand) * h / ((1 - o.p_rand) * h + o.p_rand) / (o.sigma * o.sigma);
    Eigen::Matrix<double, 2, 3> J;
    J << 1, 0, -r.y(), 0, 1, r.x();
    gradient -= w * J.transpose() * e;
    information += w * J.transpose() * J;
  }
}

TEST(EndpointLikelihood, DerivativesAgainstBruteForceAndFiniteDifferences) {
  // The memo pass with derivatives: its value is the plain pass's bit for bit; gradient and
  // information equal the brute force's; the gradient equals central differences of the log
  // likelihood (the search's, equal to the brute force's; a step far below a cell: no point
  // changes its nearest cell).
  const Room room;
  const TiledGrid2D g = room.mapped();
  const EndpointLikelihoodOptions o;
  const EndpointLikelihood lik(o, g.resolution());
  EndpointLikelihood::Memo memo;
  std::mt19937 rng(4);
  std::normal_distribution<double> n(0.0, 0.03);
  constexpr double kStep = 1e-6;  // m and rad
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d truth(2.0 + 1.5 * k, 2.0 + 0.6 * k, 0.5 * k - 0.7);
    const Points2 pts = room.points(truth);
    const Eigen::Vector3d pose = truth + Eigen::Vector3d(n(rng), n(rng), n(rng));
    EndpointLikelihood::Derivatives d;
    double q = 0.0, q_plain = 0.0;
    EXPECT_EQ(lik.log_likelihood(g, pose, pts, memo, d, &q), lik.log_likelihood(g, pose, pts, &q_plain));
    EXPECT_EQ(q, q_plain);
    Eigen::Vector3d gradient;
    Eigen::Matrix3d information;
    brute_force_derivatives(g, o, pose, pts, gradient, information);
    EXPECT_LT((d.gradient - gradient).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + gradient.cwiseAbs().maxCoeff())) << k;
    EXPECT_LT((d.information - information).cwiseAbs().maxCoeff(), 1e-9 * information.cwiseAbs().maxCoeff()) << k;
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector3d h = kStep * Eigen::Vector3d::Unit(a);
      const double fd = (lik.log_likelihood(g, pose + h, pts) - lik.log_likelihood(g, pose - h, pts)) / (2 * kStep);
      EXPECT_NEAR(d.gradient[a], fd, 1e-4 * (1.0 + std::fabs(fd))) << "pose " << k << " axis " << a;
    }
  }
}

TEST(EndpointLikelihood, BadOptionsAreRefusedByName) {
  auto with = [](auto set) {
    EndpointLikelihoodOptions o;
    set(o);
    return o;
  };
  expect_invalid([&] { EndpointLikelihood(with([](auto& o) { o.sigma = 0; }), 0.05); }, "sigma");
  expect_invalid([&] { EndpointLikelihood(with([](auto& o) { o.p_rand = 1.0; }), 0.05); }, "p_rand");
  expect_invalid([&] { EndpointLikelihood(with([](auto& o) { o.search_radius = -1; }), 0.05); }, "search_radius");
  expect_invalid([&] { EndpointLikelihood(with([](auto& o) { o.search_radius = 1e9; }), 0.05); }, "search_radius");
  expect_invalid([&] { EndpointLikelihood(EndpointLikelihoodOptions{}, 0.0); }, "resolution");
}

TEST(ScanProposal, LogGaussianPoseIsTheNormalDensity) {
  const Eigen::Vector3d prior(1.0, -2.0, 3.1);
  Eigen::Matrix3d cov;
  cov << 0.04, 0.01, 0.0, 0.01, 0.09, 0.002, 0.0, 0.002, 0.01;
  const Eigen::Vector3d x(1.1, -2.2, -3.1);  // heading across the +-pi seam
  const Eigen::Vector3d d(0.1, -0.2, wrap_angle(-3.1 - 3.1));
  const double want = -0.5 * (d.dot(cov.inverse() * d) + std::log(std::pow(2 * M_PI, 3) * cov.determinant()));
  EXPECT_NEAR(log_gaussian_pose(x, prior, cov), want, 1e-12);
}

namespace {
using PoseRows = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// The 27 poses of the proposal's grid around `centre`, the centre first.
PoseRows laplace_grid(const Eigen::Vector3d& centre, const Eigen::Vector3d& spacing) {
  PoseRows x(27, 3);
  int k = 0;
  for (int i : {0, -1, 1})
    for (int j : {0, -1, 1})
      for (int a : {0, -1, 1})
        x.row(k++) << centre.x() + i * spacing.x(), centre.y() + j * spacing.y(), wrap_angle(centre.z() + a * spacing.z());
  return x;
}

/// log N(d; 0, cov) for an offset d.
double log_normal(const Eigen::Vector3d& d, const Eigen::Matrix3d& cov) {
  return -0.5 * (d.dot(cov.inverse() * d) + std::log(std::pow(2 * M_PI, 3) * cov.determinant()));
}
}  // namespace

TEST(ScanProposal, LaplaceFitOfAGaussianProductIsExact) {
  // s = log N(x; mu_z, S_z) + log N(x; mu_p, S_p) is a quadratic: the fit must return the
  // product's Gaussian, (S_z^-1 + S_p^-1)^-1 and its mean, and the integral N(mu_z; mu_p, S_z + S_p).
  const Eigen::Vector3d spacing(0.01, 0.01, 0.005);
  const Eigen::Vector3d centre(3.0, -1.0, M_PI - 0.002);  // the grid straddles the +-pi seam
  Eigen::Matrix3d Sz, Sp;
  Sz << 4e-5, 1e-5, 0.0, 1e-5, 9e-5, 2e-6, 0.0, 2e-6, 1e-5;
  Sp << 4e-4, -5e-5, 1e-5, -5e-5, 2e-4, 0.0, 1e-5, 0.0, 1e-4;
  const Eigen::Vector3d mu_z = centre + Eigen::Vector3d(0.003, -0.002, 0.001);
  const Eigen::Vector3d mu_p = centre + Eigen::Vector3d(-0.02, 0.03, -0.01);
  auto off = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return Eigen::Vector3d(a.x() - b.x(), a.y() - b.y(), wrap_angle(a.z() - b.z()));
  };
  const PoseRows x = laplace_grid(centre, spacing);
  Eigen::VectorXd s(27);
  for (int j = 0; j < 27; ++j) {
    const Eigen::Vector3d xj = x.row(j).transpose();
    s[j] = 700.0 + log_normal(off(xj, mu_z), Sz) + log_normal(off(xj, mu_p), Sp);  // large: no underflow either
  }
  Eigen::Vector3d mean;
  Eigen::Matrix3d cov;
  const double log_z = fit_pose_laplace(x, s, spacing, Sp.inverse(), mean, cov);
  const Eigen::Matrix3d want_cov = (Sz.inverse() + Sp.inverse()).inverse();
  const Eigen::Vector3d want_mean = centre + want_cov * (Sz.inverse() * off(mu_z, centre) + Sp.inverse() * off(mu_p, centre));
  EXPECT_LT((cov - want_cov).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT(off(mean, want_mean).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(log_z, 700.0 + log_normal(off(mu_z, mu_p), Sz + Sp), 1e-6);
}

TEST(ScanProposal, LaplaceFitGivesAFlatMeasurementDirectionThePriorsWidth) {
  // A corridor: the measurement constrains y and the heading, not x. Along x the proposal must be
  // as wide as the motion prior (a scatter of poses 1 cm apart would say 1 cm); a measurement
  // term that curves upwards (not a peak) adds nothing either.
  const Eigen::Vector3d spacing(0.01, 0.01, 0.005), centre(1.0, 2.0, 0.5);
  const Eigen::Matrix3d Sp = Eigen::Vector3d(0.05 * 0.05, 0.04 * 0.04, 0.02 * 0.02).asDiagonal();
  const PoseRows x = laplace_grid(centre, spacing);
  for (double along : {0.0, 3e3}) {  // flat, then convex along x
    Eigen::VectorXd s(27);
    for (int j = 0; j < 27; ++j) {
      const Eigen::Vector3d d = x.row(j).transpose() - centre;
      s[j] = 0.5 * along * d.x() * d.x() - 0.5 * (d.y() * d.y() / 1e-6 + d.z() * d.z() / 1e-6) +
             log_normal(d, Sp);  // the prior centred on the grid
    }
    Eigen::Vector3d mean;
    Eigen::Matrix3d cov;
    fit_pose_laplace(x, s, spacing, Sp.inverse(), mean, cov);
    EXPECT_NEAR(cov(0, 0), Sp(0, 0), 1e-9) << along;
    EXPECT_NEAR(cov(1, 1), 1.0 / (1e6 + 1.0 / Sp(1, 1)), 1e-12);
    EXPECT_LT((mean - centre).norm(), 1e-9);
  }
  Eigen::Vector3d mean;
  Eigen::Matrix3d cov;
  expect_invalid([&] { fit_pose_laplace(x.topRows(26), Eigen::VectorXd::Zero(26), spacing, Sp.inverse(), mean, cov); },
                 "log_scores");
  expect_invalid([&] { fit_pose_laplace(x, Eigen::VectorXd::Zero(27), -spacing, Sp.inverse(), mean, cov); }, "spacing");
}

TEST(ScanProposal, FindsTheTruePoseAndFitsItsOwnSamples) {
  const Room room;
  const TiledGrid2D g = room.mapped();
  const EndpointLikelihood lik(EndpointLikelihoodOptions{}, g.resolution());
  const ScanProposalOptions opt;
  Eigen::Matrix3d prior_cov = Eigen::Vector3d(0.1 * 0.1, 0.1 * 0.1, 0.05 * 0.05).asDiagonal();
  for (const Eigen::Vector3d& truth : {Eigen::Vector3d(2.5, 2.0, 0.3), Eigen::Vector3d(6.0, 3.5, -2.0)}) {
    const Points2 pts = room.points(truth);
    const Eigen::Vector3d prior = truth + Eigen::Vector3d(0.07, -0.06, 0.03);
    const ScanProposal p = scan_matching_proposal(lik, g, pts, prior, prior_cov, opt);
    ASSERT_TRUE(p.matched) << p.quality;
    EXPECT_LT((p.mode.head<2>() - truth.head<2>()).norm(), 0.05);  // within a cell
    EXPECT_LT(std::fabs(wrap_angle(p.mode.z() - truth.z())), 0.02);
    ASSERT_EQ(p.samples.rows(), 27);
    for (int j = 0; j < 27; ++j) {
      const Eigen::Vector3d xj = p.samples.row(j).transpose();
      EXPECT_NEAR(p.log_scores[j], lik.log_likelihood(g, xj, pts) + log_gaussian_pose(xj, prior, prior_cov), 1e-9);
    }
    Eigen::Vector3d mean;
    Eigen::Matrix3d cov;
    const Eigen::Vector3d spacing(opt.sample_linear, opt.sample_linear, opt.sample_angular);
    EXPECT_NEAR(fit_pose_laplace(p.samples, p.log_scores, spacing, prior_cov.inverse(), mean, cov), p.log_normaliser, 1e-9);
    EXPECT_LT((mean - p.mean).norm(), 1e-12);
    EXPECT_LT((cov - p.covariance).norm(), 1e-15);
    EXPECT_TRUE(Eigen::LLT<Eigen::Matrix3d>(p.covariance).info() == Eigen::Success);
  }
  // Far from any wall of the map: the match fails and says so.
  const ScanProposal lost = scan_matching_proposal(lik, g, room.points(Eigen::Vector3d(2.5, 2.0, 0.3)),
                                                   Eigen::Vector3d(30, 30, 0), prior_cov, opt);
  EXPECT_FALSE(lost.matched);
  expect_invalid([&] { scan_matching_proposal(lik, g, room.points({2, 2, 0}), {2, 2, 0}, -prior_cov, opt); }, "prior_cov");
}


TEST(ScanProposal, ClimbsFromTheBetterOfPriorAndStart) {
  const Room room;
  const TiledGrid2D g = room.mapped();
  const EndpointLikelihood lik(EndpointLikelihoodOptions{}, g.resolution());
  const ScanProposalOptions opt;
  const Eigen::Matrix3d prior_cov = Eigen::Vector3d(0.3 * 0.3, 0.3 * 0.3, 0.3 * 0.3).asDiagonal();
  const Eigen::Vector3d truth(2.5, 2.0, 0.3), near = truth + Eigen::Vector3d(0.03, -0.02, 0.01),
                        far = truth + Eigen::Vector3d(0.6, -0.5, 0.5);
  const Points2 pts = room.points(truth);
  auto error = [&](const ScanProposal& p) { return (p.mode.head<2>() - truth.head<2>()).norm(); };
  // From the far pose alone the climb stops short of the truth (the reason for a second start).
  const ScanProposal stuck = scan_matching_proposal(lik, g, pts, far, prior_cov, opt);
  ASSERT_GT(error(stuck), 0.1);
  // Either way round, the start that explains the scan better wins.
  EXPECT_LT(error(scan_matching_proposal(lik, g, pts, far, prior_cov, opt, near)), 0.05);
  EXPECT_LT(error(scan_matching_proposal(lik, g, pts, near, prior_cov, opt, far)), 0.05);
  expect_invalid([&] { scan_matching_proposal(lik, g, pts, near, prior_cov, opt, Eigen::Vector3d(NAN, 0, 0)); },
                 "start");
}

TEST(ScanProposal, GaussNewtonModeIsTheBruteForceMaximumAroundIt) {
  // search = fallback: the ascent's mode against a brute-force maximisation of the same score
  // (the likelihood plus the prior) over a lattice of poses 0.5 mm / 0.5 mrad apart
  // around it, and against the climb (search = always): the same optimum, within the Laplace
  // fit's spacing, in far fewer evaluations of p(z | x, m) (32-35 against 100-130 here).
  const Room room;
  const TiledGrid2D g = room.mapped();
  const EndpointLikelihoodOptions lo;
  const EndpointLikelihood lik(lo, g.resolution());
  ScanProposalOptions local, climb;
  local.search = ProposalSearch::kFallback;
  climb.search = ProposalSearch::kAlways;
  const Eigen::Matrix3d prior_cov = Eigen::Vector3d(0.1 * 0.1, 0.1 * 0.1, 0.05 * 0.05).asDiagonal();
  std::mt19937 rng(8);
  std::normal_distribution<double> n(0.0, 0.03);
  for (const Eigen::Vector3d& truth : {Eigen::Vector3d(2.5, 2.0, 0.3), Eigen::Vector3d(6.0, 3.5, -2.0),
                                       Eigen::Vector3d(3.5, 4.2, 1.9)}) {
    const Points2 pts = room.points(truth);
    const Eigen::Vector3d prior = truth + Eigen::Vector3d(n(rng), n(rng), 0.5 * n(rng));
    const Eigen::Vector3d start = truth + Eigen::Vector3d(0.3 * n(rng), 0.3 * n(rng), 0.1 * n(rng));
    const ScanProposal p = scan_matching_proposal(lik, g, pts, prior, prior_cov, local, start);
    const ScanProposal c = scan_matching_proposal(lik, g, pts, prior, prior_cov, climb, start);
    ASSERT_TRUE(p.local && p.matched && c.matched);
    EXPECT_FALSE(c.local);
    // The score by the plain search (EqualsABruteForceNearestObstacleSearch: the brute force's).
    auto score = [&](const Eigen::Vector3d& x) { return lik.log_likelihood(g, x, pts) + log_gaussian_pose(x, prior, prior_cov); };
    EXPECT_NEAR(p.log_scores[0], brute_force_log_likelihood(g, lo, p.mode, pts) + log_gaussian_pose(p.mode, prior, prior_cov),
                1e-9);
    constexpr int kHalf = 6;
    constexpr double kLattice = 5e-4;  // m and rad
    double best = -std::numeric_limits<double>::infinity();
    Eigen::Vector3d argmax = p.mode;
    for (int i = -kHalf; i <= kHalf; ++i)
      for (int j = -kHalf; j <= kHalf; ++j)
        for (int a = -kHalf; a <= kHalf; ++a) {
          const Eigen::Vector3d x = p.mode + kLattice * Eigen::Vector3d(i, j, a);
          const double s = score(x);
          if (s > best) best = s, argmax = x;
        }
    // The ascent and the climb's last stages after it: the mode is a local maximum to the climb's
    // precision, within half the Laplace fit's spacing of the lattice's best.
    EXPECT_LE((argmax - p.mode).head<2>().norm(), 0.5 * local.sample_linear);
    EXPECT_LE(std::fabs(argmax.z() - p.mode.z()), 0.5 * local.sample_angular);
    // The climb from the prior stops within the same distance of the optimum.
    EXPECT_LT((p.mode - c.mode).head<2>().norm(), local.sample_linear);
    EXPECT_LT(std::fabs(wrap_angle(p.mode.z() - c.mode.z())), local.sample_angular);
    // What the filter draws from: the two proposals' means agree far closer (under 0.8 mm and
    // 0.6 mrad here): each fit's Newton step goes to the same quadratic's top.
    EXPECT_LT((p.mean - c.mean).head<2>().norm(), 0.1 * local.sample_linear);
    EXPECT_LT(std::fabs(wrap_angle(p.mean.z() - c.mean.z())), 0.2 * local.sample_angular);
    EXPECT_LT(p.evaluations, c.evaluations);
  }
}

TEST(ScanProposal, FallsBackToTheClimbWhenTheAscentIsPoor) {
  // A prior far tighter than its error (1 cm stated, 7 cm off): the scan's optimum lies beyond the
  // prior's 99.9 % gate, so the ascent is not trusted and the proposal is the climb's, to the bit.
  // A start far away in an empty corner: the ascent from it does not reach walls, its quality is
  // poor, and the proposal is again the climb's.
  const Room room;
  const TiledGrid2D g = room.mapped();
  const EndpointLikelihood lik(EndpointLikelihoodOptions{}, g.resolution());
  ScanProposalOptions local, climb;
  local.search = ProposalSearch::kFallback;
  climb.search = ProposalSearch::kAlways;
  const Eigen::Vector3d truth(2.5, 2.0, 0.3);
  const Points2 pts = room.points(truth);
  auto same = [](const ScanProposal& a, const ScanProposal& b) {
    return a.mode == b.mode && a.quality == b.quality && a.mean == b.mean && a.covariance == b.covariance &&
           a.log_normaliser == b.log_normaliser;
  };
  const Eigen::Matrix3d tight = Eigen::Vector3d(0.01 * 0.01, 0.01 * 0.01, 0.01 * 0.01).asDiagonal();
  const Eigen::Vector3d off = truth + Eigen::Vector3d(0.07, -0.06, 0.03);
  const ScanProposal gated = scan_matching_proposal(lik, g, pts, off, tight, local);
  EXPECT_FALSE(gated.local);
  EXPECT_TRUE(same(gated, scan_matching_proposal(lik, g, pts, off, tight, climb)));
  const Eigen::Matrix3d wide = Eigen::Vector3d(0.1 * 0.1, 0.1 * 0.1, 0.05 * 0.05).asDiagonal();
  const ScanProposal held = scan_matching_proposal(lik, g, pts, off, wide, local);
  EXPECT_TRUE(held.local);
  EXPECT_LT((held.mode.head<2>() - truth.head<2>()).norm(), 0.05);
  const Eigen::Vector3d lost(30.0, 30.0, 0.0);
  const ScanProposal poor = scan_matching_proposal(lik, g, pts, lost, wide, local, lost);
  EXPECT_FALSE(poor.local);
  EXPECT_TRUE(same(poor, scan_matching_proposal(lik, g, pts, lost, wide, climb, lost)));
}

TEST(GridFastSlam, CopyIsDeepAndContinuesAsTheOriginalDoes) {
  // Three particles through the room of test_support with noisy odometry: a copy made after 15
  // scans and the original, fed the same 15 more scans, end bit for bit equal, and equal to a
  // filter that was never copied (copying does not disturb the original).
  const std::vector<test_support::Segment> walls = test_support::room_walls();
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(91, -kPi / 2, kPi / 2);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::vector<Eigen::Vector3d> odometry;
  std::vector<Eigen::VectorXd> ranges;
  for (int k = 0; k < 30; ++k) {
    const Eigen::Vector3d truth(-3.0 + 0.15 * k, -1.0 + 0.05 * k, 0.02 * k);
    odometry.push_back(truth + Eigen::Vector3d(noise(rng), noise(rng), 0.1 * noise(rng)));
    ranges.push_back(test_support::cast(truth, angles, walls));
  }
  GridFastSlamOptions o;
  o.num_particles = 3;
  o.resolution = 0.1;
  o.update.distance = 0.1;
  o.resample_threshold = 1.0;  // resample at every update: the filter's own stream is copied too
  o.seed = 4;
  GridFastSlam original(o), reference(o);
  for (int k = 0; k < 15; ++k) {
    original.add_scan(ranges[k], angles, odometry[k], k);
    reference.add_scan(ranges[k], angles, odometry[k], k);
  }
  GridFastSlam copy(original);
  for (int k = 15; k < 30; ++k) {
    copy.add_scan(ranges[k], angles, odometry[k], k);
    original.add_scan(ranges[k], angles, odometry[k], k);
    reference.add_scan(ranges[k], angles, odometry[k], k);
  }
  ASSERT_GT(copy.summary().updates, 10);
  ASSERT_GT(copy.summary().resamples, 10);
  for (const GridFastSlam* f : {&copy, &reference}) {
    EXPECT_TRUE(f->poses() == original.poses());
    EXPECT_TRUE(f->log_weights() == original.log_weights());
    for (int p = 0; p < 3; ++p) {
      EXPECT_TRUE(f->scan_poses(p) == original.scan_poses(p)) << "particle " << p;
      const OccupancyGrid2D a = f->map(p), b = original.map(p);
      EXPECT_TRUE(a.width() == b.width() && a.height() == b.height() && a.log_odds() == b.log_odds()) << "particle " << p;
    }
  }
  for (int p = 0; p < 3; ++p)
    for (std::size_t t = 0; t < static_cast<std::size_t>(copy.tiled_map(p).tiles_x() * copy.tiled_map(p).tiles_y()); ++t)
      EXPECT_FALSE(copy.tiled_map(p).shares_tile(original.tiled_map(p), t)) << "particle " << p << " tile " << t;
}

TEST(GridFastSlam, BadInputNamesTheArgumentAndChangesNothing) {
  GridFastSlamOptions o;
  o.num_particles = 3;
  GridFastSlam f(o);
  const Eigen::VectorXd r = Eigen::VectorXd::Constant(5, 2.0), a = Eigen::VectorXd::LinSpaced(5, -1.0, 1.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  expect_invalid([&] { f.add_scan(r, a, Eigen::Vector3d(nan, 0, 0), 0.0); }, "odometry");
  expect_invalid([&] { f.add_scan(r, Eigen::VectorXd::Zero(4), Eigen::Vector3d::Zero(), 0.0); }, "beam_angles");
  expect_invalid([&] { f.add_scan(r, a, Eigen::Vector3d::Zero(), nan); }, "timestamp");
  expect_invalid([&] { f.add_scan(r, a, Eigen::Vector3d(2e9, 0, 0), 0.0); }, "odometry");
  EXPECT_EQ(f.num_scans(), 0);
  EXPECT_TRUE(f.add_scan(r, a, Eigen::Vector3d::Zero(), 0.0));
  EXPECT_EQ(f.num_scans(), 1);
  o.num_particles = 0;
  expect_invalid([&] { GridFastSlam g(o); }, "num_particles");
  o.num_particles = 3;
  o.weight_scale = 0.0;
  expect_invalid([&] { GridFastSlam g(o); }, "weight_scale");
}

}  // namespace
}  // namespace probslam
