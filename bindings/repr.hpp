#pragma once
// Formatting for the bindings' __repr__s: "<Class: facts>" with numbers in %g style.
#include <pybind11/pybind11.h>

#include <sstream>
#include <string>

namespace probslam::bindings {

/// A number as %g would print it (0.05, 1228, 1e-06), not std::to_string's fixed 6 decimals.
inline std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

/// "<Name: body>" where Name is the Python type of self (a subclass shows its own name).
inline std::string repr_of(pybind11::handle self, const std::string& body) {
  const std::string name = pybind11::str(pybind11::type::handle_of(self).attr("__name__"));
  return "<" + name + ": " + body + ">";
}

}  // namespace probslam::bindings
