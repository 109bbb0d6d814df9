#pragma once
// First-order propagation of covariance through planar pose composition and inversion, the
// Jacobians the submap graph's constraints and the scan matcher's frames need.
#include <Eigen/Core>

namespace probslam {

/// blockdiag(R(theta), 1): rotates a covariance (x, y, theta) between frames.
Eigen::Matrix3d frame_rotation(double theta);

/// Jacobians of a (+) b (Pose2::compose of (x, y, theta) vectors) with respect to a and to b.
void compose_jacobians(const Eigen::Vector3d& a, const Eigen::Vector3d& b, Eigen::Matrix3d& d_a, Eigen::Matrix3d& d_b);

/// Covariance of a (+) b for independent a (covariance Sa) and b (Sb), symmetrised.
Eigen::Matrix3d compose_covariance(const Eigen::Vector3d& a, const Eigen::Matrix3d& Sa, const Eigen::Vector3d& b,
                                   const Eigen::Matrix3d& Sb);

/// Jacobian of the inverse pose a^-1 = (-R^T t, -theta) with respect to a.
Eigen::Matrix3d inverse_jacobian(const Eigen::Vector3d& a);

}  // namespace probslam
