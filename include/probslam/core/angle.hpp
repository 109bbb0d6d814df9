#pragma once
#include <cmath>

namespace probslam {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kTwoPi = 2.0 * kPi;

/// Wraps an angle (radians) to (-pi, pi]. Angles already in range are returned unchanged,
/// bit for bit, so wrapping is idempotent.
inline double wrap_angle(double angle) {
  if (angle > -kPi && angle <= kPi) return angle;
  // Differences of two wrapped angles are at most one turn out: avoid fmod for them.
  const double once = angle > 0.0 ? angle - kTwoPi : angle + kTwoPi;
  if (once > -kPi && once <= kPi) return once;
  double r = std::fmod(angle + kPi, kTwoPi);  // in (-2pi, 2pi)
  if (r <= 0.0) r += kTwoPi;                  // in (0, 2pi]
  return r - kPi;
}

}  // namespace probslam
