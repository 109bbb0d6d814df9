#pragma once
// The result type of the landmark filters' landmarks() (EkfSlam and FastSlam): one map's
// landmarks as arrays, bound once as probslam.Landmarks.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <vector>

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

/// Binds Landmarks; called before the classes whose methods return it.
void define_landmarks(py::module_& m);

}  // namespace probslam::bindings
