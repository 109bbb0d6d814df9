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

/// Whether landmark (m_x, m_y) lies in a sensor's field seen from pose: within `range` (m) and
/// within fov / 2 (rad) of the heading either way. Where negative information (a landmark in view
/// and not seen) applies.
inline bool in_sensor_field(const Eigen::Vector3d& pose, const Eigen::Vector2d& landmark, double range, double fov) {
  const Eigen::Vector2d d = landmark - pose.head<2>();
  return d.squaredNorm() <= range * range && std::abs(wrap_angle(std::atan2(d.y(), d.x()) - pose[2])) <= 0.5 * fov;
}

}  // namespace probslam
