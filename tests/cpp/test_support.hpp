#pragma once
// Helpers shared by the C++ test files.
#include <gtest/gtest.h>

#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "probslam/grid/occupancy_grid_3d.hpp"

namespace probslam::test_support {

/// Expects std::invalid_argument whose message starts with the argument's name.
inline void expect_invalid(const std::function<void()>& call, const std::string& name) {
  try {
    call();
    ADD_FAILURE() << "accepted; expected std::invalid_argument naming " << name;
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind(name, 0), 0u) << e.what();
  }
}

/// n points (3n floats) uniform in the cube [-extent, extent]^3.
inline std::vector<float> random_cloud(std::mt19937& rng, int n, float extent) {
  std::uniform_real_distribution<float> u(-extent, extent);
  std::vector<float> c(3 * n);
  for (float& v : c) v = u(rng);
  return c;
}

/// The same known voxels with bit-identical log-odds.
inline bool same_map(const OccupancyGrid3D& a, const OccupancyGrid3D& b) {
  if (a.num_known_voxels() != b.num_known_voxels()) return false;
  bool same = true;
  a.for_each_known([&](const CellKey<3>& k, float l) { same = same && b.log_odds_at_key(k) == l; });
  return same;
}

}  // namespace probslam::test_support
