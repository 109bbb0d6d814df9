#pragma once
// The graph optimisers' options from Python strings, shared by the 2-D and 3-D graph bindings.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "args.hpp"
#include "interrupt.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "probslam/graph/graph_initialization.hpp"  // IncrementalOptions
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

/// Vertex ids from Python (a sequence or 1-D array of integers): integers only (a float id would
/// be truncated) and within int (a larger one would wrap onto another vertex); TypeError /
/// ValueError naming the argument otherwise.
inline std::vector<int> vertex_ids_arg(py::handle obj, const std::string& name) {
  const LongArray ids = integer_array_arg(obj, name.c_str());
  if (ids.ndim() != 1) throw py::value_error(name + " must be a 1-D array of integers");
  return int_entries(ids, name.c_str(), "vertex id");
}

/// Groups of vertex ids (a sequence of sequences of integers), each checked as vertex_ids_arg
/// and named by its position ("groups[2]").
inline std::vector<std::vector<int>> vertex_id_groups_arg(py::handle obj, const std::string& name) {
  if (py::isinstance<py::str>(obj) || py::isinstance<py::bytes>(obj) || !PySequence_Check(obj.ptr()))
    throw py::type_error(name + " must be a sequence of sequences of vertex ids");
  const py::sequence seq = py::reinterpret_borrow<py::sequence>(obj);
  std::vector<std::vector<int>> groups;
  for (std::size_t k = 0; k < seq.size(); ++k)
    groups.push_back(vertex_ids_arg(seq[k], name + "[" + std::to_string(k) + "]"));
  return groups;
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

/// The docstrings of one graph type's optimize / marginal_covariances / joint_marginal_covariances.
struct OptimizerDocs {
  const char* optimize;
  const char* marginals;
  const char* joint_marginals;
  const char* optimize_incremental;
};

/// optimize, optimize_incremental, marginal_covariances and joint_marginal_covariances for one graph type: the same
/// arguments for PoseGraph2D and PoseGraph3D, each with its own default linear solver and
/// ordering (graph3d.cpp says why 3-D's differ).
template <class Graph>
void def_optimizer(py::module_& m, const char* linear_solver, const char* ordering, const OptimizerDocs& doc) {
  auto list_of = [](const std::vector<Eigen::MatrixXd>& blocks) {
    py::list out;
    for (const auto& b : blocks) out.append(py::cast(b));
    return out;
  };
  m.def("optimize",
        [](Graph& graph, StrArg algorithm, IntArg max_iterations_arg, RealArg relative_tolerance,
           RealArg step_tolerance, StrArg kernel, RealArg kernel_width, StrArg linear_solver, StrArg ordering,
           StrArg damping, const py::object& callback) {
          const int max_iterations = max_iterations_arg.get("max_iterations");
          const OptimizerOptions o = optimizer_options(
              algorithm.get("algorithm"), max_iterations, relative_tolerance.get("relative_tolerance"),
              step_tolerance.get("step_tolerance"), kernel.get("kernel"), kernel_width.get("kernel_width"),
              linear_solver.get("linear_solver"), ordering.get("ordering"), damping.get("damping"));
          const IterationCallback on_iteration = iteration_callback(callback);
          return locked(graph, [&] { return optimize(graph, o, on_iteration); });
        },
        py::arg("graph"), py::arg("algorithm") = "gauss-newton", py::arg("max_iterations") = 100,
        py::arg("relative_tolerance") = 1e-10, py::arg("step_tolerance") = 1e-10, py::arg("kernel") = "none",
        py::arg("kernel_width") = 1.0, py::arg("linear_solver") = linear_solver, py::arg("ordering") = ordering,
        py::arg("damping") = "marquardt", py::arg("callback") = py::none(), doc.optimize);
  m.def("optimize_incremental",
        [](Graph& graph, IntArg poses_per_step_arg, StrArg algorithm, IntArg max_iterations_arg,
           RealArg relative_tolerance, RealArg step_tolerance, StrArg kernel, RealArg kernel_width,
           StrArg linear_solver, StrArg ordering, StrArg damping) {
          IncrementalOptions o;
          o.poses_per_step = poses_per_step_arg.get("poses_per_step");
          o.step = optimizer_options(
              algorithm.get("algorithm"), max_iterations_arg.get("max_iterations"),
              relative_tolerance.get("relative_tolerance"), step_tolerance.get("step_tolerance"), kernel.get("kernel"),
              kernel_width.get("kernel_width"), linear_solver.get("linear_solver"), ordering.get("ordering"),
              damping.get("damping"));
          o.interrupt = python_interrupt();  // Ctrl-C between steps and iterations
          return locked(graph, [&] { return optimize_incremental(graph, o); });
        },
        py::arg("graph"), py::arg("poses_per_step") = 100, py::arg("algorithm") = "gauss-newton",
        py::arg("max_iterations") = 10, py::arg("relative_tolerance") = 1e-6, py::arg("step_tolerance") = 1e-10,
        py::arg("kernel") = "none", py::arg("kernel_width") = 1.0, py::arg("linear_solver") = linear_solver,
        py::arg("ordering") = ordering, py::arg("damping") = "marquardt", doc.optimize_incremental);
  m.def("marginal_covariances",
        [list_of](const Graph& graph, py::handle ids_arg, StrArg linear_solver, StrArg ordering) {
          const std::vector<int> ids = vertex_ids_arg(ids_arg, "ids");
          const SparseCholeskyOptions o = solver_options(linear_solver.get("linear_solver"), ordering.get("ordering"));
          return list_of(locked(graph, [&] { return marginal_covariances(graph, ids, o); }));
        },
        py::arg("graph"), py::arg("ids"), py::arg("linear_solver") = linear_solver, py::arg("ordering") = ordering,
        doc.marginals);
  m.def("joint_marginal_covariances",
        [list_of](const Graph& graph, py::handle groups_arg, StrArg linear_solver, StrArg ordering) {
          const std::vector<std::vector<int>> groups = vertex_id_groups_arg(groups_arg, "groups");
          const SparseCholeskyOptions o = solver_options(linear_solver.get("linear_solver"), ordering.get("ordering"));
          return list_of(locked(graph, [&] { return joint_marginal_covariances(graph, groups, o); }));
        },
        py::arg("graph"), py::arg("groups"), py::arg("linear_solver") = linear_solver, py::arg("ordering") = ordering,
        doc.joint_marginals);
}

}  // namespace probslam::bindings
