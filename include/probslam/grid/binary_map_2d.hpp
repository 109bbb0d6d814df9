#pragma once
// A binary occupancy map on an OccupancyGrid2D lattice: what forward sensor models (ch. 6.3)
// and MAP occupancy mapping (ch. 9.4) see.
#include <cstdint>
#include <vector>

#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

/// width x height cells on a GridLattice2D, row-major like OccupancyGrid2D: cell (row, col) is
/// occupied[row * width + col] != 0.
class BinaryMap2D {
 public:
  /// The geometry of `grid` with the given occupancy (width * height entries, row-major).
  BinaryMap2D(const OccupancyGrid2D& grid, std::vector<std::uint8_t> occupied);
  /// `grid` thresholded: a cell is occupied iff its probability exceeds 0.5 (log-odds > 0).
  static BinaryMap2D thresholded(const OccupancyGrid2D& grid);

  const GridLattice2D& lattice() const { return lattice_; }
  int width() const { return width_; }
  int height() const { return height_; }
  bool occupied(std::size_t index) const { return occupied_[index] != 0; }
  void set(std::size_t index, bool occupied) { occupied_[index] = occupied; }
  const std::vector<std::uint8_t>& cells() const { return occupied_; }

 private:
  GridLattice2D lattice_;
  int width_ = 0, height_ = 0;
  std::vector<std::uint8_t> occupied_;
};

}  // namespace probslam
