#include "probslam/slam2d/range_scan.hpp"

#include <cmath>
#include <string>
#include <vector>

#include "probslam/core/check.hpp"

namespace probslam {

void ScanFilter::validate() const {
  require(!std::isnan(max_range) && max_range > 0.0, "max_range", "must be > 0 (inf: no maximum)");
  require(std::isfinite(min_range) && min_range >= 0.0, "min_range", "must be finite and >= 0");
  require(std::isfinite(max_usable_range) && max_usable_range > 0.0, "max_usable_range",
          "must be finite and > 0");
  require(min_range < usable_range(), "min_range", "must be below max_range and max_usable_range");
  require(std::isfinite(min_point_spacing) && min_point_spacing >= 0.0, "min_point_spacing",
          "must be finite and >= 0");
}

namespace {

bool is_hit(double r, const ScanFilter& f) { return r >= f.min_range && r < f.usable_range() && r > 0.0; }

void require_scan(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                  const Eigen::Ref<const Eigen::VectorXd>& beam_angles) {
  require(ranges.size() == beam_angles.size(), "beam_angles", "must have one angle per range");
  require_all_finite(beam_angles, "beam_angles");
}

}  // namespace

std::string scan_arg_name(const char* single, const char* batch, long row) {
  return row < 0 ? std::string(single) : std::string(batch) + "[" + std::to_string(row) + "]";
}

void check_scan_input(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                      const Eigen::Vector3d& odometry, double timestamp, long row) {
  if (ranges.size() == 0) throw_invalid_argument(scan_arg_name("ranges", "ranges", row), "must not be empty");
  if (ranges.size() != beam_angles.size())
    throw_invalid_argument(scan_arg_name("beam_angles", "beam_angles", row), "must have one angle per range");
  if (!beam_angles.allFinite())
    throw_invalid_argument(scan_arg_name("beam_angles", "beam_angles", row), "must contain only finite values");
  const std::string odo = scan_arg_name("odometry", "odometry", row);
  if (!odometry.allFinite()) throw_invalid_argument(odo, "must contain only finite values");
  // Rule: bounded sizes; a pose beyond this would grow a map (or a covariance) past its limit.
  if (odometry.head<2>().cwiseAbs().maxCoeff() > kMaxCoordinate)
    throw_invalid_argument(odo, "coordinates must be <= 1e9 m");
  if (!std::isfinite(timestamp)) throw_invalid_argument(scan_arg_name("timestamp", "timestamps", row), "must be finite");
}

Points2 scan_hits(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                  const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const ScanFilter& filter) {
  filter.validate();
  require_scan(ranges, beam_angles);
  std::vector<Eigen::Vector2d> kept;
  kept.reserve(static_cast<std::size_t>(ranges.size()));
  const double spacing_sq = filter.min_point_spacing * filter.min_point_spacing;
  for (Eigen::Index i = 0; i < ranges.size(); ++i) {
    if (!is_hit(ranges[i], filter)) continue;
    const Eigen::Vector2d p(ranges[i] * std::cos(beam_angles[i]), ranges[i] * std::sin(beam_angles[i]));
    if (!kept.empty() && spacing_sq > 0.0 && (p - kept.back()).squaredNorm() < spacing_sq) continue;
    kept.push_back(p);
  }
  Points2 out(static_cast<Eigen::Index>(kept.size()), 2);
  for (std::size_t i = 0; i < kept.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = kept[i].transpose();
  return out;
}

Eigen::VectorXd ranges_for_insertion(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                     const ScanFilter& filter) {
  filter.validate();
  const double nan = std::nan("");
  const double clear = filter.clear_no_return ? filter.usable_range() : nan;
  Eigen::VectorXd out(ranges.size());
  for (Eigen::Index i = 0; i < ranges.size(); ++i) {
    const double r = ranges[i];
    if (is_hit(r, filter))
      out[i] = r;
    else if (std::isnan(r) || r >= filter.usable_range())
      out[i] = clear;  // no return, or a hit too far to trust: free space only, never a hit
    else
      out[i] = nan;  // negative or closer than min_range: the robot's body or an error
  }
  return out;
}

}  // namespace probslam
