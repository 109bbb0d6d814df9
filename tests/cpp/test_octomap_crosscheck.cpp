// Cross-check of OccupancyGrid3D against Debian's liboctomap: the same clouds go into an
// octomap::OcTree (insertPointCloud, lazy_eval and discretize off) and into our grid, and both
// must end with the same known voxels holding the same log-odds.
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "probslam/grid/occupancy_grid_3d.hpp"
#include "probslam/io/octomap_bt.hpp"

namespace probslam {
namespace {

// Both sides add the same float updates in the same order per voxel, so values should agree
// bit for bit; the tolerance bounds what a different float evaluation could cause.
constexpr float kLogOddsTolerance = 1e-5f;

using Cloud = std::vector<float>;  // x y z per point

struct Comparison {
  std::size_t ours = 0, theirs = 0, missing = 0, differing = 0, not_bitwise = 0;
};

Comparison compare(const octomap::OcTree& tree, const OccupancyGrid3D& grid) {
  Comparison c;
  grid.for_each_known([&](const CellKey<3>& k, float l) {
    ++c.ours;
    const octomap::OcTreeKey key(static_cast<octomap::key_type>(k[0]), static_cast<octomap::key_type>(k[1]),
                                 static_cast<octomap::key_type>(k[2]));
    // search() returns the deepest node on the key's path: a pruned node stands for its voxels.
    const octomap::OcTreeNode* node = tree.search(key);
    if (node == nullptr) {
      ++c.missing;
      return;
    }
    if (std::fabs(node->getLogOdds() - l) > kLogOddsTolerance) ++c.differing;
    if (node->getLogOdds() != l) ++c.not_bitwise;
  });
  const unsigned depth = tree.getTreeDepth();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    c.theirs += std::size_t{1} << (3 * (depth - it.getDepth()));  // a pruned leaf covers 8^levels voxels
  return c;
}

void expect_same(const octomap::OcTree& tree, const OccupancyGrid3D& grid, const std::string& what) {
  const Comparison c = compare(tree, grid);
  EXPECT_GT(c.ours, 0u) << what;
  EXPECT_EQ(c.ours, c.theirs) << what << ": known voxels differ in number";
  EXPECT_EQ(c.missing, 0u) << what << ": our known voxels unknown to OctoMap";
  EXPECT_EQ(c.differing, 0u) << what << ": log-odds differ by more than " << kLogOddsTolerance;
  EXPECT_EQ(c.not_bitwise, 0u) << what << ": log-odds not bit-identical";
}

void insert_both(octomap::OcTree& tree, OccupancyGrid3D& grid, const Cloud& cloud, const float origin[3],
                 double max_range, int threads = 1) {
  octomap::Pointcloud pc;
  pc.reserve(cloud.size() / 3);
  for (std::size_t i = 0; i < cloud.size(); i += 3) pc.push_back(cloud[i], cloud[i + 1], cloud[i + 2]);
  tree.insertPointCloud(pc, octomap::point3d(origin[0], origin[1], origin[2]), max_range, false, false);
  grid.insert_point_cloud(cloud.data(), cloud.size() / 3, origin, max_range, threads);
}

void push(Cloud& c, float x, float y, float z) { c.insert(c.end(), {x, y, z}); }

/// A cloud that exercises the walk's corner cases around `origin`.
Cloud tricky_cloud(std::mt19937& rng, const float origin[3], double res, int n_random) {
  Cloud c;
  std::uniform_real_distribution<float> coord(-6.0f, 6.0f);
  std::uniform_int_distribution<int> cell(-50, 50);
  std::uniform_real_distribution<float> dist(0.0f, 7.0f);
  // Random points around the origin, with negative coordinates.
  for (int i = 0; i < n_random; ++i) push(c, origin[0] + coord(rng), origin[1] + coord(rng), origin[2] + coord(rng));
  // Points on voxel boundaries (k * res, rounded to float as OctoMap does).
  for (int i = 0; i < n_random / 4; ++i)
    push(c, static_cast<float>(cell(rng) * res), static_cast<float>(cell(rng) * res), static_cast<float>(cell(rng) * res));
  // Rays along the axes and the 2-D and 3-D diagonals, both ways.
  for (int dx = -1; dx <= 1; ++dx)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dz = -1; dz <= 1; ++dz) {
        if (dx == 0 && dy == 0 && dz == 0) continue;
        const float t = dist(rng);
        push(c, origin[0] + dx * t, origin[1] + dy * t, origin[2] + dz * t);
        const float k = static_cast<float>(cell(rng) * res);  // ending on a boundary
        push(c, origin[0] + dx * k, origin[1] + dy * k, origin[2] + dz * k);
      }
  // Points in the origin's own voxel (an empty ray, still a hit).
  push(c, origin[0], origin[1], origin[2]);
  push(c, origin[0] + static_cast<float>(res * 0.1), origin[1], origin[2]);
  // Repeated points.
  const std::size_t before = c.size();
  for (std::size_t i = 0; i + 3 <= before && i < 60; i += 3) c.insert(c.end(), c.begin() + i, c.begin() + i + 3);
  return c;
}

struct Case {
  double res;
  double max_range;
};

class CrossCheck : public ::testing::TestWithParam<Case> {};

TEST_P(CrossCheck, RandomisedCloudsMatchOctomap) {
  const Case p = GetParam();
  std::mt19937 rng(1234 + static_cast<int>(p.res * 1000) + static_cast<int>(p.max_range));
  octomap::OcTree tree(p.res);
  OccupancyGrid3D grid(p.res);
  std::uniform_real_distribution<float> jitter(-2.0f, 2.0f);
  const int n_random = p.res < 0.1 ? 300 : 800;
  for (int scan = 0; scan < 6; ++scan) {
    float origin[3] = {jitter(rng), jitter(rng), jitter(rng)};
    if (scan == 1) origin[0] = origin[1] = origin[2] = 0.0f;  // on a voxel corner
    if (scan == 2) origin[0] = static_cast<float>(3 * p.res), origin[1] = static_cast<float>(-2 * p.res);
    insert_both(tree, grid, tricky_cloud(rng, origin, p.res, n_random), origin, p.max_range);
    expect_same(tree, grid, "res " + std::to_string(p.res) + " scan " + std::to_string(scan));
  }
}

INSTANTIATE_TEST_SUITE_P(Resolutions, CrossCheck,
                         ::testing::Values(Case{0.1, -1.0}, Case{0.1, 4.0}, Case{0.25, -1.0}, Case{0.25, 3.0},
                                           Case{0.05, -1.0}, Case{0.05, 2.5}, Case{0.2, 0.0}),
                         [](const ::testing::TestParamInfo<Case>& info) {
                           const auto mm = [](double v) { return std::to_string(static_cast<int>(std::lround(v * 1000))); };
                           return "res_" + mm(info.param.res) + "mm_range_" +
                                  (info.param.max_range < 0 ? std::string("none") : mm(info.param.max_range) + "mm");
                         });

TEST(CrossCheck, SaturatedVoxelsAndPruningMatch) {
  // The same scan twelve times: voxels reach both clamps, OctoMap prunes uniform regions.
  octomap::OcTree tree(0.25);
  OccupancyGrid3D grid(0.25);
  std::mt19937 rng(7);
  const float origin[3] = {0.1f, 0.2f, 0.3f};
  Cloud cloud;
  // A closed box of points around the origin: every direction ends on a wall.
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  for (int i = 0; i < 3000; ++i) {
    const int face = i % 6;
    float p[3] = {u(rng), u(rng), u(rng)};
    p[face / 2] = face % 2 ? 3.0f : -3.0f;
    push(cloud, p[0], p[1], p[2]);
  }
  for (int k = 0; k < 12; ++k) insert_both(tree, grid, cloud, origin, -1.0);
  expect_same(tree, grid, "saturated box");
  EXPECT_LT(tree.size(), tree.getNumLeafNodes() * 2) << "expected OctoMap to have pruned nodes";
}

TEST(CrossCheck, OutOfRangePointsAreDroppedLikeOctomap) {
  // At 0.01 m the key range is +-327.68 m: far points, and rays from a far origin, are refused.
  octomap::OcTree tree(0.01);
  OccupancyGrid3D grid(0.01);
  Cloud cloud;
  push(cloud, 1.0f, 0.5f, 0.2f);
  push(cloud, 400.0f, 0.0f, 0.0f);   // out of range: neither ray nor hit
  push(cloud, -1.0f, -0.5f, 0.3f);
  const float origin[3] = {0.0f, 0.0f, 0.0f};
  insert_both(tree, grid, cloud, origin, -1.0);
  // ... but with a max range the cut point is inside and the ray is cleared up to it.
  insert_both(tree, grid, cloud, origin, 2.0);
  expect_same(tree, grid, "out of range");
  const InsertStats3D s = grid.insert_point_cloud(cloud.data(), 3, origin, -1.0);
  EXPECT_EQ(s.out_of_bounds, 1u);
  // An origin beyond the key range: OctoMap keeps the hits and frees nothing.
  octomap::OcTree tree2(0.01);
  OccupancyGrid3D grid2(0.01);
  const float far_origin[3] = {500.0f, 0.0f, 0.0f};
  insert_both(tree2, grid2, cloud, far_origin, -1.0);
  expect_same(tree2, grid2, "far origin");
}

TEST(CrossCheck, MultiThreadedInsertMatchesOctomap) {
  octomap::OcTree tree(0.1);
  OccupancyGrid3D grid(0.1);
  std::mt19937 rng(99);
  for (int scan = 0; scan < 4; ++scan) {
    const float origin[3] = {0.3f * scan, -0.2f * scan, 0.05f};
    Cloud cloud = tricky_cloud(rng, origin, 0.1, 3000);
    insert_both(tree, grid, cloud, origin, 5.0, 2);
  }
  expect_same(tree, grid, "two threads");
}

/// scan.dat from OctoMap's sample data (x y z per line), or empty when absent.
Cloud read_sample_scan() {
  const std::string path = std::string(PROBSLAM_SHARED_DATA) + "/scans_3d/octomap_samples/scan.dat.bz2";
  if (!std::ifstream(path)) return {};
  FILE* pipe = popen(("bzip2 -dc '" + path + "' 2>/dev/null").c_str(), "r");
  if (pipe == nullptr) return {};
  Cloud cloud;
  float x, y, z;
  while (std::fscanf(pipe, "%f %f %f", &x, &y, &z) == 3) push(cloud, x, y, z);
  pclose(pipe);
  return cloud;
}

TEST(CrossCheck, RealScanMatchesOctomap) {
  const Cloud cloud = read_sample_scan();
  if (cloud.empty()) GTEST_SKIP() << "OctoMap's scan.dat.bz2 not found under " << PROBSLAM_SHARED_DATA;
  ASSERT_EQ(cloud.size() / 3, 88206u);
  octomap::OcTree tree(0.1);
  OccupancyGrid3D grid(0.1);
  // A short sequence: the scan from its own origin, then as if seen from two nearby poses.
  const float origins[3][3] = {{0.0f, 0.0f, 0.0f}, {0.35f, -0.2f, 0.1f}, {-0.4f, 0.25f, -0.05f}};
  const double ranges[3] = {-1.0, 12.0, 20.0};
  for (int s = 0; s < 3; ++s) {
    insert_both(tree, grid, cloud, origins[s], ranges[s], s == 2 ? 2 : 1);
    expect_same(tree, grid, "scan.dat step " + std::to_string(s));
  }
}

TEST(CrossCheck, BtExportIsReadByOctomap) {
  std::mt19937 rng(5);
  octomap::OcTree reference(0.1);
  OccupancyGrid3D grid(0.1);
  const float origin[3] = {0.0f, 0.0f, 0.0f};
  for (int s = 0; s < 3; ++s) insert_both(reference, grid, tricky_cloud(rng, origin, 0.1, 2000), origin, -1.0);
  const std::string path = ::testing::TempDir() + "probslam_crosscheck.bt";
  write_octomap_bt(grid, path);
  octomap::OcTree read(0.1);
  ASSERT_TRUE(read.readBinary(path));
  EXPECT_DOUBLE_EQ(read.getResolution(), 0.1);
  // OctoMap's own export of the same map, for the node count and the bytes.
  reference.toMaxLikelihood();
  reference.prune();
  EXPECT_EQ(read.size(), reference.size());
  EXPECT_EQ(read.getNumLeafNodes(), reference.getNumLeafNodes());
  std::size_t leaves = 0, wrong = 0;
  for (auto it = read.begin_leafs(), end = read.end_leafs(); it != end; ++it) {
    ++leaves;
    const float l = grid.log_odds_at_key({it.getKey()[0] & ~((1 << (16 - it.getDepth())) - 1),
                                          it.getKey()[1] & ~((1 << (16 - it.getDepth())) - 1),
                                          it.getKey()[2] & ~((1 << (16 - it.getDepth())) - 1)});
    if (std::isnan(l) || (l >= grid.occupancy_log_odds()) != read.isNodeOccupied(*it)) ++wrong;
  }
  EXPECT_GT(leaves, 0u);
  EXPECT_EQ(wrong, 0u);
  // And back: our import of OctoMap's file equals OctoMap's maximum-likelihood map.
  const std::string theirs = ::testing::TempDir() + "probslam_crosscheck_octomap.bt";
  ASSERT_TRUE(reference.writeBinary(theirs));
  const OccupancyGrid3D imported = read_octomap_bt(theirs);
  expect_same(reference, imported, "import of OctoMap's .bt");
  std::remove(path.c_str());
  std::remove(theirs.c_str());
}

TEST(CrossCheck, Geb079ImportMatchesOctomap) {
  const std::string path = std::string(PROBSLAM_SHARED_DATA) + "/scans_3d/octomap_samples/geb079.bt";
  if (!std::ifstream(path)) GTEST_SKIP() << "geb079.bt not found";
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary(path));
  const OccupancyGrid3D grid = read_octomap_bt(path);
  EXPECT_DOUBLE_EQ(grid.resolution(), 0.08);
  expect_same(tree, grid, "geb079.bt");
}

}  // namespace
}  // namespace probslam
