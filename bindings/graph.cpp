#include <pybind11/stl.h>

#include "numpy.hpp"
#include "probslam/graph/graph_initialization.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_2d.hpp"
#include "probslam/io/pose_graph_file.hpp"

namespace probslam::bindings {

namespace {

py::array_t<long> ids_of(const PoseGraph2D& g, VertexKind kind) {
  std::vector<long> ids;
  for (const GraphVertex& v : g.vertices())
    if (v.kind == kind) ids.push_back(v.id);
  return py::array_t<long>(static_cast<py::ssize_t>(ids.size()), ids.data());
}

py::array_t<double> values_of(const PoseGraph2D& g, VertexKind kind) {
  const int dim = kind == VertexKind::kPose ? 3 : 2;
  std::vector<double> values;
  for (const GraphVertex& v : g.vertices())
    if (v.kind == kind) values.insert(values.end(), v.value.data(), v.value.data() + dim);
  py::array_t<double> out({static_cast<py::ssize_t>(values.size() / dim), py::ssize_t{dim}});
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

void set_values(PoseGraph2D& g, py::handle ids_obj, py::handle values_obj, int dim) {
  const LongArray ids = integer_array_arg(ids_obj, "ids");
  if (ids.ndim() != 1) throw py::type_error("ids must be a 1-D array of integers");
  DoubleArray values = matrix_arg(values_obj, "values", dim);
  if (values.shape(0) != ids.shape(0)) throw py::value_error("values must have one row per id");
  for (py::ssize_t k = 0; k < ids.shape(0); ++k) {
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    for (int d = 0; d < dim; ++d) v[d] = values.at(k, d);
    const int index = g.index_of(static_cast<int>(ids.at(k)));
    const VertexKind want = dim == 3 ? VertexKind::kPose : VertexKind::kPoint;
    if (g.vertex(index).kind != want)
      throw py::value_error("ids: vertex " + std::to_string(ids.at(k)) + " is not a " +
                            (dim == 3 ? "pose" : "point"));
    g.set_value(static_cast<int>(ids.at(k)), v);
  }
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

// Every edge's end ids (E, 2), measurement (E, dim) and information (E, dim, dim) as arrays.
template <int Dim, typename Edge, typename Ends>
py::tuple edge_arrays(const PoseGraph2D& g, const std::vector<Edge>& edges, Ends ends) {
  const auto n = static_cast<py::ssize_t>(edges.size());
  py::array_t<long> ids({n, py::ssize_t{2}});
  py::array_t<double> z({n, py::ssize_t{Dim}}), info({n, py::ssize_t{Dim}, py::ssize_t{Dim}});
  auto i = ids.mutable_unchecked<2>();
  auto m = z.mutable_unchecked<2>();
  auto w = info.mutable_unchecked<3>();
  for (py::ssize_t k = 0; k < n; ++k) {
    const auto [a, b] = ends(edges[k]);
    i(k, 0) = g.vertex(a).id;
    i(k, 1) = g.vertex(b).id;
    for (int r = 0; r < Dim; ++r) {
      m(k, r) = edges[k].measurement[r];
      for (int c = 0; c < Dim; ++c) w(k, r, c) = edges[k].information(r, c);
    }
  }
  return py::make_tuple(ids, z, info);
}

}  // namespace

void define_graph(py::module_& m) {
  py::class_<PoseGraph2D>(m, "PoseGraph2D")
      .def(py::init<>())
      .def("add_pose", [](PoseGraph2D& g, int id, py::handle pose) { g.add_pose(id, pose_arg(pose)); },
           py::arg("id"), py::arg("pose"))
      .def("add_point",
           [](PoseGraph2D& g, int id, py::handle p) { g.add_point(id, fixed_vector<2>(p, "point")); },
           py::arg("id"), py::arg("point"))
      .def("add_pose_edge",
           [](PoseGraph2D& g, int from, int to, py::handle z, py::handle info) {
             g.add_pose_edge(from, to, fixed_vector<3>(z, "measurement"), square_matrix_arg(info, "information", 3));
           },
           py::arg("from_id"), py::arg("to_id"), py::arg("measurement"), py::arg("information"))
      .def("add_point_edge",
           [](PoseGraph2D& g, int pose, int point, py::handle z, py::handle info) {
             g.add_point_edge(pose, point, fixed_vector<2>(z, "measurement"), square_matrix_arg(info, "information", 2));
           },
           py::arg("pose_id"), py::arg("point_id"), py::arg("measurement"), py::arg("information"))
      .def("set_fixed", &PoseGraph2D::set_fixed, py::arg("id"), py::arg("fixed") = true)
      .def("is_fixed", [](const PoseGraph2D& g, int id) { return g.vertex(g.index_of(id)).fixed; },
           py::arg("id"))
      .def("set_poses", [](PoseGraph2D& g, py::handle ids, py::handle v) { set_values(g, ids, v, 3); },
           py::arg("ids"), py::arg("poses"))
      .def("set_points", [](PoseGraph2D& g, py::handle ids, py::handle v) { set_values(g, ids, v, 2); },
           py::arg("ids"), py::arg("points"))
      .def("has_vertex", &PoseGraph2D::has_vertex, py::arg("id"))
      .def_property_readonly("num_vertices", &PoseGraph2D::num_vertices)
      .def_property_readonly("num_pose_edges", [](const PoseGraph2D& g) { return g.pose_edges().size(); })
      .def_property_readonly("num_point_edges", [](const PoseGraph2D& g) { return g.point_edges().size(); })
      .def_property_readonly("pose_ids", [](const PoseGraph2D& g) { return ids_of(g, VertexKind::kPose); })
      .def_property_readonly("point_ids", [](const PoseGraph2D& g) { return ids_of(g, VertexKind::kPoint); })
      .def_property_readonly("poses", [](const PoseGraph2D& g) { return values_of(g, VertexKind::kPose); })
      .def_property_readonly("points", [](const PoseGraph2D& g) { return values_of(g, VertexKind::kPoint); })
      .def("edge_ids",
           [](const PoseGraph2D& g) {
             const py::ssize_t n = static_cast<py::ssize_t>(g.pose_edges().size() + g.point_edges().size());
             py::array_t<long> out({n, py::ssize_t{2}});
             auto r = out.mutable_unchecked<2>();
             py::ssize_t k = 0;
             for (const PoseEdge& e : g.pose_edges()) {
               r(k, 0) = g.vertex(e.from).id;
               r(k++, 1) = g.vertex(e.to).id;
             }
             for (const PointEdge& e : g.point_edges()) {
               r(k, 0) = g.vertex(e.pose).id;
               r(k++, 1) = g.vertex(e.point).id;
             }
             return out;
           })
      .def("pose_edges",
           [](const PoseGraph2D& g) {
             return edge_arrays<3>(g, g.pose_edges(), [](const PoseEdge& e) { return std::pair{e.from, e.to}; });
           })
      .def("point_edges",
           [](const PoseGraph2D& g) {
             return edge_arrays<2>(g, g.point_edges(), [](const PointEdge& e) { return std::pair{e.pose, e.point}; });
           })
      .def("chi2", &PoseGraph2D::chi2)
      .def("copy", [](const PoseGraph2D& g) { return PoseGraph2D(g); });

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
          py::gil_scoped_release release;
          return optimize(graph, o);
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
          py::gil_scoped_release release;
          initialize_odometry(graph);
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
          py::gil_scoped_release release;
          return optimize_incremental(graph, o);
        },
        py::arg("graph"), py::arg("poses_per_step") = 100, py::arg("algorithm") = "gauss-newton",
        py::arg("max_iterations") = 10, py::arg("relative_tolerance") = 1e-6, py::arg("step_tolerance") = 1e-10,
        py::arg("kernel") = "none", py::arg("kernel_width") = 1.0, py::arg("linear_solver") = "simplicial",
        py::arg("ordering") = "amd", py::arg("damping") = "marquardt");

