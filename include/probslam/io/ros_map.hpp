#pragma once
// ROS map_server maps: a YAML description beside a PGM picture (ROS 1 map_server / Nav2).
#include <string>

#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

struct RosMapOptions {
  double occupied_thresh = 0.65;  // p above: occupied (map_saver's defaults)
  double free_thresh = 0.196;     // p below: free
};

/// Writes `yaml_path` and a trinary P5 PGM beside it (same stem, ".pgm"): 0 occupied,
/// 254 free, 205 unknown; image row 0 is the top (largest y) of the map.
void save_ros_map(const OccupancyGrid2D& grid, const std::string& yaml_path,
                  const RosMapOptions& options = {});

/// Reads a map_server map (modes trinary and scale; negate 0/1; P5 or P2 PGM). Occupied and
/// free cells take the log-odds of the default clamping bounds (0.971 and 0.1192), unknown
/// cells the prior (p = 0.5); in scale mode known cells keep their probability, clamped to
/// the same bounds. Rotated origins (yaw != 0) are refused. Errors name the file and line.
OccupancyGrid2D load_ros_map(const std::string& yaml_path);

}  // namespace probslam
