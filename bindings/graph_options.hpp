#pragma once
// The graph optimisers' options from Python strings, shared by the 2-D and 3-D graph bindings.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <initializer_list>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "args.hpp"
#include "interrupt.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "probslam/graph/graph_initialization.hpp"  // IncrementalOptions
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_3d_initialization.hpp"  // initialize_odometry (3-D)

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

/// The graph optimisers' default linear solver, and each graph type's default fill ordering:
/// nested dissection orders sphere2500 and torus3D with less fill than AMD (torus3D: 1.0e9 flops
/// against 1.35e9 a factorisation; parking-garage a little more, 3e7 against 2.2e7); 2-D graphs
/// keep AMD, faster on every one measured (docs/pose_graphs.md).
constexpr const char* kGraphLinearSolver = "supernodal";
template <class Graph>
struct DefaultOrdering;
template <>
struct DefaultOrdering<PoseGraph2D> {
  static constexpr const char* value = "amd";
};
template <>
struct DefaultOrdering<PoseGraph3D> {
  static constexpr const char* value = "metis";
};

/// A pose-graph argument (PoseGraph2D or PoseGraph3D), taken as any object and checked in the
/// body by with_graph: a wrong type is a TypeError naming the argument, where a typed overload per
/// graph class would answer with pybind11's list of signatures. Signature: `PoseGraph2D | PoseGraph3D`.
struct GraphArg {
  py::object value;
};
/// A fill ordering or None for the graph type's default (ordering_for). Signature: `str | None`.
struct OrderingArg {
  py::object value;
};

}  // namespace probslam::bindings

namespace pybind11::detail {
// GraphArg and OrderingArg: any object, checked by with_graph / ordering_for.
PROBSLAM_CHECKED_ARG(probslam::bindings::GraphArg, "PoseGraph2D | PoseGraph3D")
PROBSLAM_CHECKED_ARG(probslam::bindings::OrderingArg, "str | None")
}  // namespace pybind11::detail

