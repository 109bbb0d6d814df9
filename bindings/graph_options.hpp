#pragma once
// The graph optimisers' options from Python strings, shared by the 2-D and 3-D graph bindings.
#include <pybind11/pybind11.h>

#include <initializer_list>
#include <string>
#include <utility>

#include "probslam/graph/graph_optimizer.hpp"

namespace probslam::bindings {

namespace py = pybind11;

template <typename Enum>
Enum choice(const std::string& value, const char* name,
            std::initializer_list<std::pair<const char*, Enum>> options) {
  std::string allowed;
  for (const auto& [key, e] : options) {
    if (value == key) return e;
    allowed += std::string(allowed.empty() ? "" : ", ") + "'" + key + "'";
  }
  throw py::value_error(std::string(name) + " must be one of " + allowed + ", got '" + value + "'");
}

inline SparseCholeskyOptions solver_options(const std::string& method, const std::string& ordering) {
  SparseCholeskyOptions o;
  o.method = choice<FactorMethod>(method, "linear_solver",
                                  {{"simplicial", FactorMethod::kSimplicial},
                                   {"supernodal", FactorMethod::kSupernodal},
                                   {"auto", FactorMethod::kAuto}});
  o.ordering = choice<FillOrdering>(ordering, "ordering",
                                    {{"amd", FillOrdering::kAmd}, {"metis", FillOrdering::kMetis}});
  return o;
}

inline OptimizerOptions optimizer_options(const std::string& algorithm, int max_iterations, double relative_tolerance,
                                   double step_tolerance, const std::string& kernel, double kernel_width,
                                   const std::string& linear_solver, const std::string& ordering,
                                   const std::string& damping) {
  OptimizerOptions o;
  o.damping = choice<Damping>(damping, "damping", {{"marquardt", Damping::kMarquardt}, {"levenberg", Damping::kLevenberg}});
  o.algorithm = choice<OptimizerAlgorithm>(algorithm, "algorithm",
                                           {{"gauss-newton", OptimizerAlgorithm::kGaussNewton},
                                            {"levenberg-marquardt", OptimizerAlgorithm::kLevenbergMarquardt}});
  o.kernel = choice<RobustKernel>(kernel, "kernel",
                                  {{"none", RobustKernel::kNone},
                                   {"huber", RobustKernel::kHuber},
                                   {"cauchy", RobustKernel::kCauchy}});
  o.max_iterations = max_iterations;
  o.relative_tolerance = relative_tolerance;
  o.step_tolerance = step_tolerance;
  o.kernel_width = kernel_width;
  o.linear_solver = solver_options(linear_solver, ordering);
  return o;
}

/// The optimiser's IterationCallback calling a Python callable (or none for None); the callable
/// must outlive the optimisation.
inline IterationCallback iteration_callback(const py::object& callback) {
  if (!callback.is_none() && !PyCallable_Check(callback.ptr()))
    throw py::type_error("callback must be a callable (iteration, chi2) -> bool or None, got " +
                         std::string(py::str(py::type::of(callback).attr("__name__"))));
  IterationCallback on_iteration;
  if (!callback.is_none()) {
    // The optimiser runs with the GIL released; the callback takes it only for its call.
    // Signals are checked there too, so Ctrl-C stops even a callback that never returns False.
    on_iteration = [&callback](int iteration, double chi2) {
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      const py::object go_on = callback(iteration, chi2);
      if (go_on.is_none()) return true;
      const int truth = PyObject_IsTrue(go_on.ptr());
      if (truth < 0) throw py::error_already_set();
      return truth == 1;
    };
  }
  return on_iteration;
}

}  // namespace probslam::bindings
