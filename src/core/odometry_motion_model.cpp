#include "probslam/core/odometry_motion_model.hpp"

#include <cmath>

#include "probslam/core/check.hpp"

namespace probslam {

void OdometryMotionNoise::validate() const {
  const double a[4] = {alpha1, alpha2, alpha3, alpha4};
  const char* names[4] = {"alpha1", "alpha2", "alpha3", "alpha4"};
  for (int i = 0; i < 4; ++i) require(std::isfinite(a[i]) && a[i] >= 0.0, names[i], "must be finite and >= 0");
}

OdometryMotion OdometryMotion::between(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  require_all_finite(from, "from");
  require_all_finite(to, "to");
  OdometryMotion u;
  const double dx = to.x() - from.x(), dy = to.y() - from.y();
  u.trans = std::hypot(dx, dy);
  u.rot1 = u.trans < kPureRotationBelow ? 0.0 : wrap_angle(std::atan2(dy, dx) - from.z());
  u.rot2 = wrap_angle(to.z() - from.z() - u.rot1);
  return u;
}

double odometry_motion_log_density(const Eigen::Vector3d& from, const Eigen::Vector3d& to, const OdometryMotion& u,
                                   const OdometryMotionNoise& noise) {
  noise.validate();
  require(std::isfinite(u.rot1) && std::isfinite(u.trans) && std::isfinite(u.rot2), "u", "must be finite");
  const OdometryMotion hat = OdometryMotion::between(from, to);
  const Eigen::Vector3d var = u.variances(noise);
  require((var.array() > 0.0).all(), "noise", "gives a zero variance for this motion (the density is a Dirac)");
  const Eigen::Vector3d err(wrap_angle(u.rot1 - hat.rot1), u.trans - hat.trans, wrap_angle(u.rot2 - hat.rot2));
  double log_p = 0.0;
  for (int i = 0; i < 3; ++i) log_p += -0.5 * (err[i] * err[i] / var[i] + std::log(kTwoPi * var[i]));
  return log_p;
}

}  // namespace probslam
