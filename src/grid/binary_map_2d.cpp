#include "probslam/grid/binary_map_2d.hpp"

#include <string>
#include <utility>

#include "probslam/core/check.hpp"

namespace probslam {

BinaryMap2D::BinaryMap2D(const OccupancyGrid2D& grid, std::vector<std::uint8_t> occupied)
    : lattice_(grid.lattice()), width_(grid.width()), height_(grid.height()), occupied_(std::move(occupied)) {
  require(occupied_.size() == static_cast<std::size_t>(width_) * height_, "occupied",
          "must have one entry per grid cell (height x width)");
  for (auto& v : occupied_) v = v != 0;
}

BinaryMap2D BinaryMap2D::thresholded(const OccupancyGrid2D& grid) {
  const std::size_t n = static_cast<std::size_t>(grid.width()) * grid.height();
  std::vector<std::uint8_t> occupied(n);
  for (std::size_t i = 0; i < n; ++i) occupied[i] = grid.data()[i] > 0.0;  // p > 0.5
  return BinaryMap2D(grid, std::move(occupied));
}

}  // namespace probslam
