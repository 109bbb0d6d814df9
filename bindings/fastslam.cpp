// FastSLAM (fastslam/): thin conversions only. Every method runs its C++ work through locked():
// the GIL is released, the filter's mutex taken, Python objects converted before and built after.
#include <pybind11/stl.h>

#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "kwargs.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "repr.hpp"
#include "probslam/fastslam/fast_slam.hpp"

namespace probslam::bindings {

namespace {

DoubleArray scan_arg(const FastSlam& f, py::handle z) {
  const int md = f.landmark_dim();  // fixed at construction: no lock needed
  DoubleArray a = as_array(z, "z");
  if (a.ndim() == 1 && a.shape(0) == md) return DoubleArray(a.reshape({py::ssize_t{1}, a.shape(0)}));
  return matrix_arg(z, "z", md);
}

std::vector<long> ids_arg(py::handle ids, py::ssize_t k) {
  LongArray a = integer_array_arg(ids, "ids");
  if (a.ndim() == 0) a = a.reshape({py::ssize_t{1}});
  if (a.ndim() != 1 || a.shape(0) != k)
    throw py::value_error("ids must have shape (" + std::to_string(k) + ",), one id per measurement");
  return std::vector<long>(a.data(), a.data() + a.shape(0));
}

FastSlamOptions options_from(int num_particles, py::handle motion_noise, py::handle measurement_noise,
                             const py::kwargs& kw) {
  FastSlamOptions o;
  o.num_particles = num_particles;
  o.motion_noise = square_matrix_arg(motion_noise, "motion_noise");
  o.measurement_noise = square_matrix_arg(measurement_noise, "measurement_noise");
  Kwargs k(kw);
  k.get("version", o.version);
  k.get("use_signatures", o.use_signatures);
  if (const py::handle v = k.take("initial_pose")) o.initial_pose = pose_arg(v, "initial_pose");
  k.get("seed", o.seed);
  k.get("threads", o.threads);
  k.get("resample_threshold", o.resample_threshold);
  k.get("p_new", o.p_new);
  k.get("outlier_density", o.outlier_density);
  k.get("association_radius", o.association_radius);
  k.get("cell_size", o.cell_size);
  k.get("negative_information", o.negative_information);
  k.get("existence_hit", o.existence_hit);
  k.get("existence_miss", o.existence_miss);
  k.get("sensor_range", o.sensor_range);
  k.get("sensor_fov", o.sensor_fov);
  k.get("record_path", o.record_path);
  k.get("bearing_offset_sigma", o.bearing_offset_sigma);
  k.get("bearing_offset_correlation", o.bearing_offset_correlation);
  k.finish();
  return o;
}

template <typename T>
py::array_t<T> vector_out(const std::vector<T>& v) {
  py::array_t<T> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

void define_state(py::class_<FastSlam>& c) {
  c.def_property_readonly("num_particles", getter(&FastSlam::num_particles), "M, the number of particles.")
      .def_property_readonly("version", getter(&FastSlam::version), "1 or 2 (FastSLAM 1.0 or 2.0).")
      .def_property_readonly("landmark_dim", getter(&FastSlam::landmark_dim),
                             "Measurement length: 2 (range, bearing) or 3 with a signature.")
      .def_property_readonly("poses", getter(&FastSlam::poses), "(M, 3) particle poses (x m, y m, theta rad).")
      .def_property_readonly("log_weights", getter(&FastSlam::log_weights), "(M,) normalised log weights (log-sum-exp 0).")
      .def_property_readonly("weights",
                             [](const FastSlam& f) {
                               return Eigen::VectorXd(locked(f, [&] { return f.log_weights(); }).array().exp());
                             },
                             "(M,) weights summing to 1.")
      .def_property_readonly("bearing_offsets", getter(&FastSlam::bearing_offsets),
                             "(M,) each particle's bearing offset (rad) of its last update (bearing_offset_sigma);\n"
                             "zeros without the offset model.")
      .def_property_readonly("last_log_likelihoods", getter(&FastSlam::last_log_likelihoods),
                             "(M,) log of each particle's weight factor in the last update.")
      .def_property_readonly("effective_sample_size", getter(&FastSlam::effective_sample_size),
                             "N_eff = 1 / sum w^2.")
      .def_property_readonly("best_index", getter(&FastSlam::best_index), "Index of the particle of highest weight.")
      .def_property_readonly("best_path",
                             [](const FastSlam& f) { return locked(f, [&] { return f.path(f.best_index()); }); },
                             "(T + 1, 3) the best particle's path, oldest first.")
      .def_property_readonly("mean_pose", getter(&FastSlam::mean_pose),
                             "(3,) weighted mean pose, heading by circular mean.")
      .def_property_readonly("pose_covariance", getter(&FastSlam::pose_covariance),
                             "(3, 3) weighted covariance of the poses about mean_pose.")
      .def_property_readonly("num_resamples", getter(&FastSlam::num_resamples), "Resamplings so far.")
      .def_property_readonly("resampled", getter(&FastSlam::resampled), "Whether the last update resampled.")
      .def_property_readonly("ancestors", [](const FastSlam& f) {
        return locked(f, [&] {
          const std::vector<int>& a = f.last_ancestors();
          return Eigen::VectorXi(Eigen::Map<const Eigen::VectorXi>(a.data(), static_cast<Eigen::Index>(a.size())));
        });
      }, "(M,) int32: after a resampling, particle j's ancestor index; otherwise (0,).")
      .def_property_readonly("map_sharing",
                             [](const FastSlam& f) {
                               const MapSharing s = locked(f, [&] { return f.map_sharing(); });
                               py::dict d;
                               d["distinct_nodes"] = s.distinct_nodes;
                               d["total_nodes"] = s.total_nodes;
                               d["landmarks"] = s.landmarks;
                               d["path_nodes"] = s.path_nodes;
                               return d;
                             },
                             "Dict: distinct_nodes (tree nodes allocated for all maps), total_nodes (sum of\n"
                             "per-particle nodes: what deep copies would hold), landmarks (sum of per-particle\n"
                             "counts), path_nodes.")
      .def("path",
           [](const FastSlam& f, IntArg index) {
             const int k = index.get("index");
             return locked(f, [&] { return f.path(k); });
           },
           py::arg("index"), "(T + 1, 3) particle index's path, oldest first.")
      .def("num_landmarks",
           [](const FastSlam& f, IntArg index) {
             const int k = index.get("index");
             return locked(f, [&] { return f.particle(k).map.size(); });
           },
           py::arg("index"), "Number of landmarks in particle index's map.")
      .def(
          "landmarks",
          [](const FastSlam& f, IntArg index_arg) {
            const int index = index_arg.get("index");
            const std::vector<Landmark> lms = locked(f, [&] { return f.landmarks(index); });
            const auto n = static_cast<py::ssize_t>(lms.size());
            py::array_t<long> ids(n);
            py::array_t<double> means({n, py::ssize_t{2}}), covs({n, py::ssize_t{2}, py::ssize_t{2}});
            for (py::ssize_t i = 0; i < n; ++i) {
              const Landmark& lm = lms[static_cast<std::size_t>(i)];
              ids.mutable_at(i) = lm.id;
              for (int a = 0; a < 2; ++a) {
                means.mutable_at(i, a) = lm.mean[a];
                for (int b = 0; b < 2; ++b) covs.mutable_at(i, a, b) = lm.cov(a, b);
              }
            }
            return py::make_tuple(ids, means, covs);
          },
          py::arg("index"),
          "Particle index's landmarks by id: (ids (K,), means (K, 2) m, covariances (K, 2, 2) m^2).")
      .def(
          "landmark_details",
          [](const FastSlam& f, IntArg index_arg) {
            const int index = index_arg.get("index");
            const std::vector<Landmark> lms = locked(f, [&] { return f.landmarks(index); });
            const auto n = static_cast<py::ssize_t>(lms.size());
            py::array_t<double> existence(n), signature(n), signature_var(n);
            for (py::ssize_t i = 0; i < n; ++i) {
              const Landmark& lm = lms[static_cast<std::size_t>(i)];
              existence.mutable_at(i) = lm.existence;
              signature.mutable_at(i) = lm.signature;
              signature_var.mutable_at(i) = lm.signature_var;
            }
            py::dict d;
            d["existence"] = existence;
            d["signature"] = signature;
            d["signature_var"] = signature_var;
            return d;
          },
          py::arg("index"),
          "Dict of (K,) arrays existence, signature, signature_var, in the order of landmarks(index).");
}

void define_calls(py::class_<FastSlam>& c) {
  c.def(
       "predict", [](FastSlam& f, double v, double w, double dt) { locked(f, [&] { f.predict(v, w, dt); }); },
       py::arg("v"), py::arg("w"), py::arg("dt"),
       "Samples each particle's pose from the velocity motion model: v m/s, w rad/s, dt s.")
      .def(
          "predict_odometry",
          &predict_odometry_locked<FastSlam>,
          py::arg("delta"), py::arg("noise"),
          "x <- x (+) (delta + e), e ~ N(0, noise (3, 3)) in the robot frame; delta (3,) (m, m, rad).")
      .def(
          "update",
          [](FastSlam& f, py::handle z, py::handle ids) {
            DoubleArray zz = scan_arg(f, z);
            const std::vector<long> id = ids_arg(ids, zz.shape(0));
            return locked(f, [&] { return f.update(as_matrix(zz), id); });
          },
          py::arg("z"), py::arg("ids"),
          "Known correspondences: z (k, 2) (range m, bearing rad) or (k, 3), ids (k,) >= 0. Returns whether\n"
          "it resampled.")
      .def(
          "update_unknown",
          [](FastSlam& f, py::handle z, std::optional<double> p_new) {
            DoubleArray zz = scan_arg(f, z);
            const FastSlamAssociation r = locked(f, [&] {
              return p_new ? f.update_unknown(as_matrix(zz), *p_new) : f.update_unknown(as_matrix(zz));
            });
            const py::ssize_t m = r.num_particles, k = r.num_measurements;
            py::array_t<long> ids({m, k});
            py::array_t<bool> is_new({m, k});
            std::copy(r.ids.begin(), r.ids.end(), ids.mutable_data());
            std::copy(r.is_new.begin(), r.is_new.end(), is_new.mutable_data());
            // One (R, 2) array of (particle, landmark id) rows: a list of M arrays per scan cost
            // more than the filter's update itself.
            py::ssize_t count = 0;
            for (const std::vector<long>& v : r.removed) count += static_cast<py::ssize_t>(v.size());
            py::array_t<long> removed({count, py::ssize_t{2}});
            long* out = removed.mutable_data();
            for (std::size_t j = 0; j < r.removed.size(); ++j) {
              for (long id : r.removed[j]) {
                *out++ = static_cast<long>(j);
                *out++ = id;
              }
            }
            return py::make_tuple(ids, is_new, removed);
          },
          py::arg("z"), py::arg("p_new") = py::none(),
          "Per-particle maximum-likelihood correspondences for a scan z (k, 2) or (k, 3); p_new (1 / (m\n"
          "rad)) overrides the option. Returns (ids (M, k), is_new (M, k), removed (R, 2) rows of\n"
          "(particle, landmark id) removed by negative information), rows following the particles after\n"
          "any resampling of this call.")
      .def("resample", [](FastSlam& f) { locked(f, [&] { f.resample(); }); }, "Low-variance resampling now, whatever N_eff.")
      .def("copy", [](const FastSlam& f) { return locked(f, [&] { return FastSlam(f); }); },
           "An independent copy (maps shared copy-on-write).")
      .def("__repr__", [](py::handle self) {
        const FastSlam& f = self.cast<const FastSlam&>();
        return repr_of(self, locked(f, [&] {
          const int best = f.best_index();
          return "version " + std::to_string(f.version()) + ", " + std::to_string(f.num_particles()) +
                 " particles, best has " + std::to_string(f.particle(best).map.size()) + " landmarks, N_eff " +
                 num(f.effective_sample_size());
        }));
      });
}

}  // namespace

void define_fastslam(py::module_& m) {
  py::class_<FastSlam> c(m, "FastSlam",
                         "FastSLAM 1.0 / 2.0 (Montemerlo 2002, 2003; Probabilistic Robotics ch. 13) for point landmarks\n"
                         "seen by a range-bearing(-signature) sensor. Units: metres, radians, seconds.\n"
                         "\n"
                         "FastSlam(num_particles, motion_noise, measurement_noise, **options):\n"
                         "    num_particles: M in [1, 2^20].\n"
                         "    motion_noise: (3, 3) pose-space covariance R of (x, y, theta) added to g(x, u), or (2, 2)\n"
                         "        control-space covariance M of (v [m/s], w [rad/s]); positive semi-definite.\n"
                         "    measurement_noise: Q, (2, 2) covariance of (range [m], bearing [rad]), or (3, 3) with the\n"
                         "        signature's variance when use_signatures.\n"
                         "Keyword options: version (1: poses from the motion model; 2: from the proposal that includes\n"
                         "the scan), use_signatures, initial_pose (3,), seed (int in [0, 2^64)), threads (results\n"
                         "identical for any count; two threads run 100 particles 1.5-1.85x faster on idle cores),\n"
                         "resample_threshold (resample when N_eff < threshold * M; 0.5),\n"
                         "p_new (density 1 / (m rad) of a new landmark's measurement; 0.01), outlier_density (known\n"
                         "correspondences: density 1 / (m rad) of a measurement its labelled landmark did not produce;\n"
                         "0: no outlier model), association_radius and cell_size (m, 2.0 each), negative_information,\n"
                         "existence_hit, existence_miss, sensor_range (m), sensor_fov (rad) (the existence counter of\n"
                         "update_unknown), record_path (keep each particle's path; True), bearing_offset_sigma (rad;\n"
                         "a bearing offset shared by one scan's measurements, carried per particle; 0: none) and\n"
                         "bearing_offset_correlation (its correlation from one update to the next, in [0, 1)).\n"
                         "\n"
                         "Every call validates its input first and raises ValueError / TypeError naming the argument,\n"
                         "the filter unchanged. Calls release the GIL and are serialised by a per-filter lock.");
  c.def(py::init([](IntArg num_particles_arg, py::handle motion_noise, py::handle measurement_noise, const py::kwargs& kw) {
          const int num_particles = num_particles_arg.get("num_particles");
          const FastSlamOptions o = options_from(num_particles, motion_noise, measurement_noise, kw);
          py::gil_scoped_release release;
          return std::make_unique<FastSlam>(o);
        }),
        py::arg("num_particles"), py::arg("motion_noise"), py::arg("measurement_noise"),
        "See the class docstring for the arguments and keyword options.");
  define_state(c);
  define_calls(c);

  m.def(
      "low_variance_resample",
      [](py::handle weights, double offset) {
        const Eigen::VectorXd w = as_vector(vector_arg(weights, "weights"));
        return vector_out(low_variance_resample(w, offset));
      },
      py::arg("weights"), py::arg("offset"),
      "Low-variance (systematic) resampling (Table 4.4): (M,) int32 indices drawn at (offset + m) / M,\n"
      "m = 0 .. M - 1, over the cumulative weights (M,) (>= 0); offset in [0, 1).");
  m.def(
      "fastslam2_proposal",
      [](py::handle pose_mean, py::handle pose_cov, py::handle landmark_mean, py::handle landmark_cov, py::handle z,
         py::handle measurement_noise) {
        const PoseProposal p = fastslam2_proposal(
            pose_arg(pose_mean, "pose_mean"), Eigen::Matrix3d(square_matrix_arg(pose_cov, "pose_cov", 3)),
            fixed_vector<2>(landmark_mean, "landmark_mean"),
            Eigen::Matrix2d(square_matrix_arg(landmark_cov, "landmark_cov", 2)), fixed_vector<2>(z, "z"),
            Eigen::Matrix2d(square_matrix_arg(measurement_noise, "measurement_noise", 2)));
        return py::make_tuple(p.mean, p.cov, p.log_likelihood);
      },
      py::arg("pose_mean"), py::arg("pose_cov"), py::arg("landmark_mean"), py::arg("landmark_cov"), py::arg("z"),
      py::arg("measurement_noise"),
      "FastSLAM 2.0's proposal for one measurement z (2,) (range m, bearing rad) of a landmark with\n"
      "landmark_mean (2,), landmark_cov (2, 2), from a pose prior pose_mean (3,), pose_cov (3, 3):\n"
      "(mean (3,), cov (3, 3), log N(z - z_hat; 0, G_x pose_cov G_x^T + Q_j)).");
  m.def("_persistent_tree_nodes", [] { return g_persistent_tree_nodes.load(); },
        "Test hook: live nodes of the persistent landmark trees, over all filters.");
}

}  // namespace probslam::bindings
