#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "probslam/grid/occupancy_grid_2d.hpp"
#include "probslam/grid/ray_traversal.hpp"

using namespace probslam;

namespace {

// Overlaps shorter than this fraction of the segment are ambiguous (the segment grazes a
// corner); the walk may or may not include such cells.
constexpr double kGrazing = 1e-9;

template <int Dim>
struct UnitLattice {
  double res;
  int key(int, double c) const { return static_cast<int>(std::floor(c / res)); }
  double key_to_coord(int, int k) const { return (k + 0.5) * res; }
  double resolution() const { return res; }
};

// Length fraction of the segment o -> e inside cell `key` (brute force, Liang-Barsky).
template <int Dim>
double overlap(const double* o, const double* e, const CellKey<Dim>& key, double res) {
  double t0 = 0.0, t1 = 1.0;
  for (int d = 0; d < Dim; ++d) {
    const double lo = key[d] * res, hi = (key[d] + 1) * res, dir = e[d] - o[d];
    if (dir == 0.0) {
      if (o[d] < lo || o[d] >= hi) return 0.0;
      continue;
    }
    double a = (lo - o[d]) / dir, b = (hi - o[d]) / dir;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return std::max(0.0, t1 - t0);
}

template <int Dim>
void check_random_segments(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coord(-5.0, 5.0);
  const UnitLattice<Dim> lattice{0.37};
  for (int trial = 0; trial < 300; ++trial) {
    double o[Dim], e[Dim];
    for (int d = 0; d < Dim; ++d) {
      o[d] = coord(rng);
      e[d] = coord(rng);
    }
    if (trial % 10 == 0) e[0] = o[0];  // axis-parallel rays
    std::vector<CellKey<Dim>> walked;
    walk_ray<Dim, double>(lattice, o, e, [&](const CellKey<Dim>& k) {
      walked.push_back(k);
      return true;
    });
    CellKey<Dim> start, end, lo, hi;
    for (int d = 0; d < Dim; ++d) {
      start[d] = lattice.key(d, o[d]);
      end[d] = lattice.key(d, e[d]);
      lo[d] = std::min(start[d], end[d]);
      hi[d] = std::max(start[d], end[d]);
    }
    if (start == end) {
      EXPECT_TRUE(walked.empty());
      continue;
    }
    ASSERT_FALSE(walked.empty());
    EXPECT_EQ(walked.front(), start);
    const std::set<CellKey<Dim>> visited(walked.begin(), walked.end());
    EXPECT_EQ(visited.size(), walked.size()) << "a cell was visited twice";
    EXPECT_EQ(visited.count(end), 0u) << "the end cell is not part of the ray";
    for (std::size_t i = 1; i < walked.size(); ++i) {
      int changed = 0, steps = 0;
      for (int d = 0; d < Dim; ++d) {
        changed += walked[i][d] != walked[i - 1][d];
        steps += std::abs(walked[i][d] - walked[i - 1][d]);
      }
      EXPECT_EQ(changed, 1);
      EXPECT_EQ(steps, 1);
    }
    // Every cell the segment really crosses (the end cell aside) is visited, and nothing else.
    CellKey<Dim> k = lo;
    for (;;) {
      const double f = overlap<Dim>(o, e, k, lattice.res);
      if (f > kGrazing && k != end) EXPECT_EQ(visited.count(k), 1u) << "missed a crossed cell";
      if (visited.count(k)) EXPECT_GT(f, -kGrazing);
      int d = 0;
      while (d < Dim && ++k[d] > hi[d]) k[d++] = lo[d - 0];
      if (d == Dim) break;
    }
    for (const CellKey<Dim>& v : visited) EXPECT_GE(overlap<Dim>(o, e, v, lattice.res), 0.0);
    for (const CellKey<Dim>& v : visited)
      if (v != start) EXPECT_GT(overlap<Dim>(o, e, v, lattice.res) + kGrazing, 0.0);
  }
}

}  // namespace

TEST(WalkRay, TwoDimensionsMatchesBruteForceCrossing) { check_random_segments<2>(7); }
TEST(WalkRay, ThreeDimensionsMatchesBruteForceCrossing) { check_random_segments<3>(11); }

TEST(WalkRay, SameCellIsEmptyAndEarlyStopWorks) {
  const UnitLattice<2> lattice{1.0};
  const double o[2] = {0.2, 0.2}, e1[2] = {0.8, 0.9}, e2[2] = {9.5, 0.5};
  int n = 0;
  walk_ray<2, double>(lattice, o, e1, [&](const CellKey<2>&) { return ++n, true; });
  EXPECT_EQ(n, 0);
  walk_ray<2, double>(lattice, o, e2, [&](const CellKey<2>&) { return ++n < 3; });
  EXPECT_EQ(n, 3);
}
