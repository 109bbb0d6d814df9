#include "probslam/core/pose2_covariance.hpp"

#include <cmath>

#include "probslam/core/pose2.hpp"

namespace probslam {

Eigen::Matrix3d frame_rotation(double theta) {
  Eigen::Matrix3d J = Eigen::Matrix3d::Identity();
  J.topLeftCorner<2, 2>() = rotation_matrix(theta);
  return J;
}

void compose_jacobians(const Eigen::Vector3d& a, const Eigen::Vector3d& b, Eigen::Matrix3d& d_a, Eigen::Matrix3d& d_b) {
  d_a = heading_jacobian(rotation_matrix(a.z()) * b.head<2>());
  d_b = frame_rotation(a.z());
}

Eigen::Matrix3d compose_covariance(const Eigen::Vector3d& a, const Eigen::Matrix3d& Sa, const Eigen::Vector3d& b,
                                   const Eigen::Matrix3d& Sb) {
  Eigen::Matrix3d Ja, Jb;
  compose_jacobians(a, b, Ja, Jb);
  const Eigen::Matrix3d S = Ja * Sa * Ja.transpose() + Jb * Sb * Jb.transpose();
  return 0.5 * (S + S.transpose());
}

Eigen::Matrix3d inverse_jacobian(const Eigen::Vector3d& a) {
  const double c = std::cos(a.z()), s = std::sin(a.z());
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  J.topLeftCorner<2, 2>() = -rotation_matrix(a.z()).transpose();
  J(0, 2) = s * a.x() - c * a.y();
  J(1, 2) = c * a.x() + s * a.y();
  J(2, 2) = -1.0;
  return J;
}

}  // namespace probslam
