#pragma once
// Per-object serialisation for the bindings (the reliability policy's thread rule).
//
// Every method of a stateful class (EkfSlam, MultiHypothesisEkfSlam, OccupancyGrid2D/3D,
// PoseGraph2D) runs its C++ work inside `locked(obj, f)`: the GIL is released first and the
// object's mutex taken second, so a thread waiting for the object never holds the GIL, and the
// thread that holds the object can always get the GIL back afterwards: no deadlock. f must not
// touch Python objects; convert arguments before and results after.
#include <pybind11/pybind11.h>

#include <mutex>

#include "numpy.hpp"

namespace probslam::bindings {

template <typename T, typename F>
decltype(auto) locked(const T& object, F&& f) {
  pybind11::gil_scoped_release release;
  std::lock_guard<std::mutex> lock(object.mutex());
  return f();
}

/// A property getter (or a method without arguments) that runs `method` under the lock; the
/// result is copied out before the lock is released.
template <typename T, typename R>
auto getter(R (T::*method)() const) {
  return [method](const T& obj) { return locked(obj, [&] { return (obj.*method)(); }); };
}

/// Two objects at once (e.g. a source and a destination), in a deadlock-free order.
template <typename A, typename B, typename F>
decltype(auto) locked(const A& a, const B& b, F&& f) {
  pybind11::gil_scoped_release release;
  if (static_cast<const void*>(&a) == static_cast<const void*>(&b)) {
    std::lock_guard<std::mutex> lock(a.mutex());
    return f();
  }
  std::scoped_lock lock(a.mutex(), b.mutex());
  return f();
}

/// predict_odometry(delta, noise) of a landmark filter (EkfSlam, FastSlam): the arguments
/// converted with the GIL held, the call under the filter's lock.
template <typename Filter>
void predict_odometry_locked(Filter& f, py::handle delta, py::handle noise) {
  const Eigen::Vector3d d = fixed_vector<3>(delta, "delta");
  const Eigen::Matrix3d n = square_matrix_arg(noise, "noise", 3);
  locked(f, [&] { f.predict_odometry(d, n); });
}

}  // namespace probslam::bindings
