#pragma once
#include <cmath>

namespace probslam {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kTwoPi = 2.0 * kPi;

/// Wraps an angle (radians) to (-pi, pi]. Angles already in range are returned unchanged,
/// bit for bit, so wrapping is idempotent.
inline double wrap_angle(double angle) {
  if (angle > -kPi && angle <= kPi) return angle;
  double r = std::fmod(angle + kPi, kTwoPi);  // in (-2pi, 2pi)
  if (r <= 0.0) r += kTwoPi;                  // in (0, 2pi]
  return r - kPi;
}

}  // namespace probslam
