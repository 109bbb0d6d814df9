#include "probslam/core/check.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

// Eq. 9.9: max over probabilities equals max over log-odds, which is monotone.
void fuse_max_into(OccupancyGrid2D& fused, const OccupancyGrid2D& other) {
  require(other.same_geometry(fused), "grids", "must all have the same resolution, size and origin");
  fused.log_odds() = fused.log_odds().cwiseMax(other.log_odds());
}

OccupancyGrid2D fuse_max(const std::vector<const OccupancyGrid2D*>& grids) {
  require(!grids.empty(), "grids", "must not be empty");
  for (const OccupancyGrid2D* g : grids) require(g != nullptr, "grids", "must not contain None");
  OccupancyGrid2D fused = *grids.front();
  for (const OccupancyGrid2D* g : grids) fuse_max_into(fused, *g);
  return fused;
}

}  // namespace probslam
