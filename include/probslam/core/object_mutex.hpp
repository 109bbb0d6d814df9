#pragma once
// A mutex that a stateful class can hold as a member and stay copyable and movable.
//
// probslam's classes do not lock themselves: a C++ caller that shares one object between threads
// locks `obj.mutex()` around every call. The Python bindings do exactly that for every method, so
// concurrent calls on one object from Python threads are serialised, while calls on different
// objects still run in parallel.
#include <mutex>

namespace probslam {

class ObjectMutex {
 public:
  ObjectMutex() = default;
  // A copy is a new object: it gets a fresh, unlocked mutex (a std::mutex cannot be copied).
  ObjectMutex(const ObjectMutex&) noexcept {}
  ObjectMutex& operator=(const ObjectMutex&) noexcept { return *this; }

  std::mutex& get() const noexcept { return mutex_; }

 private:
  mutable std::mutex mutex_;
};

}  // namespace probslam
