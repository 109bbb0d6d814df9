#pragma once
// The graph optimisers' bindings, one function each for the 2-D and 3-D graphs, their options the
// typed classes of the C++ structs (options_class.hpp), and the graph arguments' checks.
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
#include "options_class.hpp"
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

/// A pose-graph argument (PoseGraph2D or PoseGraph3D), taken as any object and checked in the
/// body by with_graph: a wrong type is a TypeError naming the argument, where a typed overload per
/// graph class would answer with pybind11's list of signatures. Signature: `PoseGraph2D | PoseGraph3D`.
struct GraphArg {
  py::object value;
};

}  // namespace probslam::bindings

namespace pybind11::detail {
// GraphArg: any object, checked by with_graph.
PROBSLAM_CHECKED_ARG(probslam::bindings::GraphArg, "PoseGraph2D | PoseGraph3D")
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

/// The docstrings of optimize, marginal_covariances, joint_marginal_covariances and
/// optimize_incremental: one function each for both graph types.
struct OptimizerDocs {
  const char* optimize;
  const char* marginals;
  const char* joint_marginals;
  const char* optimize_incremental;
  const char* initialize_odometry;
};

/// "name(graph: ..., <before>*, options: Optional[T] = None<after>, <T's fields>) -> <returns>\n\n<doc>":
/// a function's signature line written from T's describe() (pybind11 would show **kwargs).
template <class T>
std::string options_signature(const char* name, const char* graph, const char* before, const char* after,
                              const char* returns, const char* doc) {
  return options_signature_line<T>(std::string(name) + "(graph: " + graph + ", " + before + "*, ", after, returns, doc);
}

/// optimize, optimize_incremental, marginal_covariances, joint_marginal_covariances and
/// initialize_odometry: one binding each taking a PoseGraph2D or a PoseGraph3D (the same arguments
/// for both). The options travel as their typed class (OptimizerOptions, IncrementalOptions,
/// SparseCholeskyOptions; None: the defaults), a field given by keyword replacing options' field;
/// the defaults are the C++ structs' (the fill ordering "default" resolved by graph type there).
inline void def_optimizers(py::module_& m, const OptimizerDocs& doc) {
  auto list_of = [](const std::vector<Eigen::MatrixXd>& blocks) {
    py::list out;
    for (const auto& b : blocks) out.append(py::cast(b));
    return out;
  };
  constexpr const char* kEither = "Union[PoseGraph2D, PoseGraph3D]";
  py::options signatures;  // the fields' keywords are written from describe(), not **kwargs
  signatures.disable_function_signatures();
  m.def("optimize",
        [](const GraphArg& graph_arg, py::handle options, const py::object& callback, const py::kwargs& fields) {
          const auto o = options_arg<OptimizerOptions>(options, fields, "optimize()");
          return with_graph(graph_arg, "graph", [&](auto& graph) {
            const IterationCallback on_iteration = iteration_callback(callback);
            return locked(graph, [&] { return optimize(graph, o, on_iteration); });
          });
        },
        py::arg("graph"), py::kw_only(), py::arg("options") = py::none(), py::arg("callback") = py::none(),
        options_signature<OptimizerOptions>("optimize", kEither, "",
                                            ", callback: Optional[Callable[[int, float], Optional[bool]]] = None",
                                            "OptimizationReport", doc.optimize)
            .c_str());
  m.def("optimize_incremental",
        [](const GraphArg& graph_arg, py::handle options, const py::kwargs& fields) {
          auto o = options_arg<IncrementalOptions>(options, fields, "optimize_incremental()");
          return with_graph(graph_arg, "graph", [&](auto& graph) {
            o.interrupt = python_interrupt();  // Ctrl-C between steps and iterations
            return locked(graph, [&] { return optimize_incremental(graph, o); });
          });
        },
        py::arg("graph"), py::kw_only(), py::arg("options") = py::none(),
        options_signature<IncrementalOptions>("optimize_incremental", kEither, "", "", "IncrementalReport",
                                              doc.optimize_incremental)
            .c_str());
  m.def("marginal_covariances",
        [list_of](const GraphArg& graph_arg, py::handle ids_arg, py::handle options, const py::kwargs& fields) {
          const auto o = options_arg<SparseCholeskyOptions>(options, fields, "marginal_covariances()");
          return with_graph(graph_arg, "graph", [&](const auto& graph) {
            const std::vector<int> ids = vertex_ids_arg(ids_arg, "ids");
            return list_of(locked(graph, [&] { return marginal_covariances(graph, ids, o); }));
          });
        },
        py::arg("graph"), py::arg("ids"), py::kw_only(), py::arg("options") = py::none(),
        options_signature<SparseCholeskyOptions>("marginal_covariances", kEither, "ids: Sequence[int], ", "",
                                                 "List[Array]", doc.marginals)
            .c_str());
  m.def("joint_marginal_covariances",
        [list_of](const GraphArg& graph_arg, py::handle groups_arg, py::handle options, const py::kwargs& fields) {
          const auto o = options_arg<SparseCholeskyOptions>(options, fields, "joint_marginal_covariances()");
          return with_graph(graph_arg, "graph", [&](const auto& graph) {
            const std::vector<std::vector<int>> groups = vertex_id_groups_arg(groups_arg, "groups");
            return list_of(locked(graph, [&] { return joint_marginal_covariances(graph, groups, o); }));
          });
        },
        py::arg("graph"), py::arg("groups"), py::kw_only(), py::arg("options") = py::none(),
        options_signature<SparseCholeskyOptions>("joint_marginal_covariances", kEither,
                                                 "groups: Sequence[Sequence[int]], ", "", "List[Array]",
                                                 doc.joint_marginals)
            .c_str());
  signatures.enable_function_signatures();
  m.def("initialize_odometry",
        [](const GraphArg& graph_arg) {
          with_graph(graph_arg, "graph", [](auto& graph) { locked(graph, [&] { initialize_odometry(graph); }); });
        },
        py::arg("graph"), doc.initialize_odometry);
}

}  // namespace probslam::bindings

