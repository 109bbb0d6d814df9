#include "probslam/core/velocity_motion_model.hpp"

#include <cmath>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2_covariance.hpp"

namespace probslam {
namespace {

// Below this half-angle the Taylor series of sinc is used: its truncation error (a^6/5040)
// is then far below double precision, and it avoids 0/0 at a = 0.
constexpr double kSincSeriesBelow = 1e-3;

double sinc(double a) {  // sin(a) / a
  if (std::abs(a) < kSincSeriesBelow) {
    const double a2 = a * a;
    return 1.0 - a2 / 6.0 + a2 * a2 / 120.0;
  }
  return std::sin(a) / a;
}

double sinc_derivative(double a) {  // d/da sin(a) / a
  if (std::abs(a) < kSincSeriesBelow) {
    const double a2 = a * a;
    return -a / 3.0 + a * a2 / 30.0;
  }
  return (a * std::cos(a) - std::sin(a)) / (a * a);
}

void check_inputs(const Eigen::Vector3d& pose, double v, double w, double dt) {
  require_all_finite(pose, "pose");
  require_finite(v, "v");
  require_finite(w, "w");
  require_positive(dt, "dt");
  require(std::isfinite(v * dt), "v", "* dt is beyond the double range");
  require(std::isfinite(w * dt), "w", "* dt is beyond the double range");
}

// Finite or raise: huge but finite inputs can still overflow (a pose near the double range
// moved further, v dt^2 in the control Jacobian).
template <typename Derived>
const Derived& finite_result(const Eigen::MatrixBase<Derived>& r, const char* name) {
  require(r.allFinite(), name, "gives a result beyond the double range");
  return r.derived();
}

// Arc geometry shared by the model and its Jacobians. With a = w dt / 2 the displacement of
// eq. 10.11, (v/w)(sin(th + 2a) - sin th, cos th - cos(th + 2a)), equals
// v dt sinc(a) (cos(th + a), sin(th + a)).
struct Arc {
  double half_angle, chord_heading, s, ds, c_h, s_h;
  Arc(const Eigen::Vector3d& pose, double w, double dt)
      : half_angle(0.5 * w * dt),
        chord_heading(pose[2] + half_angle),
        s(sinc(half_angle)),
        ds(sinc_derivative(half_angle)),
        c_h(std::cos(chord_heading)),
        s_h(std::sin(chord_heading)) {}
};

}  // namespace

// Table 10.1 line 3 (eq. 10.11 without noise).
Eigen::Vector3d velocity_motion(const Eigen::Vector3d& pose, double v, double w, double dt) {
  check_inputs(pose, v, w, dt);
  const Arc arc(pose, w, dt);
  const double d = v * dt * arc.s;
  const Eigen::Vector3d next(pose[0] + d * arc.c_h, pose[1] + d * arc.s_h, wrap_angle(pose[2] + w * dt));
  return finite_result(next, "v");
}

// Table 10.1 line 4: only the theta column differs from the identity.
Eigen::Matrix3d velocity_motion_jacobian(const Eigen::Vector3d& pose, double v, double w,
                                         double dt) {
  check_inputs(pose, v, w, dt);
  const Arc arc(pose, w, dt);
  const double d = v * dt * arc.s;
  return finite_result(heading_jacobian(Eigen::Vector2d(d * arc.c_h, d * arc.s_h)), "v");
}

Eigen::Matrix<double, 3, 2> velocity_motion_control_jacobian(const Eigen::Vector3d& pose, double v,
                                                             double w, double dt) {
  check_inputs(pose, v, w, dt);
  const Arc arc(pose, w, dt);
  // d/dw of v dt sinc(a) (cos, sin)(th + a) with da/dw = dt / 2.
  const double dd_dw = v * dt * arc.ds * 0.5 * dt;
  const double d = v * dt * arc.s;
  Eigen::Matrix<double, 3, 2> jac;
  jac(0, 0) = dt * arc.s * arc.c_h;
  jac(1, 0) = dt * arc.s * arc.s_h;
  jac(2, 0) = 0.0;
  jac(0, 1) = dd_dw * arc.c_h - d * arc.s_h * 0.5 * dt;
  jac(1, 1) = dd_dw * arc.s_h + d * arc.c_h * 0.5 * dt;
  jac(2, 1) = dt;
  return finite_result(jac, "v");
}

}  // namespace probslam
