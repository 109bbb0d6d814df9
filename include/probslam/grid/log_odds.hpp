#pragma once
// Log-odds arithmetic of ch. 9.2 (eq. 9.5-9.7) and the clamping bounds OctoMap popularised.
#include <algorithm>
#include <cmath>
#include <limits>

namespace probslam {

/// log(p / (1 - p)), eq. 9.5 / 9.7.
inline double logit(double p) { return std::log(p / (1.0 - p)); }

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
