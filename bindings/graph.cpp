#include <pybind11/stl.h>


#include "numpy.hpp"
#include "object_lock.hpp"
#include "probslam/graph/graph_initialization.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_2d.hpp"
#include "probslam/io/pose_graph_file.hpp"

namespace probslam::bindings {

namespace {

// Vertex ids and values of one kind, gathered under the graph's lock, arrays built after it.
struct KindSnapshot {
  std::vector<long> ids;
  std::vector<double> values;
};

KindSnapshot snapshot(const PoseGraph2D& g, VertexKind kind, bool landmark_ids = false) {
  return locked(g, [&] {
    KindSnapshot out;
    const int dim = kind == VertexKind::kPose ? 3 : 2;
    for (const GraphVertex& v : g.vertices()) {
      if (v.kind != kind) continue;
      out.ids.push_back(landmark_ids ? v.landmark_id : v.id);
      out.values.insert(out.values.end(), v.value.data(), v.value.data() + dim);
    }
    return out;
  });
}

py::array_t<long> ids_of(const PoseGraph2D& g, VertexKind kind, bool landmark_ids = false) {
  const KindSnapshot s = snapshot(g, kind, landmark_ids);
  return py::array_t<long>(static_cast<py::ssize_t>(s.ids.size()), s.ids.data());
}

py::array_t<double> values_of(const PoseGraph2D& g, VertexKind kind) {
  const KindSnapshot s = snapshot(g, kind);
  const py::ssize_t dim = kind == VertexKind::kPose ? 3 : 2;
  py::array_t<double> out({static_cast<py::ssize_t>(s.ids.size()), dim});
  std::copy(s.values.begin(), s.values.end(), out.mutable_data());
  return out;
}

// Vertex ids from Python: integers only (a float id would be truncated) and within int (a
// larger one would wrap onto another vertex).
std::vector<int> vertex_ids(py::handle obj, const char* name) {
  const LongArray ids = integer_array_arg(obj, name);
  if (ids.ndim() != 1) throw py::value_error(std::string(name) + " must be a 1-D array of integers");
  return int_entries(ids, name, "vertex id");
}

void set_values(PoseGraph2D& g, py::handle ids_obj, py::handle values_obj, int dim) {
  const std::vector<int> ids = vertex_ids(ids_obj, "ids");
  DoubleArray values = matrix_arg(values_obj, dim == 3 ? "poses" : "points", dim);
  if (values.shape(0) != static_cast<py::ssize_t>(ids.size()))
    throw py::value_error(std::string(dim == 3 ? "poses" : "points") + " must have one row per id");
  std::vector<Eigen::Vector3d> rows(ids.size(), Eigen::Vector3d::Zero());
  for (size_t k = 0; k < ids.size(); ++k)
    for (int d = 0; d < dim; ++d) rows[k][d] = values.at(static_cast<py::ssize_t>(k), d);
  locked(g, [&] { g.set_values(ids, rows, dim == 3 ? VertexKind::kPose : VertexKind::kPoint); });
}

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

SparseCholeskyOptions solver_options(const std::string& method, const std::string& ordering) {
  SparseCholeskyOptions o;
  o.method = choice<FactorMethod>(method, "linear_solver",
                                  {{"simplicial", FactorMethod::kSimplicial},
                                   {"supernodal", FactorMethod::kSupernodal},
                                   {"auto", FactorMethod::kAuto}});
  o.ordering = choice<FillOrdering>(ordering, "ordering",
                                    {{"amd", FillOrdering::kAmd}, {"metis", FillOrdering::kMetis}});
  return o;
}

OptimizerOptions optimizer_options(const std::string& algorithm, int max_iterations, double relative_tolerance,
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

// Every edge's end ids (E, 2), measurement (E, dim) and information (E, dim, dim) as arrays,
// copied under the graph's lock first.
template <int Dim, typename Edge, typename Ends>
py::tuple edge_arrays(const PoseGraph2D& g, const std::vector<Edge>& live, Ends ends) {
  std::vector<std::pair<long, long>> ends_ids;
  const std::vector<Edge> edges = locked(g, [&] {
    for (const Edge& e : live) {
      const auto [a, b] = ends(e);
      ends_ids.emplace_back(g.vertex(a).id, g.vertex(b).id);
    }
    return live;
  });
  const auto n = static_cast<py::ssize_t>(edges.size());
  py::array_t<long> ids({n, py::ssize_t{2}});
  py::array_t<double> z({n, py::ssize_t{Dim}}), info({n, py::ssize_t{Dim}, py::ssize_t{Dim}});
  auto i = ids.mutable_unchecked<2>();
  auto m = z.mutable_unchecked<2>();
  auto w = info.mutable_unchecked<3>();
  for (py::ssize_t k = 0; k < n; ++k) {
    i(k, 0) = ends_ids[k].first;
    i(k, 1) = ends_ids[k].second;
    for (int r = 0; r < Dim; ++r) {
      m(k, r) = edges[k].measurement[r];
      for (int c = 0; c < Dim; ++c) w(k, r, c) = edges[k].information(r, c);
    }
  }
  return py::make_tuple(ids, z, info);
}

py::array_t<long> all_edge_ids(const PoseGraph2D& g) {
  const std::vector<long> flat = locked(g, [&] {
    std::vector<long> out;
    for (const PoseEdge& e : g.pose_edges()) out.insert(out.end(), {g.vertex(e.from).id, g.vertex(e.to).id});
    for (const PointEdge& e : g.point_edges()) out.insert(out.end(), {g.vertex(e.pose).id, g.vertex(e.point).id});
    return out;
  });
  py::array_t<long> out({static_cast<py::ssize_t>(flat.size() / 2), py::ssize_t{2}});
  std::copy(flat.begin(), flat.end(), out.mutable_data());
  return out;
}

PoseGraphFormat format_arg(const std::string& format) {
  return choice<PoseGraphFormat>(format, "format",
                                 {{"auto", PoseGraphFormat::kAuto},
                                  {"g2o", PoseGraphFormat::kG2o},
                                  {"toro", PoseGraphFormat::kToro},
                                  {"isam", PoseGraphFormat::kIsam}});
}

}  // namespace

void define_graph(py::module_& m) {
  // Every method runs its C++ work under the graph's lock with the GIL released (object_lock.hpp).
  py::class_<PoseGraph2D>(m, "PoseGraph2D")
      .def(py::init<>())
      .def("add_pose",
           [](PoseGraph2D& g, int id, py::handle pose) {
             const Eigen::Vector3d p = pose_arg(pose);
             locked(g, [&] { g.add_pose(id, p); });
           },
           py::arg("id"), py::arg("pose"))
      .def("add_point",
           [](PoseGraph2D& g, int id, py::handle point) {
             const Eigen::Vector2d p = fixed_vector<2>(point, "point");
             locked(g, [&] { g.add_point(id, p); });
           },
           py::arg("id"), py::arg("point"))
      .def("add_pose_edge",
           [](PoseGraph2D& g, int from, int to, py::handle z, py::handle info) {
             const Eigen::Vector3d zv = fixed_vector<3>(z, "measurement");
             const Eigen::Matrix3d omega = square_matrix_arg(info, "information", 3);
             locked(g, [&] { g.add_pose_edge(from, to, zv, omega); });
           },
           py::arg("from_id"), py::arg("to_id"), py::arg("measurement"), py::arg("information"))
      .def("add_point_edge",
           [](PoseGraph2D& g, int pose, int point, py::handle z, py::handle info) {
             const Eigen::Vector2d zv = fixed_vector<2>(z, "measurement");
             const Eigen::Matrix2d omega = square_matrix_arg(info, "information", 2);
             locked(g, [&] { g.add_point_edge(pose, point, zv, omega); });
           },
           py::arg("pose_id"), py::arg("point_id"), py::arg("measurement"), py::arg("information"))
      .def("set_fixed", [](PoseGraph2D& g, int id, bool fixed) { locked(g, [&] { g.set_fixed(id, fixed); }); },
           py::arg("id"), py::arg("fixed") = true)
      .def("is_fixed", [](const PoseGraph2D& g, int id) { return locked(g, [&] { return g.vertex(g.index_of(id)).fixed; }); },
           py::arg("id"))
      .def("set_poses", [](PoseGraph2D& g, py::handle ids, py::handle v) { set_values(g, ids, v, 3); },
           py::arg("ids"), py::arg("poses"))
      .def("set_points", [](PoseGraph2D& g, py::handle ids, py::handle v) { set_values(g, ids, v, 2); },
           py::arg("ids"), py::arg("points"))
      .def("has_vertex", [](const PoseGraph2D& g, int id) { return locked(g, [&] { return g.has_vertex(id); }); },
           py::arg("id"))
      .def_property_readonly("num_vertices", getter(&PoseGraph2D::num_vertices))
      .def_property_readonly("num_pose_edges",
                             [](const PoseGraph2D& g) { return locked(g, [&] { return g.pose_edges().size(); }); })
      .def_property_readonly("num_point_edges",
                             [](const PoseGraph2D& g) { return locked(g, [&] { return g.point_edges().size(); }); })
      .def_property_readonly("pose_ids", [](const PoseGraph2D& g) { return ids_of(g, VertexKind::kPose); })
      .def_property_readonly("point_ids", [](const PoseGraph2D& g) { return ids_of(g, VertexKind::kPoint); })
      .def_property_readonly(
          "landmark_ids", [](const PoseGraph2D& g) { return ids_of(g, VertexKind::kPoint, true); },
          "Each point's id among the landmarks (iSAM's LANDMARK numbers, an id space apart from the "
          "poses'): equal to point_ids unless read_pose_graph moved an iSAM landmark whose number a pose "
          "uses; write_isam writes these.")
      .def_property_readonly("poses", [](const PoseGraph2D& g) { return values_of(g, VertexKind::kPose); })
      .def_property_readonly("points", [](const PoseGraph2D& g) { return values_of(g, VertexKind::kPoint); })
      .def("edge_ids", &all_edge_ids)
      .def("pose_edges",
           [](const PoseGraph2D& g) {
             return edge_arrays<3>(g, g.pose_edges(), [](const PoseEdge& e) { return std::pair{e.from, e.to}; });
           })
      .def("point_edges",
           [](const PoseGraph2D& g) {
             return edge_arrays<2>(g, g.point_edges(), [](const PointEdge& e) { return std::pair{e.pose, e.point}; });
           })
      .def("chi2", getter(&PoseGraph2D::chi2))
      .def("copy", [](const PoseGraph2D& g) { return locked(g, [&] { return PoseGraph2D(g); }); });

  py::class_<OptimizationReport>(m, "OptimizationReport")
      .def_readonly("iterations", &OptimizationReport::iterations)
      .def_readonly("initial_chi2", &OptimizationReport::initial_chi2)
      .def_readonly("chi2", &OptimizationReport::chi2)
      .def_readonly("objective", &OptimizationReport::objective)
      .def_readonly("converged", &OptimizationReport::converged)
      .def_readonly("stop_reason", &OptimizationReport::stop_reason)
      .def_readonly("chi2_history", &OptimizationReport::chi2_history)
      .def_readonly("iteration_seconds", &OptimizationReport::iteration_seconds)
      .def_readonly("factor_nonzeros", &OptimizationReport::factor_nonzeros)
      .def("__repr__", [](const OptimizationReport& r) {
        return "OptimizationReport(iterations=" + std::to_string(r.iterations) +
               ", initial_chi2=" + std::to_string(r.initial_chi2) + ", chi2=" + std::to_string(r.chi2) +
               ", converged=" + (r.converged ? "True" : "False") + ", stop_reason='" + r.stop_reason + "')";
      });

  m.def("optimize",
        [](PoseGraph2D& graph, const std::string& algorithm, int max_iterations, double relative_tolerance,
           double step_tolerance, const std::string& kernel, double kernel_width,
           const std::string& linear_solver, const std::string& ordering, const std::string& damping) {
          const OptimizerOptions o = optimizer_options(algorithm, max_iterations, relative_tolerance, step_tolerance,
                                                       kernel, kernel_width, linear_solver, ordering, damping);
          return locked(graph, [&] { return optimize(graph, o); });
        },
        py::arg("graph"), py::arg("algorithm") = "gauss-newton", py::arg("max_iterations") = 100,
        py::arg("relative_tolerance") = 1e-10, py::arg("step_tolerance") = 1e-10, py::arg("kernel") = "none",
        py::arg("kernel_width") = 1.0, py::arg("linear_solver") = "simplicial", py::arg("ordering") = "amd",
        py::arg("damping") = "marquardt");

  py::class_<IncrementalReport>(m, "IncrementalReport")
      .def_readonly("steps", &IncrementalReport::steps)
      .def_readonly("iterations", &IncrementalReport::iterations)
      .def_readonly("chi2", &IncrementalReport::chi2)
      .def_readonly("step_chi2", &IncrementalReport::step_chi2)
      .def("__repr__", [](const IncrementalReport& r) {
        return "IncrementalReport(steps=" + std::to_string(r.steps) + ", iterations=" + std::to_string(r.iterations) +
               ", chi2=" + std::to_string(r.chi2) + ")";
      });

  m.def("initialize_odometry",
        [](PoseGraph2D& graph) {
          locked(graph, [&] { initialize_odometry(graph); });
        },
        py::arg("graph"));
  m.def("optimize_incremental",
        [](PoseGraph2D& graph, int poses_per_step, const std::string& algorithm, int max_iterations,
           double relative_tolerance, double step_tolerance, const std::string& kernel, double kernel_width,
           const std::string& linear_solver, const std::string& ordering, const std::string& damping) {
          IncrementalOptions o;
          o.poses_per_step = poses_per_step;
          o.step = optimizer_options(algorithm, max_iterations, relative_tolerance, step_tolerance, kernel,
                                     kernel_width, linear_solver, ordering, damping);
          return locked(graph, [&] { return optimize_incremental(graph, o); });
        },
        py::arg("graph"), py::arg("poses_per_step") = 100, py::arg("algorithm") = "gauss-newton",
        py::arg("max_iterations") = 10, py::arg("relative_tolerance") = 1e-6, py::arg("step_tolerance") = 1e-10,
        py::arg("kernel") = "none", py::arg("kernel_width") = 1.0, py::arg("linear_solver") = "simplicial",
        py::arg("ordering") = "amd", py::arg("damping") = "marquardt");

  m.def("marginal_covariances",
        [](const PoseGraph2D& graph, const std::vector<int>& ids, const std::string& linear_solver,
           const std::string& ordering) {
          const SparseCholeskyOptions o = solver_options(linear_solver, ordering);
          const std::vector<Eigen::MatrixXd> blocks =
              locked(graph, [&] { return marginal_covariances(graph, ids, o); });
          py::list out;
          for (const auto& b : blocks) out.append(py::cast(b));
          return out;
        },
        py::arg("graph"), py::arg("ids"), py::arg("linear_solver") = "simplicial", py::arg("ordering") = "amd");

  m.def("read_pose_graph",
        [](const std::string& path, const std::string& format) {
          const PoseGraphFormat f = format_arg(format);
          py::gil_scoped_release release;  // a new graph: nothing else can see it yet
          return read_pose_graph(path, f);
        },
        py::arg("path"), py::arg("format") = "auto");
  m.def("write_g2o", [](const std::string& path, const PoseGraph2D& g) { locked(g, [&] { write_g2o(path, g); }); },
        py::arg("path"), py::arg("graph"));
  m.def("write_isam", [](const std::string& path, const PoseGraph2D& g) { locked(g, [&] { write_isam(path, g); }); },
        py::arg("path"), py::arg("graph"),
        "iSAM text: pose edges, then LANDMARK edges under each point's landmark id (see "
        "PoseGraph2D.landmark_ids); no vertex values (reading back dead-reckons them).");
}

}  // namespace probslam::bindings
