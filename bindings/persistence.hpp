#pragma once
// save(path) / load(path) and pickle for the stateful classes, one definition for all of them:
// the state is the C++ class's (core/state_file.hpp), pickled as its bytes.
#include <pybind11/pybind11.h>

#include <string>

#include "object_lock.hpp"
#include "probslam/core/state_file.hpp"

namespace probslam::bindings {

/// A path argument as str: str or os.PathLike (through os.fspath), else TypeError naming it.
inline std::string path_argument(const pybind11::handle& path, const char* name = "path") {
  namespace py = pybind11;
  py::object s;
  try {
    s = py::module_::import("os").attr("fspath")(path);
  } catch (py::error_already_set&) {
    throw py::type_error(std::string(name) + ": expected a file path (str or os.PathLike)");
  }
  if (!py::isinstance<py::str>(s)) throw py::type_error(std::string(name) + ": expected a file path (str or os.PathLike)");
  return s.cast<std::string>();
}

/// Adds save, load and pickle support to the binding of T (T::save, T::load, T::kStateTag,
/// write_state / read_state).
template <typename T, typename Class>
void define_persistence(Class& c) {
  namespace py = pybind11;
  const std::string name = T::kStateTag;
  c.def(
       "save",
       [](const T& self, const py::handle& path) {
         const std::string p = path_argument(path);
         locked(self, [&] { self.save(p); });
       },
       py::arg("path"),
       ("Writes the whole state to path (docs/file_format.md), bit for bit; " + name +
        ".load(path) gives an object that equals this one and continues exactly as it would.")
           .c_str())
      .def_static(
          "load",
          [](const py::handle& path) {
            const std::string p = path_argument(path);
            py::gil_scoped_release release;
            return T::load(p);
          },
          py::arg("path"),
          ("The " + name +
           " saved at path. ValueError naming the path for a file that is not a complete, undamaged " + name +
           " state of this format version; FileNotFoundError when there is none.")
              .c_str())
      .def(py::pickle(
          [](const T& self) { return py::bytes(locked(self, [&] { return state_bytes(self); })); },
          [](const py::bytes& b) {
            std::string bytes = b;
            py::gil_scoped_release release;
            return object_from_state<T>(bytes, "pickled " + std::string(T::kStateTag));
          }));
}

}  // namespace probslam::bindings
