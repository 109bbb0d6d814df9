#pragma once
// Per-object serialisation for the bindings (the reliability policy's thread rule).
//
// Every method of a stateful class (EkfSlam, MultiHypothesisEkfSlam, OccupancyGrid2D/3D,
// PoseGraph2D) runs its C++ work inside `locked(obj, f)`: the GIL is released first and the
// object's mutex taken second, so a thread waiting for the object never holds the GIL, and the
// thread that holds the object can always get the GIL back afterwards: no deadlock. f must not
// touch Python objects; convert arguments before and results after.
//
// Re-entry: work under the lock may call back into Python on the same thread (optimize's
// callback, a signal handler run by an interrupt check), and that Python code may use the same
// object (a progress plot reading g.poses). Taking the mutex again would deadlock; instead the
// thread remembers which objects it holds, a read (a const object) runs at once, and a change
// (a non-const object) raises RuntimeError: it would pull the state from under the work.
#include <pybind11/pybind11.h>

#include <algorithm>
#include <mutex>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "numpy.hpp"

namespace probslam::bindings {

namespace detail {

// The objects whose mutex this thread holds through locked() (rarely more than one).
inline std::vector<const void*>& held_by_this_thread() {
  thread_local std::vector<const void*> held;
  return held;
}

inline bool held_here(const void* object) {
  const std::vector<const void*>& held = held_by_this_thread();
  return std::find(held.begin(), held.end(), object) != held.end();
}

// Marks an object as held by this thread while the mutex is held.
class HeldMark {
 public:
  explicit HeldMark(const void* object) : object_(object) { held_by_this_thread().push_back(object); }
  ~HeldMark() {
    std::vector<const void*>& held = held_by_this_thread();
    held.erase(std::find(held.begin(), held.end(), object_));
  }
  HeldMark(const HeldMark&) = delete;
  HeldMark& operator=(const HeldMark&) = delete;

 private:
  const void* object_;
};

// A re-entrant call on an object this thread already holds: reads run, changes are refused.
template <typename T>
void check_reentry() {
  if constexpr (!std::is_const_v<T>)
    throw std::logic_error(
        "the object is in use by a call running on this thread (e.g. optimize, whose callback is "
        "running): it can be read but not changed until that call returns");
}

}  // namespace detail

template <typename T, typename F>
decltype(auto) locked(T& object, F&& f) {
  if (detail::held_here(&object)) {
    detail::check_reentry<T>();
    return f();
  }
  pybind11::gil_scoped_release release;
  std::lock_guard<std::mutex> lock(object.mutex());
  const detail::HeldMark mark(&object);
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
decltype(auto) locked(A& a, B& b, F&& f) {
  if (static_cast<const void*>(&a) == static_cast<const void*>(&b)) return locked(a, std::forward<F>(f));
  if (detail::held_here(&a)) {
    detail::check_reentry<A>();
    return locked(b, std::forward<F>(f));
  }
  if (detail::held_here(&b)) {
    detail::check_reentry<B>();
    return locked(a, std::forward<F>(f));
  }
  pybind11::gil_scoped_release release;
  std::scoped_lock lock(a.mutex(), b.mutex());
  const detail::HeldMark mark_a(&a), mark_b(&b);
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

/// The (K, 3) deltas and (K, 3, 3) noises of predict_odometry_batch, as (K, 3) and (K, 9) views.
struct OdometryBatch {
  DoubleArray deltas, noises;
  ConstRowMatrixMap d() const { return {deltas.data(), deltas.shape(0), 3}; }
  ConstRowMatrixMap n() const { return {noises.data(), noises.shape(0), 9}; }
};

inline OdometryBatch odometry_batch_args(py::handle deltas, py::handle noises) {
  OdometryBatch b{matrix_arg(deltas, "deltas", 3), as_array(noises, "noises")};
  if (b.noises.ndim() != 3 || b.noises.shape(0) != b.deltas.shape(0) || b.noises.shape(1) != 3 || b.noises.shape(2) != 3)
    throw py::value_error("noises must have shape (" + std::to_string(b.deltas.shape(0)) + ", 3, 3), one per row of "
                          "deltas, got " + shape_of(b.noises));
  return b;
}

}  // namespace probslam::bindings
