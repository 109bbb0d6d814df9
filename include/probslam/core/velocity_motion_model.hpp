#pragma once
// The noise-free velocity motion model g(u, x) of eq. 10.11 / Table 10.1 lines 3-4.
#include <Eigen/Core>

namespace probslam {

/// Pose (x, y, theta) after driving with translational velocity v (m/s) and rotational
/// velocity w (rad/s) for dt seconds along a circular arc (a straight line when w = 0).
/// Exact and continuous across w = 0: the arc is written with sinc(w dt / 2), never v / w.
/// The returned heading is wrapped to (-pi, pi]. Throws std::invalid_argument on non-finite
/// input or dt <= 0.
Eigen::Vector3d velocity_motion(const Eigen::Vector3d& pose, double v, double w, double dt);

/// G = dg/dx (3x3), Table 10.1 line 4 with its signs corrected (checked by finite differences).
Eigen::Matrix3d velocity_motion_jacobian(const Eigen::Vector3d& pose, double v, double w, double dt);

/// V = dg/du (3x2) with respect to the control u = (v, w), for control-space noise M: R = V M V^T.
Eigen::Matrix<double, 3, 2> velocity_motion_control_jacobian(const Eigen::Vector3d& pose, double v,
                                                             double w, double dt);

}  // namespace probslam
