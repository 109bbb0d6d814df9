#pragma once
// What the landmark filters' bindings (EkfSlam, MultiHypothesisEkfSlam, FastSlam) share: the
// result type of landmarks(), one map's landmarks as arrays bound once as probslam.Landmarks, and
// the conversion of a scan's measurements and their ids.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <vector>

#include "numpy.hpp"

namespace probslam::bindings {

namespace py = pybind11;

struct LandmarkArrays {
  py::array_t<long> ids;             // (N,) int64
  py::array_t<double> means;         // (N, 2) m
  py::array_t<double> covariances;   // (N, 2, 2) m^2
};

/// A landmark's id, position and position covariance, as the filters hold them.
struct LandmarkEntry {
  long id;
  Eigen::Vector2d mean;
  Eigen::Matrix2d cov;
};

LandmarkArrays landmark_arrays(const std::vector<LandmarkEntry>& entries);

/// A scan's measurements z: (k, landmark_dim), or one measurement (landmark_dim,) as one row.
DoubleArray measurements_arg(int landmark_dim, py::handle z);

/// The landmark ids (k,) of k measurements, integers only (integer_array_arg refuses floats, bools
/// and unsigned values beyond long); the filters check their range.
std::vector<long> ids_arg(py::handle ids, py::ssize_t k);

/// Binds Landmarks; called before the classes whose methods return it.
void define_landmarks(py::module_& m);

}  // namespace probslam::bindings
