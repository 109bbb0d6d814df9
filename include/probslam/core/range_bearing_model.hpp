#pragma once
// The range-bearing(-signature) measurement model h of eq. 10.18, its Jacobians and its inverse.
#include <Eigen/Core>

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

}  // namespace probslam
