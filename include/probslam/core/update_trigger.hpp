#pragma once
// When a filter or a scan matcher works on a scan: once the robot has moved this far or turned
// this much since it last did (ROS AMCL's update_min_d / update_min_a, GMapping's
// linearUpdate / angularUpdate). One struct for SubmapSlam2D's frontend (a scan is matched),
// GridFastSlam (the particles are updated) and MonteCarloLocalization (the particles are
// updated), so the concept has one name everywhere.
#include <cmath>

#include "probslam/core/check.hpp"

namespace probslam {

struct UpdateTrigger {
  double distance = 0.0;  ///< m
  double angle = 0.0;     ///< rad

  /// Whether a travel of `travelled` metres or a turn of `turned` radians (both >= 0) since the
  /// last update calls for the next.
  bool reached(double travelled, double turned) const { return travelled >= distance || turned >= angle; }

  /// std::invalid_argument naming the field ("distance must be finite and >= 0").
  void validate() const {
    require(std::isfinite(distance) && distance >= 0.0, "distance", "must be finite and >= 0");
    require(std::isfinite(angle) && angle >= 0.0, "angle", "must be finite and >= 0");
  }

  template <class V>
  static void describe(V& v) {
    v("distance", &UpdateTrigger::distance, "m", "travel since the last update that calls for the next");
    v("angle", &UpdateTrigger::angle, "rad", "turn since the last update that calls for the next");
  }
};

}  // namespace probslam
