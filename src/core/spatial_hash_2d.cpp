#include "probslam/core/spatial_hash_2d.hpp"

#include <algorithm>
#include <cmath>

#include "probslam/core/check.hpp"

namespace probslam {

SpatialHash2D::SpatialHash2D(double cell_size) : cell_(cell_size) { require_positive(cell_size, "cell_size"); }

namespace {
// Cell indices are clamped to +-2^40: far inside int64 (so key() and the query loops cannot
// overflow), and far beyond any map (2^40 cells of 1 um span 1000 km).
constexpr double kMaxCellIndex = 1099511627776.0;
}  // namespace

std::int64_t SpatialHash2D::cell_of(double v) const {
  if (std::isnan(v)) return 0;  // a NaN query finds nothing (its distance test fails)
  return static_cast<std::int64_t>(std::clamp(std::floor(v / cell_), -kMaxCellIndex, kMaxCellIndex));
}

void SpatialHash2D::insert(int id, double x, double y) {
  require(std::isfinite(x) && std::isfinite(y), "point", "must be finite");
  cells_[key(cell_of(x), cell_of(y))].push_back(id);
}

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
  const std::int64_t lo_x = cell_of(x - radius), hi_x = cell_of(x + radius);
  const std::int64_t lo_y = cell_of(y - radius), hi_y = cell_of(y + radius);
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
