#pragma once
// The range-bearing(-signature) measurement model h of eq. 10.18, its Jacobians and its inverse.
#include <Eigen/Core>

#include <cmath>

#include "probslam/core/angle.hpp"

namespace probslam {

/// Jacobians of h with respect to the robot pose (x, y, theta) and the landmark.
template <int M>
struct MeasurementJacobians {
  Eigen::Matrix<double, M, 3> pose;
  Eigen::Matrix<double, M, M> landmark;
};

/// z = (range [m], bearing [rad, wrapped to (-pi, pi]]) of landmark (m_x, m_y) seen from pose.
Eigen::Vector2d range_bearing(const Eigen::Vector3d& pose, const Eigen::Vector2d& landmark);
/// With signature: landmark (m_x, m_y, s) gives z = (range, bearing, s).
Eigen::Vector3d range_bearing(const Eigen::Vector3d& pose, const Eigen::Vector3d& landmark);

/// Table 10.1 line 16 with the erratum's signs. Throws std::invalid_argument when the landmark
/// coincides with the robot (the bearing is then undefined).
MeasurementJacobians<2> range_bearing_jacobians(const Eigen::Vector3d& pose,
                                                const Eigen::Vector2d& landmark);
MeasurementJacobians<3> range_bearing_jacobians(const Eigen::Vector3d& pose,
                                                const Eigen::Vector3d& landmark);

/// Table 10.1 line 10: the landmark (m_x, m_y) that measurement z = (r, phi) places.
Eigen::Vector2d landmark_from_range_bearing(const Eigen::Vector3d& pose, const Eigen::Vector2d& z);
/// Jacobians of that inverse model: .pose (2x3) and .landmark, here d m / d z (2x2).
MeasurementJacobians<2> landmark_from_range_bearing_jacobians(const Eigen::Vector3d& pose,
                                                              const Eigen::Vector2d& z);

/// range_bearing and range_bearing_jacobians in one pass (one hypot, one atan2) and without
/// their checks, for inner loops whose pose and landmark are finite and at least 1 nm apart
/// (the caller checks): the same values, bit for bit.
inline void range_bearing_unchecked(const Eigen::Vector3d& pose, const Eigen::Vector2d& landmark, Eigen::Vector2d& z,
                                    MeasurementJacobians<2>& j) {
  const double dx = landmark[0] - pose[0], dy = landmark[1] - pose[1];
  const double r = std::hypot(dx, dy);
  z << r, wrap_angle(std::atan2(dy, dx) - pose[2]);
  // Unit vector u = d / r; the 1/q terms as u / r, which cannot overflow where d^2 would.
  const double ux = dx / r, uy = dy / r;
  j.pose << -ux, -uy, 0.0,  //
      uy / r, -ux / r, -1.0;
  j.landmark << ux, uy,  //
      -uy / r, ux / r;
}

/// landmark_from_range_bearing and its Jacobians in one pass (one sincos) and without their
/// checks, for inner loops whose pose and z are finite with z's range >= 0: the same values.
inline void landmark_from_range_bearing_unchecked(const Eigen::Vector3d& pose, const Eigen::Vector2d& z,
                                                  Eigen::Vector2d& m, MeasurementJacobians<2>& j) {
  const double a = z[1] + pose[2];
  const double c = std::cos(a), s = std::sin(a);
  m << pose[0] + z[0] * c, pose[1] + z[0] * s;
  j.pose << 1.0, 0.0, -z[0] * s,  //
      0.0, 1.0, z[0] * c;
  j.landmark << c, -z[0] * s,  //
      s, z[0] * c;
}

/// Whether landmark (m_x, m_y) lies in a sensor's field seen from pose: within `range` (m) and
/// within fov / 2 (rad) of the heading either way. Where negative information (a landmark in view
/// and not seen) applies.
inline bool in_sensor_field(const Eigen::Vector3d& pose, const Eigen::Vector2d& landmark, double range, double fov) {
  const Eigen::Vector2d d = landmark - pose.head<2>();
  return d.squaredNorm() <= range * range && std::abs(wrap_angle(std::atan2(d.y(), d.x()) - pose[2])) <= 0.5 * fov;
}

}  // namespace probslam
