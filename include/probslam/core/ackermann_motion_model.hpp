#pragma once
// The car-like (Ackermann) motion model of Guivant and Nebot (IEEE Trans. Robotics and
// Automation 17(3), 2001) as used on the Victoria Park run: the state is the pose of a sensor
// mounted on the car (its position and the car's heading), the controls are the speed measured
// by an encoder on the rear left wheel and the front wheels' steering angle. The encoder's speed
// is carried to the rear axle's centre (v_c = v_e / (1 - tan(alpha) H / L)), the car turns at
// w = v_c tan(alpha) / L, and the sensor at (a, b) in the car's frame (a ahead of the rear
// axle, b to the left) moves with the rigid body. One step of dt is Euler's: the heading at the
// step's start. Such a step is a relative pose in the sensor's own frame that depends on the
// controls only (ackermann_increment), so x' = x (+) increment: the filters take it as they take
// an odometry step, with the control noise carried by the increment's control Jacobian.
#include <Eigen/Core>

namespace probslam {

/// The car's geometry (m). Defaults: the Victoria Park utility car (the dataset's info.txt and
/// drawing: wheelbase 2.83 m, encoder 0.76 m left of the rear axle's centre, laser 0.95 m ahead
/// of the front axle = 3.78 m ahead of the rear axle and 0.50 m to the left).
struct AckermannGeometry {
  double wheelbase = 2.83;       ///< L: rear axle to front axle, > 0
  double encoder_offset = 0.76;  ///< H: the encoder wheel's distance left of the rear axle's centre
  double sensor_ahead = 3.78;    ///< a: the sensor ahead of the rear axle
  double sensor_left = 0.50;     ///< b: the sensor left of the car's centre line
  /// std::invalid_argument naming the first field that is not finite (wheelbase: and > 0).
  void validate() const;
};

/// The smallest allowed 1 - tan(alpha) H / L: below it the encoder wheel turns about itself
/// and its speed says nothing of the car's (v_c = v_e / 0 at tan(alpha) = L / H, 75 deg for the
/// default car, far beyond any steering stop).
inline constexpr double kMinEncoderSpeedRatio = 1e-2;

/// The sensor's motion over dt (s) at encoder speed `speed` (m/s) and steering `steering` (rad,
/// positive left), as a relative pose (dx, dy, dtheta) in the sensor's frame at the step's
/// start. Throws std::invalid_argument naming the argument on non-finite input, dt <= 0,
/// |steering| >= pi / 2 or 1 - tan(steering) H / L < kMinEncoderSpeedRatio.
Eigen::Vector3d ackermann_increment(double speed, double steering, double dt, const AckermannGeometry& geometry);
/// d increment / d (speed, steering), (3, 2).
Eigen::Matrix<double, 3, 2> ackermann_increment_jacobian(double speed, double steering, double dt,
                                                         const AckermannGeometry& geometry);

/// g(x, u): the pose after one step, pose (+) increment, heading wrapped to (-pi, pi] (the
/// README's equations of the Victoria Park data, written in the world frame).
Eigen::Vector3d ackermann_motion(const Eigen::Vector3d& pose, double speed, double steering, double dt,
                                 const AckermannGeometry& geometry);
/// G = dg/dx (3, 3).
Eigen::Matrix3d ackermann_motion_jacobian(const Eigen::Vector3d& pose, double speed, double steering, double dt,
                                          const AckermannGeometry& geometry);
/// V = dg/du (3, 2) with respect to u = (speed, steering): control-space noise M gives the
/// pose noise V M V^T.
Eigen::Matrix<double, 3, 2> ackermann_motion_control_jacobian(const Eigen::Vector3d& pose, double speed,
                                                              double steering, double dt,
                                                              const AckermannGeometry& geometry);

}  // namespace probslam
