#include <pybind11/stl.h>

#include <limits>
#include <optional>
#include <utility>

#include "numpy.hpp"
#include "object_lock.hpp"
#include "probslam/core/check.hpp"
#include "probslam/ekf/ekf_slam.hpp"
#include "probslam/ekf/multi_hypothesis_ekf_slam.hpp"

// Every method runs its C++ work through locked(): the GIL is released, the object's mutex is
// taken, and Python objects are converted before and built after (README "Reliability").
namespace probslam::bindings {

namespace {

DoubleArray measurements_arg(int landmark_dim, py::handle z) {
  DoubleArray a = as_array(z, "z");
  if (a.ndim() == 1 && a.shape(0) == landmark_dim) return DoubleArray(a.reshape({py::ssize_t{1}, a.shape(0)}));
  return matrix_arg(z, "z", landmark_dim);
}

DoubleArray measurements_arg(const EkfSlam& e, py::handle z) { return measurements_arg(getter(&EkfSlam::landmark_dim)(e), z); }

// Integer ids (integer_array_arg refuses floats, bools and unsigned values beyond long); range checks (ids in [0, 2^62]) are EkfSlam::update's own.
std::vector<long> ids_arg(py::handle ids, py::ssize_t k) {
  LongArray a = integer_array_arg(ids, "ids");
  if (a.ndim() == 0) a = a.reshape({py::ssize_t{1}});
  if (a.ndim() != 1 || a.shape(0) != k)
    throw py::value_error("ids must have shape (" + std::to_string(k) + ",), one id per measurement");
  return std::vector<long>(a.data(), a.data() + a.shape(0));
}

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
  py::class_<MapManagement>(m, "MapManagement",
                            "Ch. 10.3.3 map management; every part off by default. Values are checked when the "
                            "options are given to a filter.")
      .def(py::init<>())
      .def_readwrite("provisional", &MapManagement::provisional)
      .def_readwrite("min_observations", &MapManagement::min_observations)
      .def_readwrite("provisional_max_std", &MapManagement::provisional_max_std)
      .def_readwrite("provisional_max_age", &MapManagement::provisional_max_age)
      .def_readwrite("existence", &MapManagement::existence)
      .def_readwrite("existence_hit", &MapManagement::existence_hit)
      .def_readwrite("existence_miss", &MapManagement::existence_miss)
      .def_readwrite("existence_threshold", &MapManagement::existence_threshold)
      .def_readwrite("sensor_range", &MapManagement::sensor_range)
      .def_readwrite("sensor_fov", &MapManagement::sensor_fov);

  py::enum_<Association>(m, "Association", "How update_unknown pairs a scan's measurements with landmarks.")
      .value("MAXIMUM_LIKELIHOOD", Association::kMaximumLikelihood)
      .value("JOINT_COMPATIBILITY", Association::kJointCompatibility);

