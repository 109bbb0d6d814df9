#include "probslam/core/check.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

// Eq. 9.9: max over probabilities equals max over log-odds, which is monotone.
OccupancyGrid2D fuse_max(const std::vector<const OccupancyGrid2D*>& grids) {
  require(!grids.empty(), "grids", "must not be empty");
  for (const OccupancyGrid2D* g : grids) require(g != nullptr, "grids", "must not contain None");
  OccupancyGrid2D fused = *grids.front();
  for (const OccupancyGrid2D* g : grids) {
    require(g->same_geometry(fused), "grids", "must all have the same resolution, size and origin");
    fused.log_odds() = fused.log_odds().cwiseMax(g->log_odds());
  }
  return fused;
}

}  // namespace probslam
