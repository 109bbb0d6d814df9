// Monte Carlo localization (localization/) and the odometry motion model kernel
// (core/odometry_motion_model.hpp): conversions only; every call on the filter runs under its lock
// with the GIL released.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <tuple>
#include <utility>

#include "args.hpp"
#include "interrupt.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "options_class.hpp"
#include "persistence.hpp"
#include "repr.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/odometry_motion_model.hpp"
#include "probslam/fastslam/particles.hpp"
#include "probslam/localization/monte_carlo_localization.hpp"

namespace probslam::bindings {

namespace {

using Mcl = MonteCarloLocalization;

OdometryMotionNoise noise_arg(py::handle obj, const char* name) {
  const Eigen::Vector4d a = fixed_vector<4>(obj, name);
  OdometryMotionNoise n{a[0], a[1], a[2], a[3]};
  if (!a.allFinite() || (a.array() < 0.0).any())
    throw py::value_error(std::string(name) + " must hold four finite coefficients >= 0 (alpha1..alpha4)");
  return n;
}

/// The Python form of the initial covariance: None is the default diag(0.25 m, 0.25 m, 15 deg)^2.
Eigen::Matrix3d initial_covariance_arg(py::handle obj) {
  if (obj.is_none()) {
    Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
    c.diagonal() << 0.25 * 0.25, 0.25 * 0.25, 0.2617993877991494 * 0.2617993877991494;
    return c;
  }
  return square_matrix_arg(obj, "initial_covariance", 3);
}

}  // namespace

void define_localization(py::module_& m) {
  py::class_<MclUpdate>(m, "MclUpdate", "MonteCarloLocalization.update's report.")
      .def_readonly("updated", &MclUpdate::updated, "Whether the filter updated (enough travel, first scan, force).")
      .def_readonly("resampled", &MclUpdate::resampled, "Whether it resampled (N_eff below the threshold).")
      .def_readonly("num_particles", &MclUpdate::num_particles, "M after the call.")
      .def_readonly("effective_sample_size", &MclUpdate::effective_sample_size, "N_eff before resampling (0 without update).")
      .def_readonly("random_fraction", &MclUpdate::random_fraction,
                    "Share of random particles injected by augmented MCL at the last resampling.")
      .def("__repr__", [](const MclUpdate& u) {
        return "MclUpdate(updated=" + std::string(u.updated ? "True" : "False") + ", resampled=" +
               (u.resampled ? "True" : "False") + ", num_particles=" + std::to_string(u.num_particles) + ")";
      });

  bind_options<OdometryMotionNoise>(m, "OdometryMotionNoise",
                                    "The odometry motion model's noise (Probabilistic Robotics Table 5.5 / 5.6).");
  bind_options<BeamMixture>(m, "BeamMixture",
                            "The beam model's mixture of range readings (Probabilistic Robotics eq. 6.4-6.12).");
  bind_options<MonteCarloLocalizationOptions>(m, "MonteCarloLocalizationOptions",
                                              "The options of MonteCarloLocalization (Table 8.2 / 8.3, Fox 2003).");
  py::class_<Mcl> c(m, "MonteCarloLocalization",
      "Monte Carlo localization in a known occupancy grid (Probabilistic Robotics Table 8.2 / 8.3, Fox 2003).\n"
      "\n"
      "MonteCarloLocalization(map, *, options=None, initial_pose=None, initial_covariance=None, **fields):\n"
      "    map: an OccupancyGrid2D (copied).\n"
      "    options: a MonteCarloLocalizationOptions (None: the defaults); **fields set fields of it by name\n"
      "        (sigma=0.15, odometry=OdometryMotionNoise(alpha1=0.1), beam={\"z_hit\": 0.9, ...}).\n"
      "    initial_pose: (x, y, theta) to start around, None for a global start (max_particles uniform over\n"
      "        the free cells); initial_covariance: (3, 3), None for diag(0.25 m, 0.25 m, 15 deg)^2.\n"
      "Errors name the field's path (\"beam.z_hit\"). A failed call changes nothing.");
  py::options signatures;  // the fields' keywords are written from describe(), not **kwargs
  signatures.disable_function_signatures();
  c.def(py::init([](py::handle map, py::handle options, py::handle initial_pose, py::handle initial_covariance,
                    const py::kwargs& fields) {
          const OccupancyGrid2D& grid = ClassArg<OccupancyGrid2D>{py::reinterpret_borrow<py::object>(map)}.get("map");
          const auto o = options_arg<MonteCarloLocalizationOptions>(options, fields, "MonteCarloLocalization()");
          const bool global = initial_pose.is_none();
          Eigen::Vector3d pose = Eigen::Vector3d::Zero();
          if (!global) pose = pose_arg(initial_pose, "initial_pose");
          const Eigen::Matrix3d cov = initial_covariance_arg(initial_covariance);
          return locked(grid, [&] {
            auto f = std::make_unique<Mcl>(grid, o);
            if (!global) {
              try {
                f->initialize_pose(pose, cov);
              } catch (const std::invalid_argument& e) {
                // Name the constructor's keywords, not initialize_pose's arguments.
                std::string what = e.what();
                if (what.rfind("pose", 0) == 0) what = "initial_" + what;
                else if (what.rfind("covariance", 0) == 0) what = "initial_" + what;
                throw std::invalid_argument(what);
              }
            }
            return f;
          });
        }),
        py::arg("map"), py::kw_only(), py::arg("options") = py::none(), py::arg("initial_pose") = py::none(),
        py::arg("initial_covariance") = py::none(),
        options_init_signature<MonteCarloLocalizationOptions>(
            "MonteCarloLocalization", "map: OccupancyGrid2D, *, ", ", initial_pose: object = None, initial_covariance: object = None")
            .c_str());
  signatures.enable_function_signatures();
  c.def_property_readonly("options", [](const Mcl& self) { return self.options(); },
                          "A copy of the MonteCarloLocalizationOptions the filter runs with.");
  c.def("initialize_global", [](Mcl& self) { locked(self, [&] { self.initialize_global(); }); },
        "Restarts with max_particles poses uniform over the free cells.")
      .def("initialize_pose", [](Mcl& self, py::handle pose, py::handle covariance) {
        const Eigen::Vector3d p = pose_arg(pose, "pose");
        const Eigen::Matrix3d cov = square_matrix_arg(covariance, "covariance", 3);
        locked(self, [&] { self.initialize_pose(p, cov); });
      }, py::arg("pose"), py::arg("covariance"),
         "Restarts with max_particles poses drawn from N(pose, covariance); pose must lie in a free cell.")
      .def("predict_odometry", [](Mcl& self, py::handle delta, py::handle previous, py::handle current) {
        Eigen::Vector3d dlt;
        if (!delta.is_none()) {
          if (!previous.is_none() || !current.is_none())
            throw py::value_error("delta: give either delta or previous and current, not both");
          dlt = fixed_vector<3>(delta, "delta");
        } else {
          if (previous.is_none() || current.is_none())
            throw py::value_error("delta: give delta, or both previous and current odometry poses");
          const Eigen::Vector3d a = pose_arg(previous, "previous"), b = pose_arg(current, "current");
          require_all_finite(a, "previous");
          require_all_finite(b, "current");
          const double c0 = std::cos(a.z()), s0 = std::sin(a.z());
          const double dx = b.x() - a.x(), dy = b.y() - a.y();
          dlt = Eigen::Vector3d(c0 * dx + s0 * dy, -s0 * dx + c0 * dy, wrap_angle(b.z() - a.z()));
        }
        locked(self, [&] { self.predict_odometry(dlt); });
      }, py::arg("delta") = py::none(), py::kw_only(), py::arg("previous") = py::none(), py::arg("current") = py::none(),
         "Accumulates an odometry motion: delta (3,) = (dx, dy, dtheta) in the previous odometry pose's frame,\n"
         "or the two odometry poses previous= and current=. Particles move at the next update.")
      .def("update", [](Mcl& self, py::handle ranges, py::handle angles, BoolArg force) {
        const DoubleArray r = vector_arg(ranges, "ranges");
        const DoubleArray a = vector_arg(angles, "angles");
        const bool f = force.get("force");
        const auto interrupt = python_interrupt();
        return locked(self, [&] { return self.update(as_vector(r), as_vector(a), f, interrupt); });
      }, py::arg("ranges"), py::arg("angles"), py::kw_only(), py::arg_v("force", false),
         "One scan: ranges (B,) m (finite, >= 0), angles (B,) rad relative to the sensor heading. Updates\n"
         "after update.distance / update.angle of travel (or on the first scan, or with force=True).\n"
         "Returns an MclUpdate. Ctrl-C stops a long update with the filter unchanged.")
      .def("measurement_log_likelihood", [](const Mcl& self, py::handle pose, py::handle ranges, py::handle angles) {
        const Eigen::Vector3d p = pose_arg(pose, "pose");
        const DoubleArray r = vector_arg(ranges, "ranges");
        const DoubleArray a = vector_arg(angles, "angles");
        return locked(self, [&] { return self.measurement_log_likelihood(p, as_vector(r), as_vector(a)); });
      }, py::arg("pose"), py::arg("ranges"), py::arg("angles"),
         "log p(z | pose, map) of the sensor model with the scan subsampled as update does (before weight_scale).")
      .def_static("kld_bound", [](IntArg k, RealArg epsilon, RealArg z) {
        const int kk = k.get("k", 0);
        const double e = epsilon.get("epsilon"), zz = z.get("z");
        require_positive(e, "epsilon");
        require_finite(zz, "z");
        return Mcl::kld_bound(kk, e, zz);
      }, py::arg("k"), py::arg("epsilon"), py::arg("z"),
         "Fox 2003: particles needed for k occupied bins, (k - 1) / (2 epsilon) (1 - 2 / (9 (k - 1)) +\n"
         "sqrt(2 / (9 (k - 1))) z)^3 (0 for k <= 1), before the min / max bounds. ValueError naming epsilon\n"
         "when it overflows a double.")
      .def_property_readonly("pose", getter(&Mcl::pose),
                             "(3,) the weighted mean of the largest particle cluster, moved by pending odometry.")
      .def_property_readonly("covariance", getter(&Mcl::covariance), "(3, 3) that cluster's covariance.")
      .def_property_readonly("cluster_weight", getter(&Mcl::cluster_weight),
                             "That cluster's share of the weight (near 1 once the filter settled on one place).")
      .def_property_readonly("poses", getter(&Mcl::poses), "(M, 3) every particle's pose (m, m, rad).")
      .def_property_readonly("weights", getter(&Mcl::weights), "(M,) normalised weights.")
      .def_property_readonly("num_particles", getter(&Mcl::num_particles), "M, the number of particles.")
      .def_property_readonly("num_updates", getter(&Mcl::num_updates), "Updates since the last initialisation.")
      .def_property_readonly("w_slow", getter(&Mcl::w_slow),
                             "Augmented MCL's long-term average of the per-beam likelihood (Table 8.3).")
      .def_property_readonly("w_fast", getter(&Mcl::w_fast), "Its short-term average.")
      .def("copy", [](const Mcl& self) { return locked(self, [&] { return std::make_unique<Mcl>(self); }); },
           "An independent deep copy (particles, random streams, averages).")
      .def("__repr__", [](py::handle self) {
        const Mcl& s = self.cast<const Mcl&>();
        return repr_of(self, locked(s, [&] {
          return std::to_string(s.num_particles()) + " particles, " + std::to_string(s.num_updates()) + " updates";
        }));
      });
  define_persistence<Mcl>(c);

  m.def("odometry_motion", [](py::handle previous, py::handle current) {
    const Eigen::Vector3d a = pose_arg(previous, "previous"), b = pose_arg(current, "current");
    const OdometryMotion u = OdometryMotion::between(a, b);
    return std::make_tuple(u.rot1, u.trans, u.rot2);
  }, py::arg("previous"), py::arg("current"),
     "(rot1, trans, rot2) of the motion between two odometry poses (Table 5.5 lines 2-4).");
  m.def("sample_odometry_motion", [](py::handle pose, py::handle previous, py::handle current, py::handle noise,
                                     IntArg num_samples, UInt64Arg seed) {
    const Eigen::Vector3d x = pose_arg(pose, "pose");
    require_all_finite(x, "pose");
    const Eigen::Vector3d a = pose_arg(previous, "previous"), b = pose_arg(current, "current");
    const OdometryMotionNoise n = noise_arg(noise, "noise");
    const int count = num_samples.get("num_samples", 1, kMaxParticles);
    ParticleRng rng(seed.get("seed"), 0);
    const OdometryMotion u = OdometryMotion::between(a, b);
    Poses2 out(count, 3);
    for (int i = 0; i < count; ++i) out.row(i) = sample_odometry_motion(x, u, n, rng).transpose();
    return out;
  }, py::arg("pose"), py::arg("previous"), py::arg("current"), py::arg("noise"), py::kw_only(),
     py::arg_v("num_samples", 1), py::arg_v("seed", 0),
     "(num_samples, 3) poses drawn from Table 5.6's p(x_t | u_t, pose), u_t read between the odometry\n"
     "poses previous and current; noise (4,) alpha1..alpha4.");
  m.def("odometry_motion_log_density", [](py::handle pose, py::handle next_pose, py::handle previous,
                                          py::handle current, py::handle noise) {
    const Eigen::Vector3d x0 = pose_arg(pose, "pose"), x1 = pose_arg(next_pose, "next_pose");
    require_all_finite(x0, "pose");
    require_all_finite(x1, "next_pose");
    const Eigen::Vector3d a = pose_arg(previous, "previous"), b = pose_arg(current, "current");
    const OdometryMotionNoise n = noise_arg(noise, "noise");
    return odometry_motion_log_density(x0, x1, OdometryMotion::between(a, b), n);
  }, py::arg("pose"), py::arg("next_pose"), py::arg("previous"), py::arg("current"), py::arg("noise"),
     "Table 5.5: log p(next_pose | u_t, pose) over (rot1, trans, rot2), u_t read between the odometry poses.");
}

}  // namespace probslam::bindings
