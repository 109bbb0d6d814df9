#include "probslam/core/spatial_hash_2d.hpp"

#include <algorithm>
#include <cmath>

#include "probslam/core/check.hpp"

namespace probslam {

SpatialHash2D::SpatialHash2D(double cell_size) : cell_(cell_size) { require_positive(cell_size, "cell_size"); }

namespace {
// 2^40 cells each way: far more than any map, far less than int64's range.
constexpr double kMaxCellIndex = 1099511627776.0;
}  // namespace

std::int64_t SpatialHash2D::cell_index(double v) const {
  const double c = std::floor(v / cell_);
  if (std::isnan(c)) return 0;
  return static_cast<std::int64_t>(std::clamp(c, -kMaxCellIndex, kMaxCellIndex));
}

void SpatialHash2D::insert(int id, double x, double y) { cells_[key(cell_index(x), cell_index(y))].push_back(id); }

void SpatialHash2D::query(double x, double y, double radius,
                          const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& points,
                          std::vector<int>& out) const {
  const double r2 = radius * radius;
  const auto near = [&](int id) {
    const double dx = points(id, 0) - x, dy = points(id, 1) - y;
    return dx * dx + dy * dy <= r2;
  };
  const double span = 2.0 * radius / cell_ + 2.0;
  if (!std::isfinite(radius) || span * span > static_cast<double>(cells_.size())) {
    for (const auto& cell : cells_)  // fewer occupied cells than the query box covers
      for (int id : cell.second)
        if (near(id)) out.push_back(id);
    return;
  }
  const std::int64_t lo_x = cell_index(x - radius), hi_x = cell_index(x + radius);
  const std::int64_t lo_y = cell_index(y - radius), hi_y = cell_index(y + radius);
  for (std::int64_t cx = lo_x; cx <= hi_x; ++cx) {
    for (std::int64_t cy = lo_y; cy <= hi_y; ++cy) {
      const auto it = cells_.find(key(cx, cy));
      if (it == cells_.end()) continue;
      for (int id : it->second)
        if (near(id)) out.push_back(id);
    }
  }
}

}  // namespace probslam
