#pragma once
// Lossless storage of a 2-D grid: log-odds and every parameter, bit for bit.
#include <string>

#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

/// Binary little-endian file: magic "PSGRID2D", version, geometry, prior, clamp, beam model,
/// then height x width float64 log-odds, row-major.
void save_grid(const OccupancyGrid2D& grid, const std::string& path);
/// Throws std::invalid_argument on a file that is not a complete, valid grid file.
OccupancyGrid2D load_grid(const std::string& path);

}  // namespace probslam
