#pragma once
// A uniform hash grid over 2-D points, for "which points lie near here" in O(1) per query.
#include <Eigen/Core>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace probslam {

class SpatialHash2D {
 public:
  /// cell_size (m) should be about the typical query radius. Points and queries must be finite.
  explicit SpatialHash2D(double cell_size);

  void clear() { cells_.clear(); }
  void insert(int id, double x, double y);
  /// Ids of the points within `radius` of (x, y), appended to `out` in no particular order.
  /// `points` holds the coordinates the ids were inserted with, as rows (id -> row id).
  void query(double x, double y, double radius, const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2,
             Eigen::RowMajor>>& points, std::vector<int>& out) const;
  double cell_size() const { return cell_; }

 private:
  // Unsigned arithmetic: no overflow for any cell index (distinct cells may share a key; queries
  // check the distance of every point they return).
  static std::int64_t key(std::int64_t cx, std::int64_t cy) {
    return static_cast<std::int64_t>((static_cast<std::uint64_t>(cx) << 32) ^ (static_cast<std::uint64_t>(cy) & 0xffffffffu));
  }
  /// Cell index of coordinate v, clamped so the conversion to an integer is defined.
  std::int64_t cell_of(double v) const;
  double cell_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

}  // namespace probslam
