#pragma once
// Keyword options of the bindings' stateful classes (SubmapSlam2D, IncrementalScanMatcher,
// FastSlam), parsed by name with their types checked.
#include <pybind11/pybind11.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace probslam::bindings {

namespace py = pybind11;

/// An int argument (a Python int or anything with __index__, such as numpy.int64; not a bool)
/// as a Python int: TypeError "<name> must be an int" for anything else (an array of several
/// numbers has __index__ but refuses it).
inline py::object index_object(py::handle v, const std::string& name) {
  if (py::isinstance<py::bool_>(v) || !PyIndex_Check(v.ptr())) throw py::type_error(name + " must be an int");
  py::object i = py::reinterpret_steal<py::object>(PyNumber_Index(v.ptr()));
  if (!i) {
    PyErr_Clear();  // TypeError of a non-scalar array
    throw py::type_error(name + " must be an int");
  }
  return i;
}

/// index_object as a long long: ValueError "<name> is out of range" beyond 64 bits.
inline long long index_value(py::handle v, const std::string& name) {
  const py::object i = index_object(v, name);
  int overflow = 0;
  const long long x = PyLong_AsLongLongAndOverflow(i.ptr(), &overflow);
  if (overflow != 0) throw py::value_error(name + " is out of range");
  if (x == -1 && PyErr_Occurred()) throw py::error_already_set();
  return x;
}

/// index_value within [lo, hi]: ValueError "<name> must lie in [lo, hi], got x".
inline int int_value(py::handle v, const std::string& name, int lo = std::numeric_limits<int>::min(),
                     int hi = std::numeric_limits<int>::max()) {
  const long long x = index_value(v, name);
  if (x < lo || x > hi)
    throw py::value_error(name + " must lie in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                          std::to_string(x));
  return static_cast<int>(x);
}

/// A positional int argument as the caller passed it, checked in the function body by
/// `.get(name)`: pybind11's own int caster refuses 2**40 by failing overload resolution, a
/// multi-line TypeError listing every signature that never names the argument. Signatures still
/// show `int`.
struct IntArg {
  py::object value;
  int get(const char* name, int lo = std::numeric_limits<int>::min(), int hi = std::numeric_limits<int>::max()) const {
    return int_value(value, name, lo, hi);
  }
};

/// Keyword options of the stateful classes: each name read once with its type checked (a bool
/// is not a number here), and any name left over is a TypeError, as for a Python signature.
class Kwargs {
 public:
  explicit Kwargs(const py::kwargs& kw) : kw_(kw) {}
  void get(const char* name, double& target) {
    if (const py::handle v = take(name)) {
      if (py::isinstance<py::bool_>(v) || !PyNumber_Check(v.ptr()) || PyComplex_Check(v.ptr()))
        throw py::type_error(std::string(name) + " must be a real number");
      target = v.cast<double>();
    }
  }
  void get(const char* name, int& target) {
    if (const py::handle v = take(name)) {
      target = int_value(v, name);
    }
  }
  void get(const char* name, std::uint64_t& target) {
    if (const py::handle v = take(name)) {
      const py::object i = index_object(v, name);
      const unsigned long long x = PyLong_AsUnsignedLongLong(i.ptr());
      if (x == static_cast<unsigned long long>(-1) && PyErr_Occurred()) {
        PyErr_Clear();  // OverflowError: negative or beyond 64 bits
        throw py::value_error(std::string(name) + " must be in [0, 2^64)");
      }
      target = static_cast<std::uint64_t>(x);
    }
  }
  void get(const char* name, bool& target) {
    if (const py::handle v = take(name)) {
      if (!py::isinstance<py::bool_>(v)) throw py::type_error(std::string(name) + " must be a bool");
      target = v.cast<bool>();
    }
  }
  py::handle take(const char* name) {
    if (!kw_.contains(name)) return py::handle();
    used_.emplace_back(name);
    return kw_[name];
  }
  void finish() const {
    for (const auto& item : kw_) {
      const std::string key = py::str(item.first);
      if (std::find(used_.begin(), used_.end(), key) == used_.end())
        throw py::type_error("unexpected keyword argument '" + key + "'");
    }
  }

 private:
  py::kwargs kw_;
  std::vector<std::string> used_;
};

}  // namespace probslam::bindings

namespace pybind11::detail {
template <>
struct type_caster<probslam::bindings::IntArg> {
  PYBIND11_TYPE_CASTER(probslam::bindings::IntArg, const_name("int"));
  bool load(handle src, bool) {
    value.value = reinterpret_borrow<object>(src);
    return true;
  }
  static handle cast(const probslam::bindings::IntArg& v, return_value_policy, handle) { return v.value.inc_ref(); }
};
}  // namespace pybind11::detail
