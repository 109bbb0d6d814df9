#include "probslam/slam2d/start_map.hpp"

#include <limits>
#include <string>

#include "probslam/core/check.hpp"

namespace probslam {

void check_start_map(const OccupancyGrid2D& map, double resolution, const Eigen::Vector3d& initial_pose) {
  if (map.resolution() != resolution)
    throw_invalid_argument("map", "has resolution " + std::to_string(map.resolution()) + " m, the run " +
                                      std::to_string(resolution) + " m: give the run the map's resolution");
  const Eigen::Vector4d occupied = occupied_bounds(map);
  require(occupied[0] <= occupied[2], "map", "has no occupied cell: there is nothing to match the first scan against");
  require(initial_pose.allFinite(), "initial_pose", "must be finite");
  const Eigen::Vector2d lo = map.origin();
  const Eigen::Vector2d hi = lo + map.resolution() * Eigen::Vector2d(map.width(), map.height());
  const bool on_map = initial_pose.x() >= lo.x() && initial_pose.x() < hi.x() && initial_pose.y() >= lo.y() &&
                      initial_pose.y() < hi.y();
  if (!on_map)
    throw_invalid_argument("initial_pose", "(" + std::to_string(initial_pose.x()) + ", " +
                                               std::to_string(initial_pose.y()) + ") lies outside the map [" +
                                               std::to_string(lo.x()) + ", " + std::to_string(hi.x()) + "] x [" +
                                               std::to_string(lo.y()) + ", " + std::to_string(hi.y()) + "] m");
}

Eigen::Vector4d occupied_bounds(const OccupancyGrid2D& map) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
  const double res = map.resolution();
  for (int row = 0; row < map.height(); ++row)
    for (int col = 0; col < map.width(); ++col)
      if (map.data()[static_cast<std::size_t>(row) * map.width() + col] > 0.0) {
        const Eigen::Vector2d corner = map.origin() + res * Eigen::Vector2d(col, row);
        lo = lo.cwiseMin(corner);
        hi = hi.cwiseMax(corner + Eigen::Vector2d::Constant(res));
      }
  return {lo.x(), lo.y(), hi.x(), hi.y()};
}

}  // namespace probslam
