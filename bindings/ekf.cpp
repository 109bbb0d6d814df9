#include <pybind11/stl.h>

#include <limits>
#include <optional>
#include <utility>

#include "numpy.hpp"
#include "object_lock.hpp"
#include "options_class.hpp"
#include "persistence.hpp"
#include "landmarks.hpp"
#include "repr.hpp"
#include "probslam/core/check.hpp"
#include "probslam/ekf/ekf_slam.hpp"
#include "probslam/ekf/multi_hypothesis_ekf_slam.hpp"

// Every method runs its C++ work through locked(): the GIL is released, the object's mutex is
// taken, and Python objects are converted before and built after (README "Reliability").
namespace probslam::bindings {

namespace {

// A scan's measurements; landmark_dim read under the lock.
DoubleArray scan_arg(const EkfSlam& e, py::handle z) { return measurements_arg(getter(&EkfSlam::landmark_dim)(e), z); }

// A view into the filter's storage that keeps that storage (not the filter) alive.
py::array storage_view(const std::shared_ptr<EkfSlamStorage>& s, double* data, std::vector<py::ssize_t> shape,
                       std::vector<py::ssize_t> strides) {
  auto* keep = new std::shared_ptr<EkfSlamStorage>(s);
  py::capsule owner(keep, [](void* p) { delete static_cast<std::shared_ptr<EkfSlamStorage>*>(p); });
  return py::array_t<double>(shape, strides, data, owner);
}

// The storage and the state dimension, read under the lock (growth swaps the storage).
std::pair<std::shared_ptr<EkfSlamStorage>, int> storage_of(const EkfSlam& e) {
  return locked(e, [&] { return std::make_pair(e.storage(), e.state_dim()); });
}

// predict(v, w, dt[, noise]) of an EkfSlam or a MultiHypothesisEkfSlam, under its lock.
template <typename Filter>
void predict_locked(Filter& f, double v, double w, double dt, py::handle noise) {
  const std::optional<Eigen::MatrixXd> n =
      noise.is_none() ? std::nullopt : std::optional<Eigen::MatrixXd>(square_matrix_arg(noise, "noise"));
  locked(f, [&] {
    if (n) f.predict(v, w, dt, *n);
    else f.predict(v, w, dt);
  });
}

void define_options(py::module_& m) {
  bind_options<MapManagement>(m, "MapManagement",
                              "Ch. 10.3.3 map management of EkfSlam.update_unknown; every part off by default.");

  py::enum_<Association>(m, "Association", "How update_unknown pairs a scan's measurements with landmarks.")
      .value("MAXIMUM_LIKELIHOOD", Association::kMaximumLikelihood,
             "Table 10.2: the pairs of smallest Mahalanobis distance first.")
      .value("JOINT_COMPATIBILITY", Association::kJointCompatibility,
             "Joint compatibility branch and bound over the scan (Neira & Tardos 2001).");

  bind_options<MultiHypothesisOptions>(m, "MultiHypothesisOptions",
                                       "Beam and costs (NIS units) of MultiHypothesisEkfSlam.");
}

void define_ekf_state(py::class_<EkfSlam>& c) {
  c.def_property_readonly("state_dim", getter(&EkfSlam::state_dim),
                          "Length of the dense state: 3 + 2 * num_landmarks (signatures are kept apart:\n"
                          "see signatures).")
      .def_property_readonly("landmark_dim", getter(&EkfSlam::landmark_dim),
                             "2 (x, y) m, or 3 with a signature.")
      .def_property_readonly("num_landmarks", getter(&EkfSlam::num_landmarks), "Landmarks in the state.")
      .def_property_readonly("num_provisional", getter(&EkfSlam::num_provisional),
                             "Landmarks waiting on the provisional list (MapManagement.provisional).")
      .def_property_readonly("capacity", getter(&EkfSlam::capacity),
                             "State length the storage holds before it grows.")
      .def("landmarks",
           [](const EkfSlam& e) {
             std::vector<LandmarkEntry> entries;
             locked(e, [&] {
               for (const long id : e.landmark_ids()) {
                 const Eigen::VectorXd mean = e.landmark(id);
                 const Eigen::MatrixXd cov = e.landmark_covariance(id);
                 entries.push_back({id, mean.head<2>(), cov.topLeftCorner<2, 2>()});
               }
             });
             return landmark_arrays(entries);
           },
           "The map as Landmarks (ids, means (N, 2) m, covariances (N, 2, 2) m^2), in state order.")
      .def_property_readonly("mean",
                             [](const EkfSlam& e) {
                               auto [s, n] = storage_of(e);
                               return storage_view(s, s->mean.data(), {n}, {sizeof(double)});
                             },
                             "(state_dim,) mean (x, y, theta, then each landmark's x, y), a zero-copy view of\n"
                             "the storage (stale once the state grows).")
      .def_property_readonly("covariance",
                             [](const EkfSlam& e) {
                               auto [s, n] = storage_of(e);
                               const py::ssize_t cap = s->cov.rows();
                               // Column-major storage of a symmetric matrix: either stride order reads it.
                               return storage_view(s, s->cov.data(), {n, n},
                                                   {static_cast<py::ssize_t>(sizeof(double)),
                                                    static_cast<py::ssize_t>(cap * sizeof(double))});
                             },
                             "(state_dim, state_dim) covariance, a zero-copy view of the storage (stale once\n"
                             "the state grows).")
      .def_property_readonly("signatures",
                             [](const EkfSlam& e) {
                               return locked(e, [&] {
                                 const std::vector<double>& m = e.signatures();
                                 Eigen::MatrixX2d out(static_cast<Eigen::Index>(m.size()), 2);
                                 for (std::size_t j = 0; j < m.size(); ++j)
                                   out.row(static_cast<Eigen::Index>(j)) << m[j], e.signature_variances()[j];
                                 return out;
                               });
                             },
                             "(num_landmarks, 2) each landmark's signature mean and variance in state order,\n"
                             "a copy ((0, 2) without signatures): kept apart from the dense state, with which\n"
                             "it is uncorrelated.")
      .def_property_readonly("pose", getter(&EkfSlam::pose), "(3,) mean pose (x m, y m, theta rad), a copy.")
      .def("landmark", [](const EkfSlam& e, long id) { return locked(e, [&] { return e.landmark(id); }); },
           py::arg("id"), "Mean (landmark_dim,) of landmark id: (x, y) m[, signature].")
      .def("landmark_covariance",
           [](const EkfSlam& e, long id) { return locked(e, [&] { return e.landmark_covariance(id); }); },
           py::arg("id"), "(landmark_dim, landmark_dim) covariance of landmark id.")
      .def("existence", [](const EkfSlam& e, long id) { return locked(e, [&] { return e.existence(id); }); },
           py::arg("id"), "Existence log-odds o_j of landmark id (MapManagement.existence).")
      .def("has_landmark", [](const EkfSlam& e, long id) { return locked(e, [&] { return e.has_landmark(id); }); },
           py::arg("id"), "Whether landmark id is in the state.")
      .def_property(
          "map_management", getter(&EkfSlam::map_management),
          [](EkfSlam& e, const MapManagement& m) { locked(e, [&] { e.set_map_management(m); }); },
          "Map management of update_unknown (a copy; assign a MapManagement to change it).")
      .def_property(
          "gate_distance", getter(&EkfSlam::gate_distance),
          [](EkfSlam& e, RealArg metres_arg) {
            const double metres = metres_arg.get("gate_distance");
            locked(e, [&] { e.set_gate_distance(metres); });
          },
          "Association candidates: landmarks within this distance (m) of where a measurement places\n"
          "its landmark, plus three standard deviations (5.0).")
      .def("copy", [](const EkfSlam& e) { return locked(e, [&] { return EkfSlam(e); }); },
           "An independent copy with its own storage.")
      .def("__repr__", [](py::handle self) {
        const EkfSlam& e = self.cast<const EkfSlam&>();
        return repr_of(self, locked(e, [&] {
          const Eigen::Vector3d p = e.pose();
          return std::to_string(e.num_landmarks()) + " landmarks, state " + std::to_string(e.state_dim()) +
                 ", pose (" + num(p.x()) + ", " + num(p.y()) + ", " + num(p.z()) + ")";
        }));
      });
}

void define_ekf_calls(py::class_<EkfSlam>& c) {
  c.def(
       "predict",
       &predict_locked<EkfSlam>,
       py::arg("v"), py::arg("w"), py::arg("dt"), py::arg("noise") = py::none(),
       "Table 10.1 lines 2-5: velocity motion v (m/s), w (rad/s) for dt (s); noise: this call's (3, 3)\n"
       "pose-space or (2, 2) control-space covariance (default: the filter's motion noise).")
      .def(
          "predict_odometry",
          &predict_odometry_locked<EkfSlam>,
          py::arg("delta"), py::arg("noise"),
          "Odometry as a relative pose: x <- x (+) delta, delta (3,) (m, m, rad) with covariance noise\n"
          "(3, 3) in the robot frame.")
      .def(
          "predict_odometry_batch",
          [](EkfSlam& e, py::handle deltas, py::handle noises) {
            const OdometryBatch b = odometry_batch_args(deltas, noises);
            Poses2 poses = locked(e, [&] { return e.predict_odometry_batch(b.d(), b.n()); });
            return py::array_t<double>({poses.rows(), Eigen::Index{3}}, poses.data());
          },
          py::arg("deltas"), py::arg("noises"),
          "predict_odometry(deltas[k], noises[k]) for k = 0 .. K - 1 in one call: deltas (K, 3), noises\n"
          "(K, 3, 3); returns the pose after each step (K, 3). The landmarks' cross covariances are\n"
          "moved once, by the steps' composed Jacobian (equal to K calls up to rounding).")
      .def(
          "update",
          [](EkfSlam& e, py::handle z, py::handle ids, double gate) {
            DoubleArray zz = scan_arg(e, z);
            const std::vector<long> id = ids_arg(ids, zz.shape(0));
            const UpdateReport r = locked(e, [&] { return e.update(as_matrix(zz), id, gate); });
            std::vector<bool> used(r.used.begin(), r.used.end());
            return py::make_tuple(r.nis, py::array(py::cast(used)));
          },
          py::arg("z"), py::arg("ids"), py::arg("gate") = std::numeric_limits<double>::infinity(),
          "Table 10.1 lines 6-20, known correspondences: z (k, 2) (range m, bearing rad) or (k, 3) with\n"
          "signatures, ids (k,) landmark ids; new ids are added. Measurements with NIS > gate are\n"
          "skipped. Returns (nis (k,), NaN for first sightings; used (k,) bool).")
      .def(
          "update_unknown",
          [](EkfSlam& e, py::handle z, double alpha, double alpha_new, Association association) {
            DoubleArray zz = scan_arg(e, z);
            const AssociationReport r =
                locked(e, [&] { return e.update_unknown(as_matrix(zz), alpha, alpha_new, association); });
            return py::make_tuple(py::array(py::cast(r.ids)), r.mahalanobis,
                                  py::array(py::cast(std::vector<int>(r.outcome.begin(), r.outcome.end()))),
                                  py::array(py::cast(r.removed)));
          },
          py::arg("z"), py::arg("alpha"), py::arg("alpha_new"),
          py::arg("association") = Association::kMaximumLikelihood,
          "Table 10.2, unknown correspondences for a scan z (k, 2) or (k, 3): candidates with\n"
          "Mahalanobis distance pi <= alpha; a measurement farther than alpha_new from every free\n"
          "landmark starts a new one. Returns (ids (k,), -1 if none; smallest pi (k,); outcome (k,):\n"
          "0 associated, 1 new landmark, 2 provisional, 3 discarded; removed ids).")
      .def(
          "remove_landmark", [](EkfSlam& e, long id) { locked(e, [&] { e.remove_landmark(id); }); }, py::arg("id"),
          "Marginalises landmark id out of the state.")
      .def(
          "pairing_likelihood",
          [](const EkfSlam& e, py::handle z, long id) {
            DoubleArray zz = scan_arg(e, z);
            if (zz.shape(0) != 1) throw py::value_error("z must be one measurement");
            const Eigen::VectorXd zi = as_matrix(zz).row(0).transpose();
            const EkfSlam::PairingLikelihood p = locked(e, [&] { return e.pairing_likelihood(zi, id); });
            return py::make_tuple(p.nis, p.log_det);
          },
          py::arg("z"), py::arg("id"),
          "(NIS, log det(2 pi S)) of one measurement z (landmark_dim,) against landmark id, without\n"
          "updating; their sum is -2 log N(nu; 0, S).");
}

void define_multi_hypothesis(py::module_& m) {
  using Mht = MultiHypothesisEkfSlam;
  auto mht_class = py::class_<Mht>(m, "_MultiHypothesisEkfSlam",
                  "A beam of EKF SLAM filters over data-association hypotheses (probslam.ekf.MultiHypothesisEkfSlam\n"
                  "is the public face).")
      .def(py::init([](const EkfSlam& initial, const MultiHypothesisOptions& options) {
             return locked(initial, [&] { return std::make_unique<Mht>(initial, options); });
           }),
           py::arg("initial"), py::arg("options"), "One hypothesis, a copy of initial.")
      .def(
          "predict",
          &predict_locked<Mht>,
          py::arg("v"), py::arg("w"), py::arg("dt"), py::arg("noise") = py::none(),
          "EkfSlam.predict on every hypothesis: v m/s, w rad/s, dt s.")
      .def(
          "update",
          [](Mht& e, py::handle z) {
            DoubleArray zz = measurements_arg(locked(e, [&] { return e.best().landmark_dim(); }), z);
            const std::vector<long> ids = locked(e, [&] { return e.update(as_matrix(zz)); });
            return py::array(py::cast(ids));
          },
          py::arg("z"),
          "Branches every hypothesis on the assignments of scan z (k, 2) or (k, 3), keeps the beam;\n"
          "returns the best hypothesis's landmark id per measurement (k,), -1 for clutter.")
      .def_property_readonly("best", [](const Mht& e) { return locked(e, [&] { return EkfSlam(e.best()); }); },
                             "A copy of the cheapest hypothesis's filter.")
      .def_property_readonly("pose", [](const Mht& e) { return locked(e, [&] { return e.best().pose(); }); },
                             "(3,) pose of the cheapest hypothesis.")
      .def_property_readonly("num_hypotheses", getter(&Mht::num_hypotheses), "Hypotheses in the beam.")
      .def_property_readonly("total_cost", getter(&Mht::total_cost), "The cheapest hypothesis's cost, NIS units.")
      .def_property_readonly("costs", [](const Mht& e) { return py::array(py::cast(locked(e, [&] { return e.costs(); }))); },
                             "(H,) each hypothesis's cost above the best, ascending.")
      .def_property_readonly("options", getter(&Mht::options), "The MultiHypothesisOptions in use (a copy).")
      .def("history", [](const Mht& e) {
        py::list out;
        for (const auto& ids : locked(e, [&] { return e.history(); })) out.append(py::array(py::cast(ids)));
        return out;
      }, "The best hypothesis's assignments, one (k,) array of landmark ids per scan so far.")
      .def("copy", [](const Mht& e) { return locked(e, [&] { return Mht(e); }); },
           "An independent deep copy (every hypothesis, its history and costs).")
      .def("__repr__", [](py::handle self) {
        const Mht& e = self.cast<const Mht&>();
        return repr_of(self, locked(e, [&] {
          return std::to_string(e.num_hypotheses()) + " hypotheses, best " + std::to_string(e.best().num_landmarks()) +
                 " landmarks, cost " + num(e.total_cost());
        }));
      });
  define_persistence<Mht>(mht_class);
}

}  // namespace

void define_ekf(py::module_& m) {
  define_options(m);
  py::class_<EkfSlam> c(m, "_EkfSlam",
                        "EKF SLAM (ch. 10) with point landmarks and range-bearing measurements; the public face is\n"
                        "probslam.ekf.EkfSlam. Units: metres, radians, seconds.");
  c.def(py::init([](py::handle motion_noise, py::handle measurement_noise, bool use_signatures, py::handle initial_pose,
                    py::handle initial_pose_cov) {
          return EkfSlam(square_matrix_arg(motion_noise, "motion_noise"),
                         square_matrix_arg(measurement_noise, "measurement_noise"), use_signatures,
                         pose_arg(initial_pose, "initial_pose"),
                         Eigen::Matrix3d(square_matrix_arg(initial_pose_cov, "initial_pose_cov", 3)));
        }),
        py::arg("motion_noise"), py::arg("measurement_noise"), py::arg("use_signatures"), py::arg("initial_pose"),
        py::arg("initial_pose_cov"),
        "motion_noise: (3, 3) pose-space R or (2, 2) control-space M of (v, w); measurement_noise: Q,\n"
        "(2, 2) of (range m, bearing rad) or (3, 3) with the signature; initial_pose (3,),\n"
        "initial_pose_cov (3, 3).");
  define_ekf_state(c);
  define_ekf_calls(c);
  define_persistence<EkfSlam>(c);
  define_multi_hypothesis(m);
}

}  // namespace probslam::bindings
