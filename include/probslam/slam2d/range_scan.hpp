#pragma once
// One laser scan as the scan matcher and the submaps use it: hit points in the sensor frame,
// and the ranges the grid update takes, with every invalid reading made "no return".
#include <Eigen/Core>
#include <limits>
#include <string>

#include "probslam/core/filter_limits.hpp"
#include "probslam/core/options_description.hpp"
#include "probslam/core/types.hpp"

namespace probslam {

/// How raw readings become hits. A reading r is a hit when it is finite and
/// 0 < r, min_range <= r and r < min(max_range, max_usable_range). Readings at or beyond the
/// sensor's maximum, inf and NaN are "no return": they never hit, and (clear_no_return) clear
/// free space up to the usable range, as do hits beyond the usable range. Negative readings
/// and readings below min_range are dropped.
struct ScanFilter {
  double max_range = std::numeric_limits<double>::infinity();  ///< sensor maximum, m
  double min_range = 0.0;  ///< closer readings (the robot's own body) are dropped, m
  /// Hits farther than this are not used (the error of a point grows with its range); they
  /// clear free space up to this range instead, m.
  double max_usable_range = 30.0;
  bool clear_no_return = true;  ///< no-return beams clear free space up to the usable range
  /// Voxel-style decimation: consecutive hits closer than this to the last kept one are
  /// dropped (0 keeps every hit), m.
  double min_point_spacing = 0.0;

  /// Throws std::invalid_argument naming the field when a value is out of range.
  void validate() const;
  double usable_range() const { return max_range < max_usable_range ? max_range : max_usable_range; }

  template <class V>
  static void describe(V& v) {
    using O = ScanFilter;
    v("max_range", &O::max_range, "m", "the sensor's maximum: readings at or beyond it (inf, NaN) are no returns");
    v("min_range", &O::min_range, "m", "closer readings (the robot's own body) are dropped");
    v("max_usable_range", &O::max_usable_range, "m", "farther hits are not used; they clear free space up to it");
    v("clear_no_return", &O::clear_no_return, "", "no-return beams clear free space up to the usable range");
    v("min_point_spacing", &O::min_point_spacing, "m", "hits closer than this to the last kept one are dropped (0: keep all)");
  }
};

/// The per-scan checks every laser SLAM class's add_scan makes: ranges non-empty and as long as
/// beam_angles, beam_angles finite, odometry finite with |x|, |y| <= kMaxCoordinate (core/filter_limits.hpp), timestamp
/// finite. std::invalid_argument naming the argument: add_scan's (`odometry`), or with row >= 0
/// add_scans' row (`odometry[3]`, `timestamps[3]`).
void check_scan_input(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                      const Eigen::Vector3d& odometry, double timestamp, long row = -1);

/// The name of a scan argument in a message: `single` for add_scan, `batch[row]` for add_scans.
std::string scan_arg_name(const char* single, const char* batch, long row);

/// Hit points of one scan in the sensor frame, (N, 2) metres, after the filter.
/// ranges and beam_angles (rad, relative to the sensor heading) have equal length.
Points2 scan_hits(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                  const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const ScanFilter& filter);

/// The ranges to give OccupancyGrid2D::insert_rays with max_range = usable_range():
/// hits stay, no-return beams and far hits become usable_range() (clear only) or NaN (skipped)
/// without clear_no_return, dropped readings become NaN.
Eigen::VectorXd ranges_for_insertion(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                     const ScanFilter& filter);

}  // namespace probslam
