#pragma once
// First-order propagation of covariance through planar pose composition and inversion, the
// Jacobians the submap graph's constraints, the scan matcher's frames and the motion models need.
#include <Eigen/Core>

namespace probslam {

/// d(x (+) step) / d x for a step whose translation, turned into the world by x's heading, is
/// `turned`: the identity but for the heading column (-turned.y, turned.x, 1), since turning x
/// swings the step about x's position. The motion models' G (Table 10.1 line 4's form), the
/// composition's first Jacobian, a lever arm carrying a heading's spread.
inline Eigen::Matrix3d heading_jacobian(const Eigen::Vector2d& turned) {
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();
  g(0, 2) = -turned.y();
  g(1, 2) = turned.x();
  return g;
}

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
