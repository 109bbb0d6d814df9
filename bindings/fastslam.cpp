// FastSLAM (fastslam/): thin conversions only. Every method runs its C++ work through locked():
// the GIL is released, the filter's mutex taken, Python objects converted before and built after.
#include <pybind11/stl.h>

#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "args.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "options_class.hpp"
#include "persistence.hpp"
#include "repr.hpp"
#include "landmarks.hpp"
#include "probslam/core/check.hpp"
#include "probslam/fastslam/fast_slam.hpp"

namespace probslam::bindings {

namespace {

// A scan's measurements; landmark_dim is fixed at construction: no lock needed.
DoubleArray scan_arg(const FastSlam& f, py::handle z) { return measurements_arg(f.landmark_dim(), z); }

/// The result of FastSlam.update (known correspondences).
struct FastSlamUpdateResult {
  bool resampled = false;
};

/// The result of FastSlam.update_unknown: rows follow the particles after the call.
struct FastSlamAssociationResult {
  py::array_t<long> ids;      // (M, k) landmark used or created
  py::array_t<bool> is_new;   // (M, k)
  py::array_t<long> removed;  // (R, 2) rows of (particle, landmark id)
  bool resampled = false;
};

/// Particle k's landmarks' existence counters and signatures, in landmarks(k)'s order.
struct LandmarkDetails {
  py::array_t<long> ids;
  py::array_t<double> existence, signature, signature_var;
};

template <typename T>
py::array_t<T> vector_out(const std::vector<T>& v) {
  py::array_t<T> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

void define_results(py::module_& m) {
  py::class_<FastSlamUpdateResult>(m, "FastSlamUpdateResult", "What FastSlam.update did.")
      .def_readonly("resampled", &FastSlamUpdateResult::resampled, "Whether the update resampled the particles.")
      .def("__repr__", [](py::handle self) {
        return repr_of(self, std::string("resampled ") + (self.cast<const FastSlamUpdateResult&>().resampled ? "True" : "False"));
      });
  py::class_<FastSlamAssociationResult>(m, "FastSlamAssociationResult",
                                        "What FastSlam.update_unknown did with the k measurements of a scan, per\n"
                                        "particle; row j is particle j after any resampling of the call.")
      .def_readonly("ids", &FastSlamAssociationResult::ids, "(M, k) int64 landmark id used or created.")
      .def_readonly("is_new", &FastSlamAssociationResult::is_new, "(M, k) bool, True where the measurement created it.")
      .def_readonly("removed", &FastSlamAssociationResult::removed,
                    "(R, 2) int64 rows (particle, landmark id) removed by negative information or as provisional\n"
                    "landmarks not seen in min_sightings scans.")
      .def_readonly("resampled", &FastSlamAssociationResult::resampled, "Whether the update resampled the particles.")
      .def("__repr__", [](py::handle self) {
        const auto& r = self.cast<const FastSlamAssociationResult&>();
        return repr_of(self, std::to_string(r.ids.shape(0)) + " particles x " + std::to_string(r.ids.shape(1)) +
                                 " measurements, " + std::to_string(r.removed.shape(0)) + " removed, resampled " +
                                 (r.resampled ? "True" : "False"));
      });
  py::class_<LandmarkDetails>(m, "LandmarkDetails",
                              "A particle's landmarks beyond their position (FastSlam.landmark_details), in the\n"
                              "order of FastSlam.landmarks.")
      .def_readonly("ids", &LandmarkDetails::ids, "(N,) int64 landmark ids.")
      .def_readonly("existence", &LandmarkDetails::existence,
                    "(N,) existence counters (negative_information; removed below zero).")
      .def_readonly("signature", &LandmarkDetails::signature, "(N,) signature means (use_signatures; else 0).")
      .def_readonly("signature_var", &LandmarkDetails::signature_var, "(N,) signature variances.")
      .def("__len__", [](const LandmarkDetails& d) { return d.ids.shape(0); })
      .def("__repr__", [](py::handle self) {
        return repr_of(self, std::to_string(self.cast<const LandmarkDetails&>().ids.shape(0)) + " landmarks");
      });
  py::class_<MapSharing>(m, "MapSharing", "How much of the particles' maps and paths is shared (FastSlam.map_sharing).")
      .def_readonly("distinct_nodes", &MapSharing::distinct_nodes, "Tree nodes allocated for all the maps.")
      .def_readonly("total_nodes", &MapSharing::total_nodes,
                    "Sum of the per-particle tree nodes: what deep copies of the maps would hold.")
      .def_readonly("landmarks", &MapSharing::landmarks, "Sum of the per-particle landmark counts.")
      .def_readonly("path_nodes", &MapSharing::path_nodes, "Distinct path chunks.")
      .def("__repr__", [](py::handle self) {
        const MapSharing& s = self.cast<const MapSharing&>();
        return repr_of(self, std::to_string(s.distinct_nodes) + " of " + std::to_string(s.total_nodes) +
                                 " tree nodes distinct, " + std::to_string(s.landmarks) + " landmarks, " +
                                 std::to_string(s.path_nodes) + " path chunks");
      });
}

void define_state(py::class_<FastSlam>& c) {
  c.def_property_readonly("num_particles", getter(&FastSlam::num_particles), "M, the number of particles.")
      .def_property_readonly("version", getter(&FastSlam::version), "1 or 2 (FastSLAM 1.0 or 2.0).")
      .def_property_readonly("landmark_dim", getter(&FastSlam::landmark_dim),
                             "Measurement length: 2 (range, bearing) or 3 with a signature.")
      .def_property_readonly("use_signatures", [](const FastSlam& f) { return f.landmark_dim() == 3; },
                             "Whether landmarks and measurements carry a signature (3 values instead of 2).")
      .def_property_readonly("pose",
                             [](const FastSlam& f) {
                               return locked(f, [&] { return Eigen::Vector3d(f.particle(f.best_index()).pose); });
                             },
                             "(3,) the best particle's pose (x m, y m, theta rad).")
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
      .def_property_readonly("map_sharing", getter(&FastSlam::map_sharing),
                             "MapSharing: tree nodes and path chunks shared between the particles.")
      .def_property_readonly("num_landmarks",
                             [](const FastSlam& f) {
                               return locked(f, [&] { return f.particle(f.best_index()).map.size(); });
                             },
                             "Landmarks in the best particle's map (landmarks(particle) for another's).")
      .def("path",
           [](const FastSlam& f, py::handle particle) {
             const ParticleChoice k = ParticleChoice::from(particle);
             return locked(f, [&] { return f.path(k.resolve(f)); });
           },
           py::arg("particle") = py::none(),
           "(T + 1, 3) a particle's path, oldest first (default: the best particle's); (0, 3) without\n"
           "record_path.")
      .def(
          "landmarks",
          [](const FastSlam& f, py::handle particle) {
            const ParticleChoice k = ParticleChoice::from(particle);
            std::vector<LandmarkEntry> entries;
            locked(f, [&] {
              for (const Landmark& lm : f.landmarks(k.resolve(f))) entries.push_back({lm.id, lm.mean, lm.cov});
            });
            return landmark_arrays(entries);
          },
          py::arg("particle") = py::none(),
          "A particle's map as Landmarks (ids, means (N, 2) m, covariances (N, 2, 2) m^2), sorted by id\n"
          "(default: the best particle's).")
      .def(
          "landmark_details",
          [](const FastSlam& f, py::handle particle) {
            const ParticleChoice k = ParticleChoice::from(particle);
            const std::vector<Landmark> lms = locked(f, [&] { return f.landmarks(k.resolve(f)); });
            const auto n = static_cast<py::ssize_t>(lms.size());
            LandmarkDetails d{py::array_t<long>(n), py::array_t<double>(n), py::array_t<double>(n), py::array_t<double>(n)};
            for (py::ssize_t i = 0; i < n; ++i) {
              const Landmark& lm = lms[static_cast<std::size_t>(i)];
              d.ids.mutable_at(i) = lm.id;
              d.existence.mutable_at(i) = lm.existence;
              d.signature.mutable_at(i) = lm.signature;
              d.signature_var.mutable_at(i) = lm.signature_var;
            }
            return d;
          },
          py::arg("particle") = py::none(),
          "LandmarkDetails (existence, signature, signature_var) of a particle's landmarks, in the order\n"
          "of landmarks(particle) (default: the best particle's).");
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
          "predict_odometry_batch",
          [](FastSlam& f, py::handle deltas, py::handle noises) {
            const OdometryBatch b = odometry_batch_args(deltas, noises);
            locked(f, [&] { f.predict_odometry_batch(b.d(), b.n()); });
          },
          py::arg("deltas"), py::arg("noises"),
          "predict_odometry(deltas[k], noises[k]) for k = 0 .. K - 1 in one call, bit for bit the same:\n"
          "deltas (K, 3), noises (K, 3, 3). Every step is checked before any particle moves.")
      .def(
          "update",
          [](FastSlam& f, py::handle z, py::handle ids) {
            DoubleArray zz = scan_arg(f, z);
            const std::vector<long> id = ids_arg(ids, zz.shape(0));
            return FastSlamUpdateResult{locked(f, [&] { return f.update(as_matrix(zz), id); })};
          },
          py::arg("z"), py::arg("ids"),
          "Known correspondences: z (k, 2) (range m, bearing rad) or (k, 3), ids (k,) >= 0. Returns a\n"
          "FastSlamUpdateResult.")
      .def(
          "update_unknown",
          [](FastSlam& f, py::handle z, std::optional<double> p_new) {
            DoubleArray zz = scan_arg(f, z);
            const auto [r, resampled] = locked(f, [&] {
              FastSlamAssociation a = p_new ? f.update_unknown(as_matrix(zz), *p_new) : f.update_unknown(as_matrix(zz));
              return std::make_pair(std::move(a), f.resampled());
            });
            const py::ssize_t m = r.num_particles, k = r.num_measurements;
            FastSlamAssociationResult out{py::array_t<long>({m, k}), py::array_t<bool>({m, k}), py::array_t<long>(), resampled};
            std::copy(r.ids.begin(), r.ids.end(), out.ids.mutable_data());
            std::copy(r.is_new.begin(), r.is_new.end(), out.is_new.mutable_data());
            // One (R, 2) array of (particle, landmark id) rows: a list of M arrays per scan cost
            // more than the filter's update itself.
            py::ssize_t count = 0;
            for (const std::vector<long>& v : r.removed) count += static_cast<py::ssize_t>(v.size());
            out.removed = py::array_t<long>({count, py::ssize_t{2}});
            long* removed = out.removed.mutable_data();
            for (std::size_t j = 0; j < r.removed.size(); ++j) {
              for (long id : r.removed[j]) {
                *removed++ = static_cast<long>(j);
                *removed++ = id;
              }
            }
            return out;
          },
          py::arg("z"), py::arg("p_new") = py::none(),
          "Per-particle maximum-likelihood correspondences for a scan z (k, 2) or (k, 3); p_new (1 / (m\n"
          "rad)) overrides the option. Returns a FastSlamAssociationResult (ids (M, k), is_new (M, k),\n"
          "removed (R, 2) rows of (particle, landmark id) removed by negative information, resampled),\n"
          "rows following the particles after any resampling of this call.")
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
  define_results(m);
  bind_options<FastSlamOptions>(m, "FastSlamOptions",
                                 "The options of FastSlam (Probabilistic Robotics ch. 13; Montemerlo 2002, 2003).");
  py::class_<FastSlam> c(m, "FastSlam",
                         "FastSLAM 1.0 / 2.0 (Montemerlo 2002, 2003; Probabilistic Robotics ch. 13) for point landmarks\n"
                         "seen by a range-bearing(-signature) sensor. Units: metres, radians, seconds.\n"
                         "\n"
                         "FastSlam(motion_noise, measurement_noise, *, initial_pose=(0, 0, 0), options=None, **fields):\n"
                         "    motion_noise: (3, 3) pose-space covariance R of (x, y, theta) added to g(x, u), or (2, 2)\n"
                         "        control-space covariance M of (v [m/s], w [rad/s]); positive semi-definite.\n"
                         "    measurement_noise: Q, (2, 2) covariance of (range [m], bearing [rad]), or (3, 3) with the\n"
                         "        signature's variance when use_signatures.\n"
                         "    initial_pose: (3,) every particle's start pose (m, m, rad).\n"
                         "    options: a FastSlamOptions (None: the defaults); **fields set fields of it by name\n"
                         "        (num_particles=50, version=2, seed=3, ...; see FastSlamOptions for each).\n"
                         "\n"
                         "Every call validates its input first and raises ValueError / TypeError naming the argument\n"
                         "or the option's field, the filter unchanged. Calls release the GIL and are serialised by a\n"
                         "per-filter lock.");
  {
    py::options signatures;  // the fields' keywords are written from describe(), not **kwargs
    signatures.disable_function_signatures();
    c.def(py::init([](py::handle motion_noise, py::handle measurement_noise, py::handle initial_pose,
                      py::handle options, const py::kwargs& fields) {
            const Eigen::MatrixXd r = square_matrix_arg(motion_noise, "motion_noise");
            const Eigen::MatrixXd q = square_matrix_arg(measurement_noise, "measurement_noise");
            const Eigen::Vector3d x0 = pose_arg(initial_pose, "initial_pose");
            const auto o = options_arg<FastSlamOptions>(options, fields, "FastSlam()");
            py::gil_scoped_release release;
            return std::make_unique<FastSlam>(r, q, o, x0);
          }),
          py::arg("motion_noise"), py::arg("measurement_noise"), py::kw_only(),
          py::arg("initial_pose") = py::make_tuple(0.0, 0.0, 0.0), py::arg("options") = py::none(),
          options_init_signature<FastSlamOptions>(
              "FastSlam", "motion_noise: ArrayLike, measurement_noise: ArrayLike, *, initial_pose: ArrayLike = (0.0, 0.0, 0.0), ")
              .c_str());
  }
  c.def_property_readonly("options", [](const FastSlam& f) { return f.options(); },
                          "A copy of the FastSlamOptions the filter runs with.")
      .def_property_readonly("motion_noise", [](const FastSlam& f) { return f.motion_noise(); },
                             "The motion noise it was given (symmetrised): (3, 3) pose space or (2, 2) control space.")
      .def_property_readonly("measurement_noise", [](const FastSlam& f) { return f.measurement_noise(); },
                             "Q (symmetrised): (2, 2) of (range, bearing), or (3, 3) with the signature.")
      .def_property_readonly("initial_pose", [](const FastSlam& f) { return f.initial_pose(); },
                             "(3,) every particle's start pose (heading wrapped).");
  define_state(c);
  define_calls(c);
  define_persistence<FastSlam>(c);

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
