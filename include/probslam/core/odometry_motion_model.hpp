#pragma once
// The odometry motion model of Probabilistic Robotics ch. 5.4: a motion between two odometry
// poses is read as a first rotation rot1, a translation trans and a second rotation rot2, each
// perturbed by zero-mean Gaussian noise whose variance grows with the motion (alpha1..alpha4).
// The sampler is Table 5.6 (sample_motion_model_odometry), the density Table 5.5
// (motion_model_odometry) with prob(a, b^2) the normal density of variance b^2.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "probslam/core/angle.hpp"

namespace probslam {

/// The noise coefficients of Table 5.5 / 5.6 (dimensionless: variances of rad^2 per rad^2,
/// rad^2 per m^2, m^2 per m^2 and m^2 per rad^2).
struct OdometryMotionNoise {
  double alpha1 = 0.2;  ///< rotation noise from rotation
  double alpha2 = 0.2;  ///< rotation noise from translation
  double alpha3 = 0.2;  ///< translation noise from translation
  double alpha4 = 0.2;  ///< translation noise from rotation
  /// std::invalid_argument naming the first coefficient that is not finite and >= 0.
  void validate() const;

  template <class V>
  static void describe(V& v) {
    using O = OdometryMotionNoise;
    v("alpha1", &O::alpha1, "rad^2/rad^2", "rotation noise from rotation");
    v("alpha2", &O::alpha2, "rad^2/m^2", "rotation noise from translation");
    v("alpha3", &O::alpha3, "m^2/m^2", "translation noise from translation");
    v("alpha4", &O::alpha4, "m^2/rad^2", "translation noise from rotation");
  }
};

/// (rot1, trans, rot2) of Table 5.5 lines 2-4: rot1 = atan2(dy, dx) - theta, trans = |d|,
/// rot2 = dtheta - rot1, angles wrapped to (-pi, pi]. For a motion shorter than
/// kPureRotationBelow (m) the direction atan2(dy, dx) is the odometry's noise (a robot turning
/// on the spot reports millimetres in any direction): rot1 is then 0 and rot2 the whole turn,
/// or a turn in place would be read as rot1 ~ +-pi, rot2 ~ -+pi, with noise to match.
struct OdometryMotion {
  double rot1 = 0.0, trans = 0.0, rot2 = 0.0;
  static constexpr double kPureRotationBelow = 0.01;
  static OdometryMotion between(const Eigen::Vector3d& from, const Eigen::Vector3d& to);
  /// The motion of the relative pose `delta` (dx, dy, dtheta in the frame of the start pose).
  static OdometryMotion of_delta(const Eigen::Vector3d& delta) { return between(Eigen::Vector3d::Zero(), delta); }
  /// The variances of Table 5.6 lines 2-4: of rot1, trans and rot2. A rotation enters as its
  /// distance to the nearest of 0 and +-pi (as ROS AMCL does): driving backwards reads as
  /// rot1 ~ pi, which is no turn of the wheels, and must not cost a half turn's noise.
  Eigen::Vector3d variances(const OdometryMotionNoise& noise) const {
    const double a1 = turn_size(rot1), a2 = turn_size(rot2);
    const double r1 = a1 * a1, t = trans * trans, r2 = a2 * a2;
    return {noise.alpha1 * r1 + noise.alpha2 * t, noise.alpha3 * t + noise.alpha4 * (r1 + r2),
            noise.alpha1 * r2 + noise.alpha2 * t};
  }
  static double turn_size(double angle) {
    const double a = std::abs(angle);
    return std::min(a, kPi - a);
  }
  /// The noise-free end pose from `pose` (Table 5.6 lines 5-7 with the hatted values = these).
  Eigen::Vector3d apply(const Eigen::Vector3d& pose) const {
    return {pose.x() + trans * std::cos(pose.z() + rot1), pose.y() + trans * std::sin(pose.z() + rot1),
            wrap_angle(pose.z() + rot1 + rot2)};
  }
};

/// Table 5.6: one pose drawn from p(x_t | u_t, x_{t-1}) for the odometry motion `u`; `rng`
/// has normal() returning a standard normal deviate (e.g. ParticleRng). Three deviates are
/// drawn per call, always in the order rot1, trans, rot2 (so a stream gives the same poses
/// whatever the noise).
template <class Rng>
Eigen::Vector3d sample_odometry_motion(const Eigen::Vector3d& pose, const OdometryMotion& u,
                                       const OdometryMotionNoise& noise, Rng& rng) {
  const Eigen::Vector3d var = u.variances(noise);
  OdometryMotion hat;
  hat.rot1 = u.rot1 - std::sqrt(var[0]) * rng.normal();
  hat.trans = u.trans - std::sqrt(var[1]) * rng.normal();
  hat.rot2 = u.rot2 - std::sqrt(var[2]) * rng.normal();
  return hat.apply(pose);
}

/// Table 5.5: log p(x_t | u_t, x_{t-1}), the odometry motion `u` read between the odometry
/// poses and the hypothesis motion between `from` and `to`; the density is over (rot1, trans,
/// rot2) as in the book. Throws std::invalid_argument when a variance is 0 (the density is
/// then a Dirac), or on non-finite input.
double odometry_motion_log_density(const Eigen::Vector3d& from, const Eigen::Vector3d& to, const OdometryMotion& u,
                                   const OdometryMotionNoise& noise);

}  // namespace probslam