  py::class_<MultiHypothesisOptions>(m, "MultiHypothesisOptions",
                                     "Beam and costs (NIS units) of MultiHypothesisEkfSlam; checked when given to it.")
      .def(py::init<>())
      .def_readwrite("max_hypotheses", &MultiHypothesisOptions::max_hypotheses)
      .def_readwrite("max_children", &MultiHypothesisOptions::max_children)
      .def_readwrite("gate", &MultiHypothesisOptions::gate)
      .def_readwrite("new_landmark_cost", &MultiHypothesisOptions::new_landmark_cost)
      .def_readwrite("clutter_cost", &MultiHypothesisOptions::clutter_cost)
      .def_readwrite("prune_margin", &MultiHypothesisOptions::prune_margin);
}

void define_ekf_state(py::class_<EkfSlam>& c) {
  c.def_property_readonly("state_dim", getter(&EkfSlam::state_dim))
      .def_property_readonly("landmark_dim", getter(&EkfSlam::landmark_dim))
      .def_property_readonly("num_landmarks", getter(&EkfSlam::num_landmarks))
      .def_property_readonly("num_provisional", getter(&EkfSlam::num_provisional))
      .def_property_readonly("capacity", getter(&EkfSlam::capacity))
      .def_property_readonly("landmark_ids",
                             [](const EkfSlam& e) {
                               const std::vector<long> ids = locked(e, [&] { return e.landmark_ids(); });
                               return py::array_t<long>(static_cast<py::ssize_t>(ids.size()), ids.data());
                             })
      .def_property_readonly("mean",
                             [](const EkfSlam& e) {
                               auto [s, n] = storage_of(e);
                               return storage_view(s, s->mean.data(), {n}, {sizeof(double)});
                             })
      .def_property_readonly("covariance",
                             [](const EkfSlam& e) {
                               auto [s, n] = storage_of(e);
                               const py::ssize_t cap = s->cov.rows();
                               // Column-major storage of a symmetric matrix: either stride order reads it.
                               return storage_view(s, s->cov.data(), {n, n},
                                                   {static_cast<py::ssize_t>(sizeof(double)),
                                                    static_cast<py::ssize_t>(cap * sizeof(double))});
                             })
      .def_property_readonly("pose", getter(&EkfSlam::pose))
      .def("landmark", [](const EkfSlam& e, long id) { return locked(e, [&] { return e.landmark(id); }); },
           py::arg("id"))
      .def("landmark_covariance",
           [](const EkfSlam& e, long id) { return locked(e, [&] { return e.landmark_covariance(id); }); },
           py::arg("id"))
      .def("existence", [](const EkfSlam& e, long id) { return locked(e, [&] { return e.existence(id); }); },
           py::arg("id"))
      .def("has_landmark", [](const EkfSlam& e, long id) { return locked(e, [&] { return e.has_landmark(id); }); },
           py::arg("id"))
      .def_property(
          "map_management", getter(&EkfSlam::map_management),
          [](EkfSlam& e, const MapManagement& m) { locked(e, [&] { e.set_map_management(m); }); })
      .def_property(
          "gate_distance", getter(&EkfSlam::gate_distance),
          [](EkfSlam& e, double metres) { locked(e, [&] { e.set_gate_distance(metres); }); })
      .def("clone", [](const EkfSlam& e) { return locked(e, [&] { return e.clone(); }); });
}

void define_ekf_calls(py::class_<EkfSlam>& c) {
  c.def(
       "predict",
       &predict_locked<EkfSlam>,
       py::arg("v"), py::arg("w"), py::arg("dt"), py::arg("noise") = py::none())
      .def(
          "predict_odometry",
          [](EkfSlam& e, py::handle delta, py::handle noise) {
            const Eigen::Vector3d d = fixed_vector<3>(delta, "delta");
            const Eigen::Matrix3d n = square_matrix_arg(noise, "noise", 3);
            locked(e, [&] { e.predict_odometry(d, n); });
          },
          py::arg("delta"), py::arg("noise"))
      .def(
          "update",
          [](EkfSlam& e, py::handle z, py::handle ids, double gate) {
            DoubleArray zz = measurements_arg(e, z);
            const std::vector<long> id = ids_arg(ids, zz.shape(0));
            const UpdateReport r = locked(e, [&] { return e.update(as_matrix(zz), id, gate); });
            std::vector<bool> used(r.used.begin(), r.used.end());
            return py::make_tuple(r.nis, py::array(py::cast(used)));
          },
          py::arg("z"), py::arg("ids"), py::arg("gate") = std::numeric_limits<double>::infinity())
      .def(
          "update_unknown",
          [](EkfSlam& e, py::handle z, double alpha, double alpha_new, Association association) {
            DoubleArray zz = measurements_arg(e, z);
            const AssociationReport r =
                locked(e, [&] { return e.update_unknown(as_matrix(zz), alpha, alpha_new, association); });
            return py::make_tuple(py::array(py::cast(r.ids)), r.mahalanobis,
                                  py::array(py::cast(std::vector<int>(r.outcome.begin(), r.outcome.end()))),
                                  py::array(py::cast(r.removed)));
          },
          py::arg("z"), py::arg("alpha"), py::arg("alpha_new"),
          py::arg("association") = Association::kMaximumLikelihood)
      .def(
          "remove_landmark", [](EkfSlam& e, long id) { locked(e, [&] { e.remove_landmark(id); }); }, py::arg("id"))
      .def(
          "pairing_likelihood",
          [](const EkfSlam& e, py::handle z, long id) {
            DoubleArray zz = measurements_arg(e, z);
            if (zz.shape(0) != 1) throw py::value_error("z must be one measurement");
            const Eigen::VectorXd zi = as_matrix(zz).row(0).transpose();
            const EkfSlam::PairingLikelihood p = locked(e, [&] { return e.pairing_likelihood(zi, id); });
            return py::make_tuple(p.nis, p.log_det);
          },
          py::arg("z"), py::arg("id"));
}

void define_multi_hypothesis(py::module_& m) {
  using Mht = MultiHypothesisEkfSlam;
  py::class_<Mht>(m, "_MultiHypothesisEkfSlam")
      .def(py::init([](const EkfSlam& initial, const MultiHypothesisOptions& options) {
             return locked(initial, [&] { return std::make_unique<Mht>(initial, options); });
           }),
           py::arg("initial"), py::arg("options"))
      .def(
          "predict",
          &predict_locked<Mht>,
          py::arg("v"), py::arg("w"), py::arg("dt"), py::arg("noise") = py::none())
      .def(
          "update",
          [](Mht& e, py::handle z) {
            DoubleArray zz = measurements_arg(locked(e, [&] { return e.best().landmark_dim(); }), z);
            const std::vector<long> ids = locked(e, [&] { return e.update(as_matrix(zz)); });
            return py::array(py::cast(ids));
          },
          py::arg("z"))
      .def_property_readonly("best", [](const Mht& e) { return locked(e, [&] { return e.best().clone(); }); })
      .def_property_readonly("pose", [](const Mht& e) { return locked(e, [&] { return e.best().pose(); }); })
      .def_property_readonly("num_hypotheses", getter(&Mht::num_hypotheses))
      .def_property_readonly("total_cost", getter(&Mht::total_cost))
      .def_property_readonly("costs", [](const Mht& e) { return py::array(py::cast(locked(e, [&] { return e.costs(); }))); })
      .def_property_readonly("options", getter(&Mht::options))
      .def("history", [](const Mht& e) {
        py::list out;
        for (const auto& ids : locked(e, [&] { return e.history(); })) out.append(py::array(py::cast(ids)));
        return out;
      });
}

}  // namespace

void define_ekf(py::module_& m) {
  define_options(m);
  py::class_<EkfSlam> c(m, "_EkfSlam");
  c.def(py::init([](py::handle motion_noise, py::handle measurement_noise, bool use_signatures, py::handle initial_pose,
                    py::handle initial_pose_cov) {
          return EkfSlam(square_matrix_arg(motion_noise, "motion_noise"),
                         square_matrix_arg(measurement_noise, "measurement_noise"), use_signatures,
                         pose_arg(initial_pose, "initial_pose"),
                         Eigen::Matrix3d(square_matrix_arg(initial_pose_cov, "initial_pose_cov", 3)));
        }),
        py::arg("motion_noise"), py::arg("measurement_noise"), py::arg("use_signatures"), py::arg("initial_pose"),
        py::arg("initial_pose_cov"));
  define_ekf_state(c);
  define_ekf_calls(c);
  define_multi_hypothesis(m);
}

}  // namespace probslam::bindings
