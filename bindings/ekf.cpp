#include <pybind11/stl.h>

#include "numpy.hpp"
#include "probslam/core/check.hpp"
#include "probslam/ekf/ekf_slam.hpp"
#include "probslam/ekf/multi_hypothesis_ekf_slam.hpp"

namespace probslam::bindings {

namespace {

DoubleArray measurements_arg(const EkfSlam& ekf, py::handle z) {
  DoubleArray a = as_array(z, "z");
  if (a.ndim() == 1 && a.shape(0) == ekf.landmark_dim()) return DoubleArray(a.reshape({py::ssize_t{1}, a.shape(0)}));
  return matrix_arg(z, "z", ekf.landmark_dim());
}

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

}  // namespace

void define_ekf(py::module_& m) {
  py::class_<MapManagement>(m, "MapManagement", "Ch. 10.3.3 map management; every part off by default.")
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

  py::class_<EkfSlam>(m, "_EkfSlam")
      .def(py::init([](py::handle motion_noise, py::handle measurement_noise, bool use_signatures,
                       py::handle initial_pose, py::handle initial_pose_cov) {
             return EkfSlam(square_matrix_arg(motion_noise, "motion_noise"), square_matrix_arg(measurement_noise, "measurement_noise"),
                            use_signatures, pose_arg(initial_pose, "initial_pose"),
                            Eigen::Matrix3d(square_matrix_arg(initial_pose_cov, "initial_pose_cov").topLeftCorner(3, 3)));
           }),
           py::arg("motion_noise"), py::arg("measurement_noise"), py::arg("use_signatures"), py::arg("initial_pose"),
           py::arg("initial_pose_cov"))
      .def_property_readonly("state_dim", &EkfSlam::state_dim)
      .def_property_readonly("landmark_dim", &EkfSlam::landmark_dim)
      .def_property_readonly("num_landmarks", &EkfSlam::num_landmarks)
      .def_property_readonly("num_provisional", &EkfSlam::num_provisional)
      .def_property_readonly("capacity", &EkfSlam::capacity)
      .def_property_readonly("landmark_ids", [](const EkfSlam& e) {
        return py::array_t<long>(static_cast<py::ssize_t>(e.landmark_ids().size()), e.landmark_ids().data());
      })
      .def_property_readonly("mean",
                             [](EkfSlam& e) {
                               auto s = e.storage();
                               return storage_view(s, s->mean.data(), {e.state_dim()}, {sizeof(double)});
                             })
      .def_property_readonly("covariance",
                             [](EkfSlam& e) {
                               auto s = e.storage();
                               const py::ssize_t cap = s->cov.rows();
                               // Column-major storage of a symmetric matrix: either stride order reads it.
                               return storage_view(s, s->cov.data(), {e.state_dim(), e.state_dim()},
                                                   {static_cast<py::ssize_t>(sizeof(double)),
                                                    static_cast<py::ssize_t>(cap * sizeof(double))});
                             })
      .def_property_readonly("pose", &EkfSlam::pose)
      .def("landmark", &EkfSlam::landmark, py::arg("id"))
      .def("landmark_covariance", &EkfSlam::landmark_covariance, py::arg("id"))
      .def("existence", &EkfSlam::existence, py::arg("id"))
      .def("has_landmark", &EkfSlam::has_landmark, py::arg("id"))
      .def(
          "predict",
          [](EkfSlam& e, double v, double w, double dt, py::handle noise) {
            if (noise.is_none()) e.predict(v, w, dt);
            else e.predict(v, w, dt, square_matrix_arg(noise, "noise"));
          },
          py::arg("v"), py::arg("w"), py::arg("dt"), py::arg("noise") = py::none())
      .def(
          "predict_odometry",
          [](EkfSlam& e, py::handle delta, py::handle noise) {
            const Eigen::MatrixXd n = square_matrix_arg(noise, "noise");
            if (n.rows() != 3) throw py::value_error("noise must be 3x3");
            e.predict_odometry(fixed_vector<3>(delta, "delta"), n);
          },
          py::arg("delta"), py::arg("noise"))
      .def(
          "update",
          [](EkfSlam& e, py::handle z, py::handle ids, double gate) {
            DoubleArray zz = measurements_arg(e, z);
            const std::vector<long> id = ids_arg(ids, zz.shape(0));
            UpdateReport r;
            {
              py::gil_scoped_release release;
              r = e.update(as_matrix(zz), id, gate);
            }
            std::vector<bool> used(r.used.begin(), r.used.end());
            return py::make_tuple(r.nis, py::array(py::cast(used)));
          },
          py::arg("z"), py::arg("ids"), py::arg("gate") = std::numeric_limits<double>::infinity())
      .def(
          "update_unknown",
          [](EkfSlam& e, py::handle z, double alpha, double alpha_new, Association association) {
            DoubleArray zz = measurements_arg(e, z);
            AssociationReport r;
            {
              py::gil_scoped_release release;
              r = e.update_unknown(as_matrix(zz), alpha, alpha_new, association);
            }
            return py::make_tuple(py::array(py::cast(r.ids)), r.mahalanobis,
                                  py::array(py::cast(std::vector<int>(r.outcome.begin(), r.outcome.end()))),
                                  py::array(py::cast(r.removed)));
          },
          py::arg("z"), py::arg("alpha"), py::arg("alpha_new"),
          py::arg("association") = Association::kMaximumLikelihood)
      .def_property("map_management", &EkfSlam::map_management, &EkfSlam::set_map_management)
      .def_property("gate_distance", &EkfSlam::gate_distance, &EkfSlam::set_gate_distance)
      .def("remove_landmark", &EkfSlam::remove_landmark, py::arg("id"))
      .def("clone", &EkfSlam::clone)
      .def(
          "pairing_likelihood",
          [](const EkfSlam& e, py::handle z, long id) {
            DoubleArray zz = measurements_arg(e, z);
            if (zz.shape(0) != 1) throw py::value_error("z must be one measurement");
            const EkfSlam::PairingLikelihood p = e.pairing_likelihood(as_matrix(zz).row(0).transpose(), id);
            return py::make_tuple(p.nis, p.log_det);
          },
          py::arg("z"), py::arg("id"));

  py::class_<MultiHypothesisOptions>(m, "MultiHypothesisOptions",
                                     "Beam and costs (NIS units) of MultiHypothesisEkfSlam.")
      .def(py::init<>())
      .def_readwrite("max_hypotheses", &MultiHypothesisOptions::max_hypotheses)
      .def_readwrite("max_children", &MultiHypothesisOptions::max_children)
      .def_readwrite("gate", &MultiHypothesisOptions::gate)
      .def_readwrite("new_landmark_cost", &MultiHypothesisOptions::new_landmark_cost)
      .def_readwrite("clutter_cost", &MultiHypothesisOptions::clutter_cost)
      .def_readwrite("prune_margin", &MultiHypothesisOptions::prune_margin);

  using Mht = MultiHypothesisEkfSlam;
  py::class_<Mht>(m, "_MultiHypothesisEkfSlam")
      .def(py::init<const EkfSlam&, const MultiHypothesisOptions&>(), py::arg("initial"), py::arg("options"))
      .def(
          "predict",
          [](Mht& e, double v, double w, double dt, py::handle noise) {
            if (noise.is_none()) e.predict(v, w, dt);
            else e.predict(v, w, dt, square_matrix_arg(noise, "noise"));
          },
          py::arg("v"), py::arg("w"), py::arg("dt"), py::arg("noise") = py::none())
      .def(
          "update",
          [](Mht& e, py::handle z) {
            DoubleArray zz = measurements_arg(e.best(), z);
            std::vector<long> ids;
            {
              py::gil_scoped_release release;
              ids = e.update(as_matrix(zz));
            }
            return py::array(py::cast(ids));
          },
          py::arg("z"))
      .def_property_readonly("best", [](const Mht& e) { return e.best().clone(); })
      .def_property_readonly("pose", [](const Mht& e) { return e.best().pose(); })
      .def_property_readonly("num_hypotheses", &Mht::num_hypotheses)
      .def_property_readonly("total_cost", &Mht::total_cost)
      .def_property_readonly("costs", [](const Mht& e) { return py::array(py::cast(e.costs())); })
      .def_property_readonly("options", &Mht::options)
      .def("history", [](const Mht& e) {
        py::list out;
        for (const auto& ids : e.history()) out.append(py::array(py::cast(ids)));
        return out;
      });
}

}  // namespace probslam::bindings
