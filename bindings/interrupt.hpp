#pragma once
// Ctrl-C for long C++ work that runs with the GIL released: the library calls an interrupt
// hook every so often (it knows nothing of Python); this one takes the GIL back for a moment,
// lets Python run its signal handlers, and throws KeyboardInterrupt (or whatever a handler
// raised) out of the C++ call, which then leaves its result unbuilt.
#include <pybind11/pybind11.h>

#include <functional>

namespace probslam::bindings {

inline std::function<void()> python_interrupt() {
  return [] {
    pybind11::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) throw pybind11::error_already_set();
  };
}

}  // namespace probslam::bindings
