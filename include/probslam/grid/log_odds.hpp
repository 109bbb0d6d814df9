#pragma once
// Log-odds arithmetic of ch. 9.2 (eq. 9.5-9.7) and the clamping bounds OctoMap popularised.
#include <algorithm>
#include <cmath>
#include <limits>

namespace probslam {

/// log(p / (1 - p)), eq. 9.5 / 9.7.
inline double logit(double p) { return std::log(p / (1.0 - p)); }

/// Largest |log-odds| accepted as a model value (l0, l_occ, l_free). Probabilities saturate in
/// double beyond |l| ~ 37, so nothing meaningful is refused; the bound keeps unclamped sums
/// finite: a cell would need 1e302 updates to overflow.
constexpr double kMaxLogOddsValue = 1e6;

/// Throws std::invalid_argument naming `name` unless |l| <= kMaxLogOddsValue (NaN included).
void require_log_odds(double l, const char* name);

/// Occupancy probability from log-odds, eq. 9.6.
inline double probability_from_log_odds(double l) { return 1.0 - 1.0 / (1.0 + std::exp(l)); }

/// Bounds on a cell's log-odds after every update; disabled means the textbook update.
struct LogOddsClamp {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool enabled = false;

  static LogOddsClamp none() { return {}; }
  static LogOddsClamp from_probabilities(double p_min, double p_max) {
    return {logit(p_min), logit(p_max), true};
  }
  double apply(double l) const { return enabled ? std::min(std::max(l, min), max) : l; }
};

}  // namespace probslam
