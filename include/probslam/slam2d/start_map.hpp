#pragma once
// A saved map a SLAM run starts from (`probslam slam --map`): what makes one usable, shared by
// the classes that can start on one (SubmapSlam2D through its frontend, GridFastSlam).
#include <Eigen/Core>

#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

/// std::invalid_argument naming `map` unless it has `resolution` (the run's cells must be the
/// map's) and at least one cell more likely occupied than free (else nothing to match against),
/// or naming `initial_pose` unless it is finite and its position lies on the map.
void check_start_map(const OccupancyGrid2D& map, double resolution, const Eigen::Vector3d& initial_pose);

/// The extent (xmin, ymin, xmax, ymax) of the map's cells more likely occupied than free; an
/// empty box (min > max) when there is none.
Eigen::Vector4d occupied_bounds(const OccupancyGrid2D& map);

}  // namespace probslam
