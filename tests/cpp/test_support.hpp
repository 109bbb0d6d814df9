#pragma once
// Helpers shared by the C++ test files.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "probslam/grid/occupancy_grid_3d.hpp"

namespace probslam::test_support {

/// A wall of a simulated world: its two end points (m).
using Segment = std::pair<Eigen::Vector2d, Eigen::Vector2d>;

/// A 10 x 8 m room with a box and a slanted wall, so that scans pin the pose.
inline std::vector<Segment> room_walls() {
  const double w[][4] = {{-5, -4, 5, -4}, {5, -4, 5, 4}, {5, 4, -5, 4}, {-5, 4, -5, -4}, {1, 1, 2, 1},
                         {2, 1, 2, 2},    {2, 2, 1, 2},  {1, 2, 1, 1},  {-3, -2, -1, -3}};
  std::vector<Segment> out;
  for (const auto& s : w) out.push_back({{s[0], s[1]}, {s[2], s[3]}});
  return out;
}

/// The exact range from `pose` along each beam (heading + angles[k]) to the nearest of `walls`;
/// inf where a beam meets none: a laser scan of a polygon world, for the scan matchers' tests.
inline Eigen::VectorXd cast(const Eigen::Vector3d& pose, const Eigen::VectorXd& angles,
                            const std::vector<Segment>& walls) {
  Eigen::VectorXd out = Eigen::VectorXd::Constant(angles.size(), std::numeric_limits<double>::infinity());
  for (Eigen::Index k = 0; k < angles.size(); ++k) {
    const Eigen::Vector2d d(std::cos(pose.z() + angles[k]), std::sin(pose.z() + angles[k]));
    for (const auto& [p, q] : walls) {
      const Eigen::Vector2d e = q - p, w = p - pose.head<2>();
      const double det = d.x() * -e.y() - d.y() * -e.x();
      if (std::abs(det) < 1e-12) continue;  // a beam parallel to the wall
      const double t = (w.x() * -e.y() - w.y() * -e.x()) / det;
      const double u = (d.x() * w.y() - d.y() * w.x()) / det;
      if (t > 0 && u >= 0 && u <= 1) out[k] = std::min(out[k], t);
    }
  }
  return out;
}

/// The message of the std::invalid_argument `call` throws; a test failure and "" when it throws none.
inline std::string expect_invalid(const std::function<void()>& call) {
  try {
    call();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  ADD_FAILURE() << "no std::invalid_argument thrown";
  return "";
}

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