namespace probslam::bindings {

/// f(graph) with the argument as the graph class it is: TypeError "<name>: expected a PoseGraph2D
/// or PoseGraph3D, got <type>" otherwise.
template <class F>
decltype(auto) with_graph(const GraphArg& graph, const char* name, F&& f) {
  if (py::isinstance<PoseGraph2D>(graph.value)) return f(graph.value.cast<PoseGraph2D&>());
  if (py::isinstance<PoseGraph3D>(graph.value)) return f(graph.value.cast<PoseGraph3D&>());
  throw py::type_error(std::string(name) + ": expected a PoseGraph2D or PoseGraph3D, got " + type_name_of(graph.value));
}

/// The solver options of a call on `graph`: ordering None is the graph type's default.
template <class Graph>
std::string ordering_for(const OrderingArg& ordering) {
  if (ordering.value.is_none()) return DefaultOrdering<Graph>::value;
  return StrArg{ordering.value}.get("ordering");
}

/// The docstrings of optimize, marginal_covariances, joint_marginal_covariances and
/// optimize_incremental: one function each for both graph types.
struct OptimizerDocs {
  const char* optimize;
  const char* marginals;
  const char* joint_marginals;
  const char* optimize_incremental;
  const char* initialize_odometry;
};

/// optimize, optimize_incremental, marginal_covariances, joint_marginal_covariances and
/// initialize_odometry: one binding each taking a PoseGraph2D or a PoseGraph3D (the same arguments
/// for both; ordering None is the graph type's default, DefaultOrdering).
inline void def_optimizers(py::module_& m, const OptimizerDocs& doc) {
  auto list_of = [](const std::vector<Eigen::MatrixXd>& blocks) {
    py::list out;
    for (const auto& b : blocks) out.append(py::cast(b));
    return out;
  };
  m.def("optimize",
        [](const GraphArg& graph_arg, StrArg algorithm, IntArg max_iterations_arg, RealArg relative_tolerance,
           RealArg step_tolerance, StrArg kernel, RealArg kernel_width, StrArg linear_solver,
           const OrderingArg& ordering, StrArg damping, const py::object& callback) {
          return with_graph(graph_arg, "graph", [&](auto& graph) {
            using Graph = std::decay_t<decltype(graph)>;
            const OptimizerOptions o = optimizer_options(
                algorithm.get("algorithm"), max_iterations_arg.get("max_iterations"),
                relative_tolerance.get("relative_tolerance"), step_tolerance.get("step_tolerance"),
                kernel.get("kernel"), kernel_width.get("kernel_width"), linear_solver.get("linear_solver"),
                ordering_for<Graph>(ordering), damping.get("damping"));
            const IterationCallback on_iteration = iteration_callback(callback);
            return locked(graph, [&] { return optimize(graph, o, on_iteration); });
          });
        },
        py::arg("graph"), py::arg("algorithm") = "gauss-newton", py::arg("max_iterations") = 100,
        py::arg("relative_tolerance") = 1e-10, py::arg("step_tolerance") = 1e-10, py::arg("kernel") = "none",
        py::arg("kernel_width") = 1.0, py::arg("linear_solver") = kGraphLinearSolver,
        py::arg("ordering") = py::none(), py::arg("damping") = "marquardt", py::arg("callback") = py::none(),
        doc.optimize);
  m.def("optimize_incremental",
        [](const GraphArg& graph_arg, IntArg poses_per_step_arg, StrArg algorithm, IntArg max_iterations_arg,
           RealArg relative_tolerance, RealArg step_tolerance, StrArg kernel, RealArg kernel_width,
           StrArg linear_solver, const OrderingArg& ordering, StrArg damping) {
          return with_graph(graph_arg, "graph", [&](auto& graph) {
            using Graph = std::decay_t<decltype(graph)>;
            IncrementalOptions o;
            o.poses_per_step = poses_per_step_arg.get("poses_per_step");
            o.step = optimizer_options(
                algorithm.get("algorithm"), max_iterations_arg.get("max_iterations"),
                relative_tolerance.get("relative_tolerance"), step_tolerance.get("step_tolerance"),
                kernel.get("kernel"), kernel_width.get("kernel_width"), linear_solver.get("linear_solver"),
                ordering_for<Graph>(ordering), damping.get("damping"));
            o.interrupt = python_interrupt();  // Ctrl-C between steps and iterations
            return locked(graph, [&] { return optimize_incremental(graph, o); });
          });
        },
        py::arg("graph"), py::arg("poses_per_step") = 100, py::arg("algorithm") = "gauss-newton",
        py::arg("max_iterations") = 10, py::arg("relative_tolerance") = 1e-6, py::arg("step_tolerance") = 1e-10,
        py::arg("kernel") = "none", py::arg("kernel_width") = 1.0, py::arg("linear_solver") = kGraphLinearSolver,
        py::arg("ordering") = py::none(), py::arg("damping") = "marquardt", doc.optimize_incremental);
  m.def("marginal_covariances",
        [list_of](const GraphArg& graph_arg, py::handle ids_arg, StrArg linear_solver, const OrderingArg& ordering) {
          return with_graph(graph_arg, "graph", [&](const auto& graph) {
            using Graph = std::decay_t<decltype(graph)>;
            const std::vector<int> ids = vertex_ids_arg(ids_arg, "ids");
            const SparseCholeskyOptions o = solver_options(linear_solver.get("linear_solver"), ordering_for<Graph>(ordering));
            return list_of(locked(graph, [&] { return marginal_covariances(graph, ids, o); }));
          });
        },
        py::arg("graph"), py::arg("ids"), py::arg("linear_solver") = kGraphLinearSolver,
        py::arg("ordering") = py::none(), doc.marginals);
  m.def("joint_marginal_covariances",
        [list_of](const GraphArg& graph_arg, py::handle groups_arg, StrArg linear_solver, const OrderingArg& ordering) {
          return with_graph(graph_arg, "graph", [&](const auto& graph) {
            using Graph = std::decay_t<decltype(graph)>;
            const std::vector<std::vector<int>> groups = vertex_id_groups_arg(groups_arg, "groups");
            const SparseCholeskyOptions o = solver_options(linear_solver.get("linear_solver"), ordering_for<Graph>(ordering));
            return list_of(locked(graph, [&] { return joint_marginal_covariances(graph, groups, o); }));
          });
        },
        py::arg("graph"), py::arg("groups"), py::arg("linear_solver") = kGraphLinearSolver,
        py::arg("ordering") = py::none(), doc.joint_marginals);
  m.def("initialize_odometry",
        [](const GraphArg& graph_arg) {
          with_graph(graph_arg, "graph", [](auto& graph) { locked(graph, [&] { initialize_odometry(graph); }); });
        },
        py::arg("graph"), doc.initialize_odometry);
}

}  // namespace probslam::bindings

