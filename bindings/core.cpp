#include <cmath>
#include <functional>

#include "args.hpp"
#include "numpy.hpp"
#include "repr.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/angle.hpp"
#include "probslam/core/chi_square.hpp"
#include "probslam/core/filter_limits.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "probslam/core/ackermann_motion_model.hpp"
#include "probslam/core/filter_limits.hpp"

namespace probslam::bindings {

namespace {

py::array points_through(py::handle points, const char* name,
                         const std::function<Eigen::Vector2d(const Eigen::Vector2d&)>& f) {
  DoubleArray a = as_array(points, name);
  if (a.ndim() == 1) return py::cast(f(fixed_vector<2>(points, name)));
  DoubleArray m = matrix_arg(points, name, 2);
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> out(m.shape(0), 2);
  const auto in = as_matrix(m);
  for (Eigen::Index i = 0; i < out.rows(); ++i) out.row(i) = f(in.row(i).transpose()).transpose();
  return py::cast(std::move(out));
}

// Re-raises a row's std::invalid_argument with the row's index after the argument's name
// ("steering[12] must lie in ..."), so a long control array names the bad entry.
[[noreturn]] void rethrow_for_row(const std::invalid_argument& e, py::ssize_t row) {
  const std::string what = e.what();
  const std::size_t space = what.find(' ');
  const std::string name = what.substr(0, space);
  throw std::invalid_argument(name + "[" + std::to_string(row) + "]" +
                              (space == std::string::npos ? "" : what.substr(space)));
}

AckermannGeometry geometry_arg(py::handle obj) {
  if (obj.is_none()) return AckermannGeometry();
  if (!py::isinstance<AckermannGeometry>(obj)) throw py::type_error("geometry must be an AckermannGeometry");
  return obj.cast<AckermannGeometry>();
}

void define_ackermann(py::module_& m) {
  py::class_<AckermannGeometry>(m, "AckermannGeometry",
                                "A car's geometry (m) for the Ackermann motion model: the defaults are the Victoria\n"
                                "Park utility car (wheelbase L, encoder offset H left of the rear axle's centre, the\n"
                                "sensor a ahead of the rear axle and b to the left).")
      .def(py::init([](RealArg wheelbase, RealArg encoder_offset, RealArg sensor_ahead, RealArg sensor_left) {
             AckermannGeometry g{wheelbase.get("wheelbase"), encoder_offset.get("encoder_offset"),
                                 sensor_ahead.get("sensor_ahead"), sensor_left.get("sensor_left")};
             g.validate();
             return g;
           }),
           py::arg("wheelbase") = 2.83, py::arg("encoder_offset") = 0.76, py::arg("sensor_ahead") = 3.78,
           py::arg("sensor_left") = 0.50)
      .def_readonly("wheelbase", &AckermannGeometry::wheelbase, "L (m), rear axle to front axle.")
      .def_readonly("encoder_offset", &AckermannGeometry::encoder_offset,
                    "H (m), the encoder wheel left of the rear axle's centre.")
      .def_readonly("sensor_ahead", &AckermannGeometry::sensor_ahead, "a (m), the sensor ahead of the rear axle.")
      .def_readonly("sensor_left", &AckermannGeometry::sensor_left, "b (m), the sensor left of the centre line.")
      .def("__repr__", [](const AckermannGeometry& g) {
        return "AckermannGeometry(wheelbase=" + num(g.wheelbase) + ", encoder_offset=" + num(g.encoder_offset) +
               ", sensor_ahead=" + num(g.sensor_ahead) + ", sensor_left=" + num(g.sensor_left) + ")";
      });
  m.def(
      "ackermann_motion",
      [](py::handle pose, RealArg speed, RealArg steering, RealArg dt, py::handle geometry) {
        return ackermann_motion(pose_arg(pose), speed.get("speed"), steering.get("steering"), dt.get("dt"),
                                geometry_arg(geometry));
      },
      py::arg("pose"), py::arg("speed"), py::arg("steering"), py::arg("dt"), py::arg("geometry") = py::none(),
      "The sensor's pose (3,) after dt (s) at encoder speed (m/s) and steering (rad, positive left)\n"
      "from pose (3,) (Guivant and Nebot's car model, Euler step); geometry: AckermannGeometry\n"
      "(None: the Victoria Park car).");
  m.def(
      "ackermann_motion_jacobian",
      [](py::handle pose, RealArg speed, RealArg steering, RealArg dt, py::handle geometry) {
        return ackermann_motion_jacobian(pose_arg(pose), speed.get("speed"), steering.get("steering"), dt.get("dt"),
                                         geometry_arg(geometry));
      },
      py::arg("pose"), py::arg("speed"), py::arg("steering"), py::arg("dt"), py::arg("geometry") = py::none(),
      "(3, 3) Jacobian G = d g / d pose of ackermann_motion.");
  m.def(
      "ackermann_motion_control_jacobian",
      [](py::handle pose, RealArg speed, RealArg steering, RealArg dt, py::handle geometry) {
        return ackermann_motion_control_jacobian(pose_arg(pose), speed.get("speed"), steering.get("steering"),
                                                 dt.get("dt"), geometry_arg(geometry));
      },
      py::arg("pose"), py::arg("speed"), py::arg("steering"), py::arg("dt"), py::arg("geometry") = py::none(),
      "(3, 2) Jacobian V = d g / d (speed, steering) of ackermann_motion.");
  m.def(
      "ackermann_increments",
      [](py::handle speed, py::handle steering, py::handle dt, py::handle control_noise, py::handle geometry) {
        const DoubleArray sa = vector_arg(speed, "speed");
        const DoubleArray aa = vector_arg(steering, "steering", sa.shape(0));
        const DoubleArray da = vector_arg(dt, "dt", sa.shape(0));
        const Eigen::MatrixXd noise = square_matrix_arg(control_noise, "control_noise", 2);
        require_covariance(noise, "control_noise", true);
        const AckermannGeometry g = geometry_arg(geometry);
        const auto v = as_vector(sa), a = as_vector(aa), t = as_vector(da);
        const py::ssize_t n = sa.shape(0);
        py::array_t<double> deltas({n, py::ssize_t{3}}), covs({n, py::ssize_t{3}, py::ssize_t{3}});
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> d(deltas.mutable_data(), n, 3);
        double* c = covs.mutable_data();
        {
          py::gil_scoped_release release;
          for (py::ssize_t k = 0; k < n; ++k) {
            try {
              d.row(k) = ackermann_increment(v[k], a[k], t[k], g).transpose();
              const Eigen::Matrix<double, 3, 2> j = ackermann_increment_jacobian(v[k], a[k], t[k], g);
              Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(c + 9 * k) = j * noise * j.transpose();
            } catch (const std::invalid_argument& e) {
              rethrow_for_row(e, k);
            }
          }
        }
        return py::make_tuple(deltas, covs);
      },
      py::arg("speed"), py::arg("steering"), py::arg("dt"), py::arg("control_noise"), py::arg("geometry") = py::none(),
      "Each step's motion as a relative pose in the sensor's frame at its start, (N, 3), and its\n"
      "covariance J M J^T, (N, 3, 3), for the control noise M = control_noise (2, 2) of (speed,\n"
      "steering): speed, steering, dt are (N,) arrays (m/s, rad, s). The pose after a step is\n"
      "pose (+) delta: what EkfSlam / FastSlam.predict_odometry take.");
}


}  // namespace

void define_core(py::module_& m) {
  // The filters' coordinate limit (core/filter_limits.hpp), for readers that check data before a run.
  m.attr("MAX_COORDINATE") = kMaxCoordinate;
  m.def(
      "chi_square_quantile", [](double p, IntArg dof) { return chi_square_quantile(p, dof.get("dof")); }, py::arg("p"),
      py::arg("dof"),
      "The x with P(X <= x) = p for X chi-square with dof >= 1 degrees of freedom, 0 < p < 1: the\n"
      "Mahalanobis gate that keeps a fraction p of correct associations.");
  m.def(
      "chi_square_cdf", [](double x, IntArg dof) { return chi_square_cdf(x, dof.get("dof")); }, py::arg("x"),
      py::arg("dof"), "P(X <= x) for X chi-square with dof >= 1 degrees of freedom (0 for x <= 0).");
  m.def(
      "wrap_angle",
      [](py::handle angle) -> py::object {
        DoubleArray a = as_array(angle, "angle");
        const auto in = as_vector(a);
        if (!in.allFinite()) throw py::value_error("angle must be finite (NaN and inf have no direction)");
        py::array_t<double> out(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
        Eigen::Map<Eigen::VectorXd>(out.mutable_data(), a.size()) = in.unaryExpr([](double v) { return wrap_angle(v); });
        if (a.ndim() == 0) return py::float_(out.data()[0]);
        return std::move(out);
      },
      py::arg("angle"), "Wrap finite angles (radians) to (-pi, pi]; works element-wise on arrays.");

  py::class_<Pose2>(m, "Pose2", "Planar pose (x, y in metres, theta in radians wrapped to (-pi, pi]).")
      .def(py::init([](double x, double y, double theta) {
             return Pose2::from_vector(Eigen::Vector3d(x, y, theta));
           }),
           py::arg("x") = 0.0, py::arg("y") = 0.0, py::arg("theta") = 0.0,
           "Pose at (x, y) metres with heading theta radians (wrapped to (-pi, pi]).")
      .def_static("from_array", [](py::handle a) { return Pose2::from_vector(pose_arg(a, "array")); },
                  py::arg("array"), "Pose from a (3,) array (x, y, theta).")
      .def_readonly("x", &Pose2::x, "x position, metres.")
      .def_readonly("y", &Pose2::y, "y position, metres.")
      .def_readonly("theta", &Pose2::theta, "Heading, radians in (-pi, pi].")
      .def("as_array", &Pose2::vector, "(3,) array (x, y, theta).")
      .def("compose", [](const Pose2& p, ClassArg<Pose2> other) { return p.compose(other.get("other")); },
           py::arg("other"), "self (+) other.")
      .def("__mul__", &Pose2::compose, "self * other is self.compose(other).")
      .def("inverse", &Pose2::inverse, "The pose p with self (+) p = identity.")
      .def("between", [](const Pose2& p, ClassArg<Pose2> other) { return p.between(other.get("other")); },
           py::arg("other"), "self^-1 (+) other.")
      .def(
          "transform_from",
          [](const Pose2& p, py::handle pts) {
            return points_through(pts, "points", [&](const Eigen::Vector2d& q) { return p.transform_from(q); });
          },
          py::arg("points"), "Body-frame points (2,) or (n, 2) to the world frame.")
      .def(
          "transform_to",
          [](const Pose2& p, py::handle pts) {
            return points_through(pts, "points", [&](const Eigen::Vector2d& q) { return p.transform_to(q); });
          },
          py::arg("points"), "World-frame points (2,) or (n, 2) to the body frame.")
      .def("__repr__", [](const Pose2& p) {
        return "Pose2(x=" + num(p.x) + ", y=" + num(p.y) + ", theta=" + num(p.theta) + ")";
      });

  m.def(
      "velocity_motion",
      [](py::handle pose, double v, double w, double dt) { return velocity_motion(pose_arg(pose), v, w, dt); },
      py::arg("pose"), py::arg("v"), py::arg("w"), py::arg("dt"),
      "Pose (3,) after driving v (m/s) and w (rad/s) for dt (s) from pose (3,) (eq. 5.9 / 10.11,\n"
      "noise-free); exact through w = 0.");
  m.def(
      "velocity_motion_jacobian",
      [](py::handle pose, double v, double w, double dt) {
        return velocity_motion_jacobian(pose_arg(pose), v, w, dt);
      },
      py::arg("pose"), py::arg("v"), py::arg("w"), py::arg("dt"),
      "(3, 3) Jacobian G = d g / d pose of velocity_motion (Table 10.1 line 4, signs corrected);\n"
      "pose (3,), v m/s, w rad/s, dt s.");
  m.def(
      "velocity_motion_control_jacobian",
      [](py::handle pose, double v, double w, double dt) {
        return velocity_motion_control_jacobian(pose_arg(pose), v, w, dt);
      },
      py::arg("pose"), py::arg("v"), py::arg("w"), py::arg("dt"),
      "(3, 2) Jacobian V = d g / d (v, w) of velocity_motion; pose (3,), v m/s, w rad/s, dt s.");

  m.def(
      "velocity_increments",
      [](py::handle v_obj, py::handle w_obj, py::handle dt_obj, py::handle noise_obj) {
        const DoubleArray v = vector_arg(v_obj, "v");
        const py::ssize_t n = v.shape(0);
        const DoubleArray w = vector_arg(w_obj, "w", n), dt = vector_arg(dt_obj, "dt", n);
        const DoubleArray noise = as_array(noise_obj, "control_noise");
        if (noise.ndim() != 3 || noise.shape(0) != n || noise.shape(1) != 2 || noise.shape(2) != 2)
          throw py::value_error("control_noise must have shape (" + std::to_string(n) + ", 2, 2), got " +
                                shape_of(noise));
        for (const DoubleArray* a : {&v, &w, &dt, &noise})
          for (py::ssize_t k = 0; k < a->size(); ++k)
            if (!std::isfinite(a->data()[k]))
              throw py::value_error(std::string(a == &v ? "v" : a == &w ? "w" : a == &dt ? "dt" : "control_noise") +
                                    " must be finite");
        py::array_t<double> delta({n, py::ssize_t{3}}), cov({n, py::ssize_t{3}, py::ssize_t{3}});
        {
          py::gil_scoped_release release;
          const Eigen::Vector3d origin = Eigen::Vector3d::Zero();
          for (py::ssize_t k = 0; k < n; ++k) {
            const Eigen::Vector3d d = velocity_motion(origin, v.data()[k], w.data()[k], dt.data()[k]);
            const Eigen::Matrix<double, 3, 2> jac = velocity_motion_control_jacobian(origin, v.data()[k], w.data()[k],
                                                                                     dt.data()[k]);
            const Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>> m_k(noise.data(k, 0, 0));
            const Eigen::Matrix3d p = jac * m_k * jac.transpose();
            const Eigen::Matrix3d c = 0.5 * (p + p.transpose());  // symmetric to the bit
            std::copy(d.data(), d.data() + 3, delta.mutable_data(k, 0));
            Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(cov.mutable_data(k, 0, 0)) = c;
          }
        }
        return py::make_tuple(delta, cov);
      },
      py::arg("v"), py::arg("w"), py::arg("dt"), py::arg("control_noise"),
      "The velocity motion model over pieces (v m/s, w rad/s, dt s) (n,): each piece's motion in\n"
      "the robot's frame (velocity_motion from the origin) (n, 3) and its covariance\n"
      "V control_noise[k] V^T (n, 3, 3), V = velocity_motion_control_jacobian; control_noise\n"
      "(n, 2, 2), the covariance of (v, w) over each piece.");

  define_ackermann(m);

  m.def(
      "range_bearing",
      [](py::handle pose, py::handle landmark) -> py::object {
        const Eigen::Vector3d x = pose_arg(pose);
        DoubleArray lm = as_array(landmark, "landmark");
        if (lm.ndim() == 1 && lm.shape(0) == 3) return py::cast(range_bearing(x, fixed_vector<3>(landmark, "landmark")));
        return py::cast(range_bearing(x, fixed_vector<2>(landmark, "landmark")));
      },
      py::arg("pose"), py::arg("landmark"),
      "Expected measurement (range m, bearing rad) (2,) of landmark (2,) m seen from pose (3,)\n"
      "(eq. 6.40 without noise); a (3,) landmark (x, y, signature) gives (3,) with the signature.");
  m.def(
      "range_bearing_jacobians",
      [](py::handle pose, py::handle landmark) -> py::tuple {
        const Eigen::Vector3d x = pose_arg(pose);
        DoubleArray lm = as_array(landmark, "landmark");
        if (lm.ndim() == 1 && lm.shape(0) == 3) {
          const auto j = range_bearing_jacobians(x, fixed_vector<3>(landmark, "landmark"));
          return py::make_tuple(j.pose, j.landmark);
        }
        const auto j = range_bearing_jacobians(x, fixed_vector<2>(landmark, "landmark"));
        return py::make_tuple(j.pose, j.landmark);
      },
      py::arg("pose"), py::arg("landmark"),
      "(d h / d pose (2, 3), d h / d landmark (2, 2)) of range_bearing; with a (3,) landmark\n"
      "(3, 3) and (3, 3), the signature passed through.");
  m.def(
      "landmark_from_range_bearing",
      [](py::handle pose, py::handle z) -> py::object {
        const Eigen::Vector3d x = pose_arg(pose);
        DoubleArray a = as_array(z, "z");
        if (a.ndim() == 1 && a.shape(0) == 3) {
          const Eigen::Vector3d z3 = fixed_vector<3>(z, "z");
          require_finite(z3[2], "z");
          const Eigen::Vector2d m2 = landmark_from_range_bearing(x, z3.head<2>());
          return py::cast(Eigen::Vector3d(m2[0], m2[1], z3[2]));
        }
        return py::cast(landmark_from_range_bearing(x, fixed_vector<2>(z, "z")));
      },
      py::arg("pose"), py::arg("z"),
      "Landmark position (2,) m from pose (3,) and z = (range m, bearing rad) (Table 10.1 line 10);\n"
      "a (3,) z (with a signature) gives (x, y, signature).");
  m.def(
      "landmark_from_range_bearing_jacobians",
      [](py::handle pose, py::handle z) {
        const auto j = landmark_from_range_bearing_jacobians(pose_arg(pose), fixed_vector<2>(z, "z"));
        return py::make_tuple(j.pose, j.landmark);
      },
      py::arg("pose"), py::arg("z"),
      "(d m / d pose (2, 3), d m / d z (2, 2)) of landmark_from_range_bearing; z = (range m, bearing rad).");
}

}  // namespace probslam::bindings