  m.def("marginal_covariances",
        [](const PoseGraph2D& graph, const std::vector<int>& ids, const std::string& linear_solver,
           const std::string& ordering) {
          const SparseCholeskyOptions o = solver_options(linear_solver, ordering);
          std::vector<Eigen::MatrixXd> blocks;
          {
            py::gil_scoped_release release;
            blocks = marginal_covariances(graph, ids, o);
          }
          py::list out;
          for (const auto& b : blocks) out.append(py::cast(b));
          return out;
        },
        py::arg("graph"), py::arg("ids"), py::arg("linear_solver") = "simplicial", py::arg("ordering") = "amd");

  m.def("read_pose_graph",
        [](const std::string& path, const std::string& format) {
          const PoseGraphFormat f = choice<PoseGraphFormat>(format, "format",
                                                            {{"auto", PoseGraphFormat::kAuto},
                                                             {"g2o", PoseGraphFormat::kG2o},
                                                             {"toro", PoseGraphFormat::kToro},
                                                             {"isam", PoseGraphFormat::kIsam}});
          py::gil_scoped_release release;
          return read_pose_graph(path, f);
        },
        py::arg("path"), py::arg("format") = "auto");
  m.def("write_g2o", [](const std::string& path, const PoseGraph2D& g) { write_g2o(path, g); },
        py::arg("path"), py::arg("graph"));
}

}  // namespace probslam::bindings
