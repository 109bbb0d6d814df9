#include "probslam/core/so3.hpp"

#include <Eigen/SVD>
#include <cmath>

namespace probslam {
namespace {

// Below this angle (rad) the closed forms lose digits to cancellation and their Taylor series
// are used instead; the series' first omitted terms are O(angle^4) ~ 1e-16 there.
constexpr double kSmallAngle = 1e-4;

}  // namespace

Eigen::Quaterniond so3_exp(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  // sin(angle / 2) / angle, exact to rounding by its series at small angles.
  const double s = angle < kSmallAngle ? 0.5 - angle * angle / 48.0 : std::sin(0.5 * angle) / angle;
  Eigen::Quaterniond q(std::cos(0.5 * angle), s * w.x(), s * w.y(), s * w.z());
  q.normalize();
  return q;
}

Eigen::Vector3d so3_log(const Eigen::Quaterniond& q_in) {
  // q and -q are the same rotation: take w >= 0 so that the angle is in [0, pi].
  const Eigen::Quaterniond q = q_in.w() < 0.0 ? Eigen::Quaterniond(-q_in.coeffs()) : q_in;
  const double n = q.vec().norm();
  if (n < kSmallAngle * kSmallAngle) return 2.0 * q.vec() / q.w();  // atan2(n, w) / n -> 1 / w
  return (2.0 * std::atan2(n, q.w()) / n) * q.vec();
}

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return m;
}

Eigen::Matrix3d so3_right_jacobian_inverse(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  const Eigen::Matrix3d k = skew(w);
  // 1/angle^2 - (1 + cos) / (2 angle sin), whose series is 1/12 + angle^2 / 720 + ...
  const double c = angle < kSmallAngle
                       ? 1.0 / 12.0 + angle * angle / 720.0
                       : 1.0 / (angle * angle) - (1.0 + std::cos(angle)) / (2.0 * angle * std::sin(angle));
  return Eigen::Matrix3d::Identity() + 0.5 * k + c * k * k;
}

Eigen::Matrix3d project_to_rotation(const Eigen::Matrix3d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

}  // namespace probslam
