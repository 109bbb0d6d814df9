// OccupancyGrid3D without OctoMap: argument checks, queries, threads, .bt files, projection.
// (Agreement with OctoMap itself is test_octomap_crosscheck.cpp.)
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "probslam/grid/occupancy_grid_3d.hpp"
#include "probslam/io/octomap_bt.hpp"
#include "test_support.hpp"

namespace probslam {
namespace {

using test_support::expect_invalid;
using test_support::random_cloud;
using test_support::same_map;

TEST(Grid3D, RejectsBadParameters) {
  expect_invalid([] { OccupancyGrid3D g(0.0); }, "resolution");
  expect_invalid([] { OccupancyGrid3D g(-0.1); }, "resolution");
  expect_invalid([] { OccupancyGrid3D g(std::nan("")); }, "resolution");
  expect_invalid([] { OccupancyGrid3D g(0.1, {1.2, 0.4, 0.12, 0.97, 0.5}); }, "p_hit");
  expect_invalid([] { OccupancyGrid3D g(0.1, {0.3, 0.4, 0.12, 0.97, 0.5}); }, "p_hit");
  expect_invalid([] { OccupancyGrid3D g(0.1, {0.7, 0.6, 0.12, 0.97, 0.5}); }, "p_miss");
  expect_invalid([] { OccupancyGrid3D g(0.1, {0.7, 0.4, 0.0, 0.97, 0.5}); }, "clamp_min");
  expect_invalid([] { OccupancyGrid3D g(0.1, {0.7, 0.4, 0.9, 0.2, 0.5}); }, "clamp_min");
  expect_invalid([] { OccupancyGrid3D g(0.1, {0.7, 0.4, 0.12, 1.0, 0.5}); }, "clamp_max");
  expect_invalid([] { OccupancyGrid3D g(0.1, {0.7, 0.4, 0.12, 0.97, 1.5}); }, "occupancy_threshold");
}

TEST(Grid3D, RejectsBadScanArguments) {
  OccupancyGrid3D g(0.1);
  const float p[3] = {1, 2, 3};
  const float nan_origin[3] = {0, std::numeric_limits<float>::quiet_NaN(), 0};
  const float origin[3] = {0, 0, 0};
  expect_invalid([&] { g.insert_point_cloud(p, 1, nan_origin); }, "origin");
  expect_invalid([&] { g.insert_point_cloud(p, 1, origin, std::nan("")); }, "max_range");
  expect_invalid([&] { g.insert_point_cloud(p, 1, origin, -1.0, 0); }, "threads");
  expect_invalid([&] { g.insert_point_cloud(nullptr, 1, origin); }, "points");
  EXPECT_EQ(g.num_known_voxels(), 0u);
}

TEST(Grid3D, SkipsAndCountsNonFinitePoints) {
  OccupancyGrid3D g(0.1);
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const float pts[] = {1.05f, 0.05f, 0.05f, nan, 0.0f, 0.0f, 0.0f, inf, 0.0f, 0.0f, 0.0f, -inf};
  const float origin[3] = {0.05f, 0.05f, 0.05f};
  const InsertStats3D s = g.insert_point_cloud(pts, 4, origin);
  EXPECT_EQ(s.points, 4u);
  EXPECT_EQ(s.skipped_nonfinite, 3u);
  // Only the finite ray: keys 0..9 along x free (the origin's included), key 10 hit.
  EXPECT_EQ(g.num_known_voxels(), 11u);
  EXPECT_FLOAT_EQ(g.log_odds_at(1.05, 0.05, 0.05), g.hit_log_odds());
  EXPECT_FLOAT_EQ(g.log_odds_at(0.55, 0.05, 0.05), g.miss_log_odds());
  EXPECT_TRUE(std::isnan(g.log_odds_at(0.55, 0.15, 0.05)));
}

TEST(Grid3D, OnePointPerScanLogOddsAndClamping) {
  OccupancyGrid3D g(0.1);
  const float origin[3] = {0.05f, 0.05f, 0.05f};
  const float twice[6] = {0.55f, 0.05f, 0.05f, 0.55f, 0.05f, 0.05f};
  g.insert_point_cloud(twice, 2, origin);  // a repeated point counts once
  EXPECT_FLOAT_EQ(g.log_odds_at(0.55, 0.05, 0.05), 0.847298f);
  for (int i = 0; i < 10; ++i) g.insert_point_cloud(twice, 2, origin);
  EXPECT_FLOAT_EQ(g.log_odds_at(0.55, 0.05, 0.05), g.clamp_max_log_odds());
  EXPECT_NEAR(g.clamp_max_log_odds(), 3.511031f, 1e-6);
  EXPECT_NEAR(g.log_odds_at(0.25, 0.05, 0.05), -2.000028f, 1e-6);
  EXPECT_TRUE(g.is_occupied(0.55, 0.05, 0.05));
  EXPECT_FALSE(g.is_occupied(0.25, 0.05, 0.05));
  EXPECT_FALSE(g.is_occupied(5.0, 5.0, 5.0));  // unknown
}

TEST(Grid3D, MaxRangeCutFreesButDoesNotHit) {
  OccupancyGrid3D g(0.1);
  const float origin[3] = {0.05f, 0.05f, 0.05f};
  const float far[3] = {3.05f, 0.05f, 0.05f};
  const InsertStats3D s = g.insert_point_cloud(far, 1, origin, 1.0);
  EXPECT_EQ(s.max_range_cut, 1u);
  EXPECT_FLOAT_EQ(g.log_odds_at(0.95, 0.05, 0.05), g.miss_log_odds());
  EXPECT_TRUE(std::isnan(g.log_odds_at(1.05, 0.05, 0.05)));  // the cut point's voxel stays unknown
  EXPECT_EQ(g.num_occupied_voxels(), 0u);
}

TEST(Grid3D, ThreadsGiveTheSameMap) {
  std::mt19937 rng(3);
  OccupancyGrid3D one(0.1), two(0.1), three(0.1);
  for (int s = 0; s < 5; ++s) {
    const float origin[3] = {0.4f * s, 0.1f, -0.2f};
    const std::vector<float> c = random_cloud(rng, 20000, 6.0f);
    const InsertStats3D a = one.insert_point_cloud(c.data(), c.size() / 3, origin, 5.0, 1);
    const InsertStats3D b = two.insert_point_cloud(c.data(), c.size() / 3, origin, 5.0, 2);
    three.insert_point_cloud(c.data(), c.size() / 3, origin, 5.0, 3);
    EXPECT_EQ(a.voxels_updated, b.voxels_updated);
  }
  EXPECT_TRUE(same_map(one, two));
  EXPECT_TRUE(same_map(one, three));
}

TEST(Grid3D, CastRayFindsTheFirstOccupiedVoxel) {
  OccupancyGrid3D g(0.1);
  const float origin[3] = {0.05f, 0.05f, 0.05f};
  const float wall[6] = {2.05f, 0.05f, 0.05f, 3.05f, 0.05f, 0.05f};
  g.insert_point_cloud(wall, 2, origin);
  const auto hit = g.cast_ray({0.05, 0.05, 0.05}, {1, 0, 0}, 10.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->x(), 2.05, 1e-9);
  EXPECT_FALSE(g.cast_ray({0.05, 0.05, 0.05}, {1, 0, 0}, 1.5).has_value());
  EXPECT_FALSE(g.cast_ray({0.05, 0.05, 0.05}, {-1, 0, 0}, 10.0).has_value());
  expect_invalid([&] { g.cast_ray({0, 0, 0}, {0, 0, 0}, 1.0); }, "direction");
}

TEST(Grid3D, ProjectionTakesTheColumnMaximum) {
  OccupancyGrid3D g(0.1);
  const float origin[3] = {0.05f, 0.05f, 1.05f};
  const float pts[6] = {1.05f, 0.05f, 1.05f, 0.05f, 1.05f, 0.25f};
  g.insert_point_cloud(pts, 2, origin);
  const OccupancyGrid2D all = g.project_2d(-10, 10);
  EXPECT_DOUBLE_EQ(all.resolution(), 0.1);
  const Eigen::Vector2i wall = all.cell_of(1.05, 0.05);
  EXPECT_FLOAT_EQ(static_cast<float>(all.log_odds()(wall[0], wall[1])), g.hit_log_odds());
  const Eigen::Vector2i floor = all.cell_of(0.05, 1.05);
  EXPECT_FLOAT_EQ(static_cast<float>(all.log_odds()(floor[0], floor[1])), g.hit_log_odds());
  const OccupancyGrid2D above = g.project_2d(0.5, 10);  // leaves out the floor hit at z = 0.25
  const Eigen::Vector2i floor2 = above.cell_of(0.05, 1.05);
  EXPECT_TRUE(!above.contains(floor2[0], floor2[1]) || above.log_odds()(floor2[0], floor2[1]) < 0.0);
  EXPECT_LT(above.height(), all.height());  // the ray's lower part is left out too
  expect_invalid([&] { g.project_2d(1.0, 0.0); }, "z_min");
}

class BtFile : public ::testing::Test {
 protected:
  // One file per test and process: ctest runs the BtFile tests at once (-j), and a shared name
  // let one test truncate the file another was reading.
  std::string path = ::testing::TempDir() + "probslam_grid3d_" +
                     ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
                     std::to_string(::getpid()) + ".bt";
  void TearDown() override { std::remove(path.c_str()); }
  void write_raw(const std::string& bytes) { std::ofstream(path, std::ios::binary) << bytes; }
};

TEST_F(BtFile, RoundTripKeepsOccupancy) {
  std::mt19937 rng(11);
  OccupancyGrid3D g(0.2);
  const float origin[3] = {0.1f, 0.1f, 0.1f};
  for (int s = 0; s < 3; ++s) {
    const std::vector<float> c = random_cloud(rng, 3000, 4.0f);
    g.insert_point_cloud(c.data(), c.size() / 3, origin);
  }
  const std::size_t nodes = write_octomap_bt(g, path);
  EXPECT_GT(nodes, 0u);
  const OccupancyGrid3D r = read_octomap_bt(path);
  EXPECT_DOUBLE_EQ(r.resolution(), 0.2);
  EXPECT_EQ(r.num_known_voxels(), g.num_known_voxels());
  std::size_t wrong = 0;
  g.for_each_known([&](const CellKey<3>& k, float l) {
    const float expected = l >= g.occupancy_log_odds() ? g.clamp_max_log_odds() : g.clamp_min_log_odds();
    wrong += r.log_odds_at_key(k) != expected;
  });
  EXPECT_EQ(wrong, 0u);
}

TEST_F(BtFile, EmptyGridRoundTrips) {
  OccupancyGrid3D g(0.05);
  EXPECT_EQ(write_octomap_bt(g, path), 0u);
  EXPECT_EQ(read_octomap_bt(path).num_known_voxels(), 0u);
}

TEST_F(BtFile, CorruptFilesRaise) {
  const std::string header = "# Octomap OcTree binary file\nid OcTree\nsize 9\nres 0.1\ndata\n";
  const auto expect_rejected = [&](const std::string& bytes, const char* why) {
    write_raw(bytes);
    EXPECT_THROW(read_octomap_bt(path), std::invalid_argument) << why;
  };
  expect_rejected("", "empty file");
  expect_rejected("hello\n", "not a .bt file");
  expect_rejected("# Octomap OcTree binary file\nid ColorOcTree\nsize 1\nres 0.1\ndata\n", "other tree type");
  expect_rejected("# Octomap OcTree binary file\nid OcTree\nsize 1\nres -0.1\ndata\n", "bad resolution");
  expect_rejected("# Octomap OcTree binary file\nid OcTree\nsize 1\nres 0.1\n", "no data line");
  expect_rejected(header, "truncated: no tree");
  expect_rejected(header + std::string("\xff", 1), "truncated node");
  expect_rejected(header + std::string("\xff\xff", 2), "inner children missing");
  // Sixteen levels of "child 0 is inner" then a 17th: a voxel cannot have children.
  std::string deep;
  for (int i = 0; i < 17; ++i) deep += std::string("\x03\x00", 2);
  expect_rejected(header + deep, "deeper than 16 levels");
  // A valid tree with a wrong node count.
  std::string one_leaf;
  for (int i = 0; i < 15; ++i) one_leaf += std::string("\x03\x00", 2);
  one_leaf += std::string("\x02\x00", 2);  // child 0 occupied leaf at full depth
  expect_rejected("# Octomap OcTree binary file\nid OcTree\nsize 5\nres 0.1\ndata\n" + one_leaf, "node count");
  write_raw("# Octomap OcTree binary file\nid OcTree\nsize 17\nres 0.1\ndata\n" + one_leaf);
  const OccupancyGrid3D g = read_octomap_bt(path);
  EXPECT_EQ(g.num_known_voxels(), 1u);
  EXPECT_EQ(g.num_occupied_voxels(), 1u);
  // A free leaf just below the root would be 2^45 voxels: refused, not attempted.
  expect_rejected("# Octomap OcTree binary file\nid OcTree\nsize 2\nres 0.1\ndata\n" + std::string("\x01\x00", 2),
                  "too large");
  EXPECT_THROW(read_octomap_bt(path + ".missing"), std::invalid_argument);
  // Random bytes after a valid header never crash.
  std::mt19937 rng(1);
  for (int trial = 0; trial < 200; ++trial) {
    std::string junk(rng() % 64, '\0');
    for (char& ch : junk) ch = static_cast<char>(rng());
    write_raw(header + junk);
    try {
      read_octomap_bt(path);
    } catch (const std::invalid_argument&) {
    }
  }
}

}  // namespace
}  // namespace probslam
