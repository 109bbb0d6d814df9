#include "probslam/grid/inverse_range_sensor_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/grid/log_odds.hpp"

namespace probslam {

namespace {
// Directions within this angle of the blind wedge's edges take the exact path (atan2): far
// larger than the rounding of the cross products (~1e-16 rad), far smaller than any beam.
constexpr double kWedgeMargin = 1e-9;
}  // namespace

void require_log_odds(double l, const char* name) {
  require(std::fabs(l) <= kMaxLogOddsValue, name, "must be a finite log-odds of magnitude <= 1e6 (kMaxLogOddsValue)");
}

void ConeModel::validate() const {
  require_positive(z_max, "z_max");
  require(std::isfinite(alpha) && alpha >= 0.0, "alpha", "must be finite and >= 0");
  require(std::isfinite(beta) && beta >= 0.0, "beta", "must be finite and >= 0");
  require_log_odds(l0, "l0");
  require_log_odds(l_occ, "l_occ");
  require_log_odds(l_free, "l_free");
}

std::vector<std::uint8_t> valid_readings(const Eigen::Ref<const Eigen::VectorXd>& ranges) {
  std::vector<std::uint8_t> valid(static_cast<std::size_t>(ranges.size()));
  for (Eigen::Index j = 0; j < ranges.size(); ++j)
    valid[j] = std::isfinite(ranges[j]) && ranges[j] >= 0.0;
  return valid;
}

namespace {
const Eigen::Ref<const Eigen::VectorXd>& checked_scan(const Eigen::Vector3d& pose,
                                                      const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                                      const Eigen::Ref<const Eigen::VectorXd>& angles,
                                                      const ConeModel& model) {
  require_all_finite(pose, "pose");
  require(ranges.size() > 0, "ranges", "must not be empty");
  require(ranges.size() == angles.size(), "beam_angles", "must have the same length as ranges");
  model.validate();
  return ranges;
}
}  // namespace

ConeScan::ConeScan(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                   const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const ConeModel& model)
    : pose_(pose),
      ranges_(checked_scan(pose, ranges, beam_angles, model)),
      angles_(beam_angles),
      model_(model),
      beams_(beam_angles, valid_readings(ranges)) {
  // Line 6: r > min(z_max, z_k + alpha / 2) for every k means l0.
  double longest = -std::numeric_limits<double>::infinity();
  const std::vector<std::uint8_t> valid = valid_readings(ranges);
  for (Eigen::Index j = 0; j < ranges.size(); ++j)
    if (valid[j]) longest = std::max(longest, ranges[j] + model.alpha / 2.0);
  reach_ = std::max(0.0, std::min(model.z_max, longest));
  // Inside the widest gap between beams, farther than beta/2 from both of its edges, the
  // nearest beam is an edge beam and line 6 returns l0.
  const double blind = beams_.gap_width() - model.beta - 2.0 * kWedgeMargin;
  if (!beams_.empty() && blind > 0.0) {
    const double from = pose[2] + beams_.gap_start() + model.beta / 2.0 + kWedgeMargin;
    const double to = from + blind;
    has_blind_wedge_ = true;
    blind_wedge_reflex_ = blind > kPi;
    wedge_from_[0] = std::cos(from), wedge_from_[1] = std::sin(from);
    wedge_to_[0] = std::cos(to), wedge_to_[1] = std::sin(to);
  }
}

bool ConeScan::in_blind_wedge(double dx, double dy) const {
  if (!has_blind_wedge_) return false;
  const double after_from = wedge_from_[0] * dy - wedge_from_[1] * dx;  // > 0: ccw of `from`
  const double before_to = dx * wedge_to_[1] - dy * wedge_to_[0];        // > 0: cw of `to`
  return blind_wedge_reflex_ ? (after_from > 0.0 || before_to > 0.0) : (after_from > 0.0 && before_to > 0.0);
}

// Table 9.2 lines 2-12 (line 8 corrected: |r - z_k| < alpha / 2).
double ConeScan::operator()(double cx, double cy) const {
  const double dx = cx - pose_[0], dy = cy - pose_[1];
  const double r = std::sqrt(dx * dx + dy * dy);
  if (r > reach_ || in_blind_wedge(dx, dy)) return model_.l0;  // implied by line 6 whatever k is
  const double phi = std::atan2(dy, dx) - pose_[2];
  const BeamIndex::Nearest nearest = beams_.nearest(phi);
  if (nearest.index < 0) return model_.l0;
  const double z_k = ranges_[nearest.index];
  const double half_alpha = model_.alpha / 2.0;
  if (r > std::min(model_.z_max, z_k + half_alpha) || nearest.distance > model_.beta / 2.0) return model_.l0;
  if (z_k < model_.z_max && std::fabs(r - z_k) < half_alpha) return model_.l_occ;
  if (r <= z_k) return model_.l_free;
  return model_.l0;
}

Eigen::VectorXd inverse_range_sensor_model(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& cells,
    const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
    const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const ConeModel& model) {
  require_all_finite(cells, "cells");
  const ConeScan scan(pose, ranges, beam_angles, model);
  Eigen::VectorXd out(cells.rows());
  for (Eigen::Index i = 0; i < cells.rows(); ++i) out[i] = scan(cells(i, 0), cells(i, 1));
  return out;
}

}  // namespace probslam
