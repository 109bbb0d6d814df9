#pragma once
// Arguments whose type the bindings check themselves, so that an error names the argument.
//
// pybind11's own casters refuse a wrong type (or an int beyond 32 bits) by failing overload
// resolution: a multi-line TypeError listing every signature, which never names the argument,
// and a bool passes as a number. The types below accept any Python object, show the expected
// type in the generated signature (`int`, `float`, `bool`, `str`), and are checked in the body
// with `.get(name)`: TypeError "<name> must be ..." or ValueError "<name> must lie in ...".
#include <pybind11/pybind11.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "probslam/core/check.hpp"

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

/// An int argument: `.get(name)` within [lo, hi] (32 bits by default). Signature: `int`.
struct IntArg {
  py::object value;
  int get(const char* name, int lo = std::numeric_limits<int>::min(), int hi = std::numeric_limits<int>::max()) const {
    return int_value(value, name, lo, hi);
  }
};

/// An unsigned 64-bit int argument (a seed): ValueError "<name> must be in [0, 2^64)" outside.
/// Signature: `int`.
struct UInt64Arg {
  py::object value;
  std::uint64_t get(const char* name) const {
    const py::object i = index_object(value, name);
    const unsigned long long x = PyLong_AsUnsignedLongLong(i.ptr());
    if (x == static_cast<unsigned long long>(-1) && PyErr_Occurred()) {
      PyErr_Clear();  // OverflowError: negative or beyond 64 bits
      throw py::value_error(std::string(name) + " must be in [0, 2^64)");
    }
    return static_cast<std::uint64_t>(x);
  }
};

/// A real number (int, float, numpy scalars; not a bool, not complex). Signature: `float`.
struct RealArg {
  py::object value;
  double get(const char* name) const {
    if (py::isinstance<py::bool_>(value) || !PyNumber_Check(value.ptr()) || PyComplex_Check(value.ptr()))
      throw py::type_error(std::string(name) + " must be a real number");
    const double x = PyFloat_AsDouble(value.ptr());
    if (x == -1.0 && PyErr_Occurred()) {
      PyErr_Clear();  // an array of several numbers, or a number type without __float__
      throw py::type_error(std::string(name) + " must be a real number");
    }
    return x;
  }
};

/// A bool (True or False only: 0 / 1 are not taken for flags). Signature: `bool`.
struct BoolArg {
  py::object value;
  bool get(const char* name) const {
    if (!py::isinstance<py::bool_>(value)) throw py::type_error(std::string(name) + " must be a bool");
    return value.cast<bool>();
  }
};

/// A str. Signature: `str`.
struct StrArg {
  py::object value;
  std::string get(const char* name) const {
    if (!py::isinstance<py::str>(value)) throw py::type_error(std::string(name) + " must be a str");
    return value.cast<std::string>();
  }
};

/// The Python name of an object's type, for error messages ("int", "NoneType", "ndarray").
inline std::string type_name_of(py::handle obj) { return py::str(py::type::of(obj).attr("__name__")); }

/// "a Pose2", "an OccupancyGrid2D": a class name with its indefinite article.
inline std::string with_article(const std::string& name) {
  const bool vowel = std::string("AEIOU").find(name[0]) != std::string::npos;
  return (vowel ? "an " : "a ") + name;
}

/// An argument of a bound class T: `.get(name)` is the T, TypeError "<name>: expected a T, got
/// <type>" otherwise (pybind11's own T& caster answers a wrong type with its list of signatures).
/// Signature: T's Python name.
template <class T>
struct ClassArg {
  py::object value;
  T& get(const std::string& name) const {
    if (!py::isinstance<T>(value)) {
      throw py::type_error(name + ": expected " + with_article(py::str(py::type::of<T>().attr("__name__"))) + ", got " +
                           type_name_of(value));
    }
    return value.cast<T&>();
  }
};

/// The `particle` argument of a particle filter's per-particle calls (FastSlam, GridFastSlam):
/// None is the best particle, resolved under the filter's lock; anything else an index in
/// [0, num_particles), its type and sign checked with the GIL held.
struct ParticleChoice {
  long long index = -1;  // -1: the best
  static ParticleChoice from(py::handle k) {
    if (k.is_none()) return {};
    const long long i = index_value(k, "particle");
    if (i < 0) throw py::value_error("particle must be in [0, num_particles)");
    return {i};
  }
  template <typename Filter>
  int resolve(const Filter& f) const {
    if (index < 0) return f.best_index();
    require(index < f.num_particles(), "particle", "must be in [0, num_particles)");
    return static_cast<int>(index);
  }
};

/// A keyword with a float default: py::arg_v whose signature shows `math.inf` for an infinite
/// default (repr's `inf` is not a Python expression; the stub imports math).
inline py::arg_v real_arg(const char* name, double v) {
  const char* shown = std::isinf(v) ? (v > 0 ? "math.inf" : "-math.inf") : nullptr;
  return py::arg_v(name, v, shown);
}

}  // namespace probslam::bindings

namespace pybind11::detail {
// The casters of the checked argument types: take any object as it is (checked in the body),
// give it back as it is, and name the expected Python type in signatures. Other headers declare
// theirs with the same macro (graph_options.hpp's GraphArg).
#define PROBSLAM_CHECKED_ARG(Type, py_name)                                                           \
  template <>                                                                                         \
  struct type_caster<Type> {                                                                          \
    PYBIND11_TYPE_CASTER(Type, const_name(py_name));                                                  \
    bool load(handle src, bool) {                                                                     \
      value.value = reinterpret_borrow<object>(src);                                                  \
      return true;                                                                                    \
    }                                                                                                 \
    static handle cast(const Type& v, return_value_policy, handle) { return v.value.inc_ref(); }     \
  };
PROBSLAM_CHECKED_ARG(probslam::bindings::IntArg, "int")
PROBSLAM_CHECKED_ARG(probslam::bindings::UInt64Arg, "int")
PROBSLAM_CHECKED_ARG(probslam::bindings::RealArg, "float")
PROBSLAM_CHECKED_ARG(probslam::bindings::BoolArg, "bool")
PROBSLAM_CHECKED_ARG(probslam::bindings::StrArg, "str")

template <class T>
struct type_caster<probslam::bindings::ClassArg<T>> {
  PYBIND11_TYPE_CASTER(probslam::bindings::ClassArg<T>, make_caster<T>::name);
  bool load(handle src, bool) {
    value.value = reinterpret_borrow<object>(src);
    return true;
  }
  static handle cast(const probslam::bindings::ClassArg<T>& v, return_value_policy, handle) {
    return v.value.inc_ref();
  }
};
}  // namespace pybind11::detail
