#include <pybind11/pybind11.h>

#include "exceptions.hpp"

namespace probslam::bindings {
void define_core(pybind11::module_& m);
void define_grid(pybind11::module_& m);
void define_forward_model(pybind11::module_& m);
void define_grid3d(pybind11::module_& m);
void define_io(pybind11::module_& m);
void define_landmarks(pybind11::module_& m);
void define_ekf(pybind11::module_& m);
void define_fastslam(pybind11::module_& m);
void define_graph(pybind11::module_& m);
void define_graph3d(pybind11::module_& m);
void define_information_form(pybind11::module_& m);
void define_slam2d(pybind11::module_& m);
void define_localization(pybind11::module_& m);
}  // namespace probslam::bindings

PYBIND11_MODULE(_core, m) {
  m.doc() = "probslam's C++ core; use the pure-Python API in the probslam package.";
  probslam::bindings::register_exception_translator();
  probslam::bindings::define_core(m);
  probslam::bindings::define_grid(m);
  probslam::bindings::define_forward_model(m);
  probslam::bindings::define_grid3d(m);
  probslam::bindings::define_io(m);
  probslam::bindings::define_landmarks(m);
  probslam::bindings::define_ekf(m);
  probslam::bindings::define_fastslam(m);
  probslam::bindings::define_graph(m);
  probslam::bindings::define_graph3d(m);
  probslam::bindings::define_information_form(m);
  probslam::bindings::define_slam2d(m);
  probslam::bindings::define_localization(m);
}
