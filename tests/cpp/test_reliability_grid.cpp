// The reliability policy (issue 12) for the grids in C++: worker threads that cannot be started,
// keys that saturate instead of overflowing, walks clipped to a box, bounded projections.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "probslam/grid/occupancy_grid_2d.hpp"
#include "probslam/grid/occupancy_grid_3d.hpp"
#include "probslam/grid/ray_traversal.hpp"
#include "probslam/core/worker_pool.hpp"
#include "test_support.hpp"

namespace probslam {
namespace {

using test_support::random_cloud;
using test_support::same_map;

// Every known voxel and its log-odds, in block order (a change anywhere shows).
std::vector<std::pair<CellKey<3>, float>> dump(const OccupancyGrid3D& g) {
  std::vector<std::pair<CellKey<3>, float>> out;
  g.for_each_known([&](const CellKey<3>& k, float l) { out.emplace_back(k, l); });
  return out;
}

// Resets the hook whatever a test does.
struct HookReset {
  ~HookReset() { testing::worker_start_failure_after.store(-1); }
};

TEST(GridReliability, RefusedWorkerThreadRaisesAndLeavesTheMapUnchanged) {
  HookReset reset;
  std::mt19937 rng(1);
  const float origin[3] = {0.05f, 0.05f, 0.05f};
  OccupancyGrid3D grid(0.1), serial(0.1);
  const std::vector<float> first = random_cloud(rng, 4000, 3.0f), second = random_cloud(rng, 4000, 3.0f);
  grid.insert_point_cloud(first.data(), 4000, origin);
  serial.insert_point_cloud(first.data(), 4000, origin);
  const auto before = dump(grid);
  for (const int successes : {0, 1, 2}) {  // the first, second or third worker refused
    testing::worker_start_failure_after.store(successes);
    EXPECT_THROW(grid.insert_point_cloud(second.data(), 4000, origin, -1.0, 4), std::system_error);
    EXPECT_EQ(dump(grid), before) << "after " << successes << " started threads";
  }
  // No "changed in this scan" mark is left behind: the next scan equals the serial one.
  grid.insert_point_cloud(second.data(), 4000, origin, -1.0, 4);
  serial.insert_point_cloud(second.data(), 4000, origin);
  EXPECT_TRUE(same_map(grid, serial));
}

TEST(GridReliability, WorkerPoolRethrowsAWorkersExceptionAfterJoiningAll) {
  WorkerPool pool(3);
  std::vector<int> ran(3, 0);
  EXPECT_THROW(pool.run([&](std::size_t w) {
    ran[w] = 1;
    if (w == 2) throw std::runtime_error("worker 2 failed");
  }),
               std::runtime_error);
  EXPECT_EQ(ran, (std::vector<int>{1, 1, 1}));
  pool.run([&](std::size_t w) { ran[w] = 2; });  // still usable
  EXPECT_EQ(ran, (std::vector<int>{2, 2, 2}));
}

TEST(GridReliability, ThreadCountBeyondTheLimitIsRefused) {
  OccupancyGrid3D grid(0.1);
  const float p[3] = {1, 1, 1}, origin[3] = {0, 0, 0};
  EXPECT_THROW(grid.insert_point_cloud(p, 1, origin, -1.0, OccupancyGrid3D::kMaxThreads + 1), std::invalid_argument);
  EXPECT_EQ(grid.num_known_voxels(), 0u);
}

TEST(GridReliability, KeysSaturateInsteadOfOverflowing) {
  const GridLattice2D lattice{0.0, 0.0, 1.0, 1.0};
  EXPECT_EQ(lattice.key(0, 1e300), kKeyBound);
  EXPECT_EQ(lattice.key(0, -1e300), -kKeyBound);
  EXPECT_EQ(lattice.key(0, 3e9), kKeyBound);
  EXPECT_EQ(lattice.key(0, std::nan("")), -kKeyBound);
  EXPECT_EQ(lattice.key(0, 12345.5), 12345);
  const OccupancyGrid2D grid(1.0, 10, 10);
  EXPECT_FALSE(grid.contains(grid.cell_of(5.0, 3e9)[0], grid.cell_of(5.0, 3e9)[1]));
  EXPECT_EQ(grid.cell_index(3e9 + 0.5, -5e9 - 0.5)[0], -5000000001LL);
  EXPECT_EQ(grid.cell_index(3e9 + 0.5, -5e9 - 0.5)[1], 3000000000LL);
  EXPECT_THROW(grid.cell_index(1e300, 0.0), std::invalid_argument);
  const OccupancyGrid3D g3(0.1);
  for (const double c : {1e300, -1e300, 3276.8, -3276.81, std::nan("")})
    EXPECT_FALSE(OctreeLattice::valid(g3.key_of(c, 0.0, 0.0))) << c;
  EXPECT_TRUE(OctreeLattice::valid(g3.key_of(-3276.8, 0.0, 3276.7)));
}

// The cells walk_ray visits inside the box (walked in full) against walk_ray_in_box.
template <class Lattice>
void expect_clipped_walk_equals_full_walk(const Lattice& lattice, const KeyBox<2>& box, const double* o,
                                          const double* e) {
  std::vector<CellKey<2>> full, clipped;
  walk_ray<2, double>(lattice, o, e, [&](const CellKey<2>& k) {
    if (box.contains(k)) full.push_back(k);
    return true;
  });
  walk_ray_in_box<2, double>(lattice, box, o, e, [&](const CellKey<2>& k) {
    EXPECT_TRUE(box.contains(k));
    clipped.push_back(k);
    return true;
  });
  EXPECT_EQ(clipped, full) << "segment (" << o[0] << ", " << o[1] << ") -> (" << e[0] << ", " << e[1] << ")";
}

TEST(GridReliability, ClippedWalkEqualsTheFullWalkInsideTheBox) {
  std::mt19937 rng(5);
  const GridLattice2D lattice{-2.0, -1.0, 0.1, 1.0 / 0.1};
  const KeyBox<2> box{{0, 0}, {40, 30}};  // [-2, 2] x [-1, 2]
  std::uniform_real_distribution<double> near(-8.0, 8.0), far(-80.0, 80.0);
  for (int i = 0; i < 4000; ++i) {
    auto& d = i % 2 ? near : far;  // origins inside, beside and far outside the box
    const double o[2] = {d(rng), d(rng)}, e[2] = {near(rng), near(rng)};
    expect_clipped_walk_equals_full_walk(lattice, box, o, e);
  }
  // Axis-parallel segments along and beside the box's edges.
  for (const double y : {-1.05, -1.0, -0.95, 1.95, 2.0, 2.05}) {
    const double o[2] = {-50.0, y}, e[2] = {50.0, y};
    expect_clipped_walk_equals_full_walk(lattice, box, o, e);
  }
}

TEST(GridReliability, SegmentsMissingTheBoxVisitNothing) {
  const GridLattice2D lattice{0.0, 0.0, 0.1, 10.0};
  const KeyBox<2> box{{0, 0}, {10, 10}};
  int visited = 0;
  const auto count = [&](const CellKey<2>&) { return ++visited, true; };
  const double o[2] = {-100.0, 100.0}, e[2] = {-1e9, 1e9}, e2[2] = {-1e308, 1e308};
  walk_ray_in_box<2, double>(lattice, box, o, e, count);
  walk_ray_in_box<2, double>(lattice, box, o, e2, count);  // heading away, end near overflow
  EXPECT_EQ(visited, 0);
  const double inf_end[2] = {std::numeric_limits<double>::infinity(), 0.5};
  walk_ray_in_box<2, double>(lattice, box, o, inf_end, count);
  EXPECT_EQ(visited, 0);
}

TEST(GridReliability, CastRayIsClippedToTheKeyRange) {
  OccupancyGrid3D grid(0.1);
  std::mt19937 rng(9);
  const float origin[3] = {0.05f, 0.05f, 0.05f};
  const std::vector<float> cloud = random_cloud(rng, 300, 3.0f);
  grid.insert_point_cloud(cloud.data(), 300, origin);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int i = 0; i < 60; ++i) {  // each far ray walks to the key range's edge (~5e4 voxels)
    const Eigen::Vector3d o(n(rng), n(rng), n(rng)), d(n(rng), n(rng), n(rng));
    const auto near = grid.cast_ray(o, d, 20.0);
    const auto far = grid.cast_ray(o, d, 1e12);
    ASSERT_EQ(near.has_value(), far.has_value());
    if (near) EXPECT_EQ(*near, *far);
    EXPECT_EQ(far, grid.cast_ray(o, d, std::numeric_limits<double>::max()));
  }
}

TEST(GridReliability, ProjectionOfDistantVoxelsIsRefusedBeforeAllocating) {
  OccupancyGrid3D grid(0.1);
  for (const float c : {3000.0f, -3000.0f}) {
    const float p[3] = {c, c, 0.0f};
    grid.insert_point_cloud(p, 1, p);
  }
  ASSERT_EQ(grid.num_known_voxels(), 2u);
  try {
    grid.project_2d(-1.0, 1.0);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_cells"), std::string::npos) << e.what();
  }
}

TEST(GridReliability, InsertScansValidatesEveryRowFirst) {
  OccupancyGrid2D grid(0.1, 50, 50);
  Poses2 poses(3, 3);
  poses << 2.5, 2.5, 0.0, 2.0, 2.0, 1.0, 3.0, std::nan(""), 2.0;
  const RowMatrixXd ranges = RowMatrixXd::Constant(3, 20, 1.5);
  const RowMatrixXd angles = Eigen::RowVectorXd::LinSpaced(20, -1.0, 1.0);
  EXPECT_THROW(grid.insert_scans(poses, ranges, angles, 3.0), std::invalid_argument);
  EXPECT_TRUE((grid.log_odds().array() == 0.0).all());
}

}  // namespace
}  // namespace probslam
