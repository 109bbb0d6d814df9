#pragma once
// Conversions from Python objects to Eigen views, with errors that name the argument.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <limits>
#include <string>
#include <vector>

namespace probslam::bindings {

namespace py = pybind11;
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using ConstVectorMap = Eigen::Map<const Eigen::VectorXd>;
using ConstRowMatrixMap =
    Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;

/// True when obj is, or converts to, a numpy array of complex numbers: forcecast would keep only
/// the real part (numpy's ComplexWarning), silently wrong input.
inline bool is_complex(py::handle obj) {
  if (py::isinstance<py::array>(obj)) return py::reinterpret_borrow<py::array>(obj).dtype().kind() == 'c';
  if (PyComplex_Check(obj.ptr())) return true;
  if (!py::isinstance<py::sequence>(obj) || py::isinstance<py::str>(obj) || py::isinstance<py::bytes>(obj)) return false;
  const py::array converted = py::array::ensure(obj);  // clears numpy's error when it fails
  return converted && converted.dtype().kind() == 'c';
}

/// A C-contiguous float64 view of obj (copied only if it is not one already). Complex values
/// are a TypeError, not their real part.
inline DoubleArray as_array(py::handle obj, const char* name) {
  if (obj.is_none()) throw py::type_error(std::string(name) + " must be an array of numbers, not None");
  if (is_complex(obj)) throw py::type_error(std::string(name) + " must hold real numbers, got complex values");
  DoubleArray array = DoubleArray::ensure(obj);
  if (!array) throw py::type_error(std::string(name) + " must be an array of numbers");
  return array;
}

inline std::string shape_of(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

/// A 1-D array of `size` entries (any size if size < 0).
inline DoubleArray vector_arg(py::handle obj, const char* name, py::ssize_t size = -1) {
  DoubleArray a = as_array(obj, name);
  if (a.ndim() != 1 || (size >= 0 && a.shape(0) != size))
    throw py::value_error(std::string(name) + " must have shape (" + (size >= 0 ? std::to_string(size) : "n") +
                          ",), got " + shape_of(a));
  return a;
}

/// A 2-D array with `cols` columns (any number if cols < 0).
inline DoubleArray matrix_arg(py::handle obj, const char* name, py::ssize_t cols = -1) {
  DoubleArray a = as_array(obj, name);
  if (a.ndim() != 2 || (cols >= 0 && a.shape(1) != cols))
    throw py::value_error(std::string(name) + " must have shape (n, " + (cols >= 0 ? std::to_string(cols) : "m") +
                          "), got " + shape_of(a));
  return a;
}

inline ConstVectorMap as_vector(const DoubleArray& a) { return {a.data(), a.size()}; }
inline ConstRowMatrixMap as_matrix(const DoubleArray& a) { return {a.data(), a.shape(0), a.shape(1)}; }

template <int N>
Eigen::Matrix<double, N, 1> fixed_vector(py::handle obj, const char* name) {
  return as_vector(vector_arg(obj, name, N));
}

/// A square matrix, of size x size when size >= 0.
inline Eigen::MatrixXd square_matrix_arg(py::handle obj, const char* name, py::ssize_t size = -1) {
  DoubleArray a = as_array(obj, name);
  if (a.ndim() != 2 || a.shape(0) != a.shape(1))
    throw py::value_error(std::string(name) + " must be a square matrix, got shape " + shape_of(a));
  if (size >= 0 && a.shape(0) != size)
    throw py::value_error(std::string(name) + " must have shape (" + std::to_string(size) + ", " +
                          std::to_string(size) + "), got " + shape_of(a));
  return as_matrix(a);
}

using LongArray = py::array_t<long, py::array::c_style | py::array::forcecast>;

/// An integer array (ids, indices); a TypeError names the argument otherwise. Float arrays are
/// refused rather than cast: a cast would truncate 1.7 to 1 and pick another id silently.
inline LongArray integer_array_arg(py::handle obj, const char* name) {
  py::array raw = obj.is_none() ? py::array() : py::array::ensure(obj);
  const bool integral = raw && (raw.size() == 0 || raw.dtype().kind() == 'i' || raw.dtype().kind() == 'u');
  if (!integral) throw py::type_error(std::string(name) + " must be an array of integers");
  if (raw.dtype().kind() == 'u' && raw.dtype().itemsize() >= static_cast<py::ssize_t>(sizeof(long))) {
    // An unsigned value beyond long's range would wrap to a negative id.
    const py::array_t<unsigned long long, py::array::forcecast> u(raw);
    for (py::ssize_t i = 0; i < u.size(); ++i)
      if (u.data()[i] > static_cast<unsigned long long>(std::numeric_limits<long>::max()))
        throw py::value_error(std::string(name) + ": value " + std::to_string(u.data()[i]) + " is out of range");
  }
  LongArray a = LongArray::ensure(raw);
  if (!a) throw py::type_error(std::string(name) + " must be an array of integers");
  return a;
}

/// The entries of an integer array as ints; an entry beyond int would wrap onto another id or
/// index, so it is refused ("NAME: NOUN N is out of range"), never truncated.
inline std::vector<int> int_entries(const LongArray& a, const char* name, const char* noun) {
  std::vector<int> out(static_cast<std::size_t>(a.size()));
  for (py::ssize_t k = 0; k < a.size(); ++k) {
    const long v = a.data()[k];
    if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max())
      throw py::value_error(std::string(name) + ": " + noun + " " + std::to_string(v) + " is out of range");
    out[static_cast<std::size_t>(k)] = static_cast<int>(v);
  }
  return out;
}

inline Eigen::Vector3d pose_arg(py::handle obj, const char* name = "pose") { return fixed_vector<3>(obj, name); }

}  // namespace probslam::bindings
