#include <cmath>
#include <tuple>
#include <pybind11/stl.h>


#include "exceptions.hpp"
#include "graph_common.hpp"
#include "graph_options.hpp"
#include "args.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "options_class.hpp"
#include "persistence.hpp"
#include "repr.hpp"
#include "probslam/graph/graph_initialization.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_2d.hpp"
#include "probslam/io/pose_graph_file.hpp"
#include "pose_graph_options.hpp"

namespace probslam::bindings {

namespace {

// The values (P, 3) of the poses or (L, 2) of the points, in the order of their ids.
py::array_t<double> values_of(const PoseGraph2D& g, VertexKind kind) {
  const int dim = kind == VertexKind::kPose ? 3 : 2;
  const std::vector<double> values = locked(g, [&] {
    std::vector<double> out;
    for (const GraphVertex& v : g.vertices())
      if (v.kind == kind) out.insert(out.end(), v.value.data(), v.value.data() + dim);
    return out;
  });
  py::array_t<double> out({static_cast<py::ssize_t>(values.size()) / dim, py::ssize_t{dim}});
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

void set_values(PoseGraph2D& g, py::handle ids_obj, py::handle values_obj, int dim) {
  const RowsPerId a = rows_per_id(ids_obj, values_obj, dim == 3 ? "poses" : "points", dim);
  std::vector<Eigen::Vector3d> rows(a.ids.size(), Eigen::Vector3d::Zero());
  for (size_t k = 0; k < a.ids.size(); ++k)
    for (int d = 0; d < dim; ++d) rows[k][d] = a.rows.at(static_cast<py::ssize_t>(k), d);
  locked(g, [&] { g.set_values(a.ids, rows, dim == 3 ? VertexKind::kPose : VertexKind::kPoint); });
}

// Every edge's end ids (E, 2), measurement (E, dim) and information (E, dim, dim) as arrays,
// copied under the graph's lock first.
template <int Dim, typename Edge, typename Ends>
py::tuple edge_arrays(const PoseGraph2D& g, const std::vector<Edge>& live, Ends ends) {
  const auto [ids, edges] = edges_with_ids(g, live, ends);
  const auto n = static_cast<py::ssize_t>(edges.size());
  py::array_t<double> z({n, py::ssize_t{Dim}}), info({n, py::ssize_t{Dim}, py::ssize_t{Dim}});
  auto m = z.mutable_unchecked<2>();
  auto w = info.mutable_unchecked<3>();
  for (py::ssize_t k = 0; k < n; ++k) {
    for (int r = 0; r < Dim; ++r) {
      m(k, r) = edges[k].measurement[r];
      for (int c = 0; c < Dim; ++c) w(k, r, c) = edges[k].information(r, c);
    }
  }
  return py::make_tuple(ids, z, info);
}

PoseGraphRead read_graph(const std::string& path, const std::string& format, const std::string& noise,
                         const std::string& rows, const std::string& equivalences) {
  const PoseGraphReadOptions options = read_options(format, noise, rows, equivalences);
  py::gil_scoped_release release;  // a new graph: nothing else can see it yet
  return read_pose_graph(path, options);
}

// The line numbers and the reasons of the lines a read report lists (skipped or repaired).
std::vector<long> line_numbers(const std::vector<SkippedLine>& listed) {
  std::vector<long> lines;
  for (const SkippedLine& s : listed) lines.push_back(s.line);
  return lines;
}

py::list reasons_of(const std::vector<SkippedLine>& listed) {
  py::list reasons;
  for (const SkippedLine& s : listed) reasons.append(escaped_text(s.reason));
  return reasons;
}

constexpr const char* kReadDoc =
    "format: \"g2o\" (VERTEX_SE2 / VERTEX_XY / EDGE_SE2 / EDGE_SE2_XY), \"toro\" (VERTEX2 / EDGE2),\n"
    "\"isam\" (ODOMETRY / EDGE2 / LANDMARK), or \"auto\" (from the first record). noise: what the\n"
    "edges' noise entries hold: \"default\" (the format's own: information for g2o and TORO,\n"
    "square-root information for iSAM), \"information\", \"sqrt_information\" (upper-triangular R,\n"
    "information R^T R) or \"covariance\". rows: \"strict\" (a malformed record raises\n"
    "ValueError(\"file:line: ...\")) or \"skip\" (skipped and counted; more than\n"
    "MAX_BAD_ROW_FRACTION of the records skipped raises, naming the first). equivalences: what\n"
    "TORO EQUIV i j records do: \"merge\" (one vertex, the smaller id; edges between them dropped) or\n"
    "\"ignore\" (counted only, as GTSAM's load2D). A missing file raises FileNotFoundError.";

}  // namespace

PoseGraphFormat format_arg(const std::string& format) {
  return choice<PoseGraphFormat>(format, "format",
                                 {{"auto", PoseGraphFormat::kAuto},
                                  {"g2o", PoseGraphFormat::kG2o},
                                  {"toro", PoseGraphFormat::kToro},
                                  {"isam", PoseGraphFormat::kIsam}});
}

PoseGraphReadOptions read_options(const std::string& format, const std::string& noise, const std::string& rows,
                                  const std::string& equivalences) {
  PoseGraphReadOptions o;
  o.format = format_arg(format);
  o.noise = choice<NoiseFormat>(noise, "noise",
                                {{"default", NoiseFormat::kDefault},
                                 {"information", NoiseFormat::kInformation},
                                 {"sqrt_information", NoiseFormat::kSquareRootInformation},
                                 {"covariance", NoiseFormat::kCovariance}});
  o.rows = choice<RowPolicy>(rows, "rows", {{"strict", RowPolicy::kStrict}, {"skip", RowPolicy::kSkipAndCount}});
  o.equivalences = choice<Equivalences>(equivalences, "equivalences",
                                        {{"merge", Equivalences::kMerge}, {"ignore", Equivalences::kIgnore}});
  return o;
}

namespace {

// Rows of an (n, cols) array of finite numbers, n = rows when rows >= 0.
DoubleArray edge_rows(py::handle obj, const char* name, py::ssize_t cols, py::ssize_t rows) {
  DoubleArray a = matrix_arg(obj, name, cols);
  if (rows >= 0 && a.shape(0) != rows)
    throw py::value_error(std::string(name) + " must have " + std::to_string(rows) + " rows (one per edge), got " +
                          std::to_string(a.shape(0)));
  for (py::ssize_t k = 0; k < a.size(); ++k)
    if (!std::isfinite(a.data()[k])) throw py::value_error(std::string(name) + " must be finite");
  return a;
}

// Writes a fixed-size matrix into entry k of an (n, rows, cols) or (n, cols) array.
template <class M>
void put_block(py::array_t<double>& out, py::ssize_t k, const M& block) {
  double* d = out.mutable_data(k);
  for (int i = 0; i < block.rows(); ++i)
    for (int j = 0; j < block.cols(); ++j) *d++ = block(i, j);
}

// The errors (n, Z) and the Jacobians (n, Z, A) and (n, Z, B) of n edges of one kind, from the
// rows of their two ends a (n, A), b (n, B) and their measurements (n, Z): linearize(a, b, z)
// returns (error, d_a, d_b) of one edge, run with the GIL released.
template <int A, int B, int Z, class Linearize>
auto linearize_rows(py::handle a_obj, const char* a_name, py::handle b_obj, const char* b_name, py::handle z_obj,
                    Linearize linearize) {
  const DoubleArray a = edge_rows(a_obj, a_name, A, -1);
  const py::ssize_t n = a.shape(0);
  const DoubleArray b = edge_rows(b_obj, b_name, B, n), z = edge_rows(z_obj, "measurements", Z, n);
  py::array_t<double> error({n, py::ssize_t{Z}}), d_a({n, py::ssize_t{Z}, py::ssize_t{A}}),
      d_b({n, py::ssize_t{Z}, py::ssize_t{B}});
  {
    py::gil_scoped_release release;
    for (py::ssize_t k = 0; k < n; ++k) {
      const auto [e, ja, jb] = linearize(Eigen::Matrix<double, A, 1>(a.data(k, 0)), Eigen::Matrix<double, B, 1>(b.data(k, 0)),
                                         Eigen::Matrix<double, Z, 1>(z.data(k, 0)));
      put_block(error, k, e.transpose());
      put_block(d_a, k, ja);
      put_block(d_b, k, jb);
    }
  }
  return py::make_tuple(error, d_a, d_b);
}

// linearize_pose_edge / linearize_point_edge over arrays of edges: the refinement of landmark
// runs (probslam.landmark_refine) linearises its edges with the graph's own errors.
void define_edge_linearization(py::module_& m) {
  m.def(
      "linearize_pose_edges",
      [](py::handle from_obj, py::handle to_obj, py::handle z_obj) {
        return linearize_rows<3, 3, 3>(from_obj, "from_poses", to_obj, "to_poses", z_obj,
                                       [](const Eigen::Vector3d& from, const Eigen::Vector3d& to, const Eigen::Vector3d& z) {
                                         const PoseEdgeLinearization l = linearize_pose_edge(from, to, z);
                                         return std::tuple{l.error, l.d_from, l.d_to};
                                       });
      },
      py::arg("from_poses"), py::arg("to_poses"), py::arg("measurements"),
      "Errors and Jacobians of pose edges, as PoseGraph2D's optimiser linearises them: for\n"
      "from_poses, to_poses and measurements (n, 3), returns (error (n, 3), d_from (n, 3, 3),\n"
      "d_to (n, 3, 3)); error = t2v(z^-1 from^-1 to), its angle wrapped; angles move additively.");
  m.def(
      "linearize_point_edges",
      [](py::handle pose_obj, py::handle point_obj, py::handle z_obj) {
        return linearize_rows<3, 2, 2>(pose_obj, "poses", point_obj, "points", z_obj,
                                       [](const Eigen::Vector3d& pose, const Eigen::Vector2d& point, const Eigen::Vector2d& z) {
                                         const PointEdgeLinearization l = linearize_point_edge(pose, point, z);
                                         return std::tuple{l.error, l.d_pose, l.d_point};
                                       });
      },
      py::arg("poses"), py::arg("points"), py::arg("measurements"),
      "Errors and Jacobians of point edges (PoseGraph2D's, g2o EDGE_SE2_XY): for poses (n, 3),\n"
      "points (n, 2) and measurements (n, 2), returns (error (n, 2), d_pose (n, 2, 3),\n"
      "d_point (n, 2, 2)); error = R(theta)^T (point - position) - z.");
}

}  // namespace

void define_graph(py::module_& m) {
  bind_options<SparseCholeskyOptions>(m, "SparseCholeskyOptions", "The sparse Cholesky factorisation (CHOLMOD).");
  bind_options<OptimizerOptions>(m, "OptimizerOptions",
                                 "The pose-graph optimiser's options (Gauss-Newton or Levenberg-Marquardt).");
  bind_options<IncrementalOptions>(m, "IncrementalOptions",
                                   "optimize_incremental's options: poses per step and each step's optimiser.");
  // Every method runs its C++ work under the graph's lock with the GIL released (object_lock.hpp).
  auto graph_class = py::class_<PoseGraph2D>(m, "PoseGraph2D",
                          "A planar pose/landmark graph (GraphSLAM's constraints, ch. 11): pose vertices (x m, y m,\n"
                          "theta rad), point vertices (x, y) m, pose edges (relative pose of `to` in `from`'s frame,\n"
                          "(3, 3) information) and point edges (the point (x, y) m in the pose's frame, (2, 2)\n"
                          "information), as in g2o's EDGE_SE2 / EDGE_SE2_XY. Vertex ids are ints shared by poses and\n"
                          "points. Every add_* refuses repeated or unknown ids, non-finite values and information\n"
                          "that is not symmetric positive definite (ValueError, graph unchanged).")
      .def(py::init<>(), "An empty graph.")
      .def("add_pose",
           [](PoseGraph2D& g, IntArg id_arg, py::handle pose) {
             const int id = id_arg.get("id");
             const Eigen::Vector3d p = pose_arg(pose);
             locked(g, [&] { g.add_pose(id, p); });
           },
           py::arg("id"), py::arg("pose"), "Adds pose vertex id with value pose (3,) (x m, y m, theta rad).")
      .def("add_point",
           [](PoseGraph2D& g, IntArg id_arg, py::handle point) {
             const int id = id_arg.get("id");
             const Eigen::Vector2d p = fixed_vector<2>(point, "point");
             locked(g, [&] { g.add_point(id, p); });
           },
           py::arg("id"), py::arg("point"), "Adds point (landmark) vertex id with value point (2,) m.")
      .def("add_pose_edge",
           [](PoseGraph2D& g, IntArg from_id, IntArg to_id, py::handle z, py::handle info) {
             const int from = from_id.get("from_id");
             const int to = to_id.get("to_id");
             const Eigen::Vector3d zv = fixed_vector<3>(z, "measurement");
             const Eigen::Matrix3d omega = square_matrix_arg(info, "information", 3);
             locked(g, [&] { g.add_pose_edge(from, to, zv, omega); });
           },
           py::arg("from_id"), py::arg("to_id"), py::arg("measurement"), py::arg("information"),
           "Adds a pose-pose edge: measurement (3,) the pose of to_id in from_id's frame (m, m, rad),\n"
           "information (3, 3) its inverse covariance.")
      .def("add_point_edge",
           [](PoseGraph2D& g, IntArg pose_id, IntArg point_id, py::handle z, py::handle info) {
             const int pose = pose_id.get("pose_id");
             const int point = point_id.get("point_id");
             const Eigen::Vector2d zv = fixed_vector<2>(z, "measurement");
             const Eigen::Matrix2d omega = square_matrix_arg(info, "information", 2);
             locked(g, [&] { g.add_point_edge(pose, point, zv, omega); });
           },
           py::arg("pose_id"), py::arg("point_id"), py::arg("measurement"), py::arg("information"),
           "Adds a pose-point edge: measurement (2,) the point in pose_id's frame (m), information (2, 2).")
      .def("set_poses", [](PoseGraph2D& g, py::handle ids, py::handle v) { set_values(g, ids, v, 3); },
           py::arg("ids"), py::arg("poses"),
           "Replaces the values of pose vertices ids (N,) with poses (N, 3), all or nothing.")
      .def("set_points", [](PoseGraph2D& g, py::handle ids, py::handle v) { set_values(g, ids, v, 2); },
           py::arg("ids"), py::arg("points"),
           "Replaces the values of point vertices ids (N,) with points (N, 2) m, all or nothing.")
      .def_property_readonly(
          "landmark_ids",
          [](const PoseGraph2D& g) {
            return ids_of(g, VertexKind::kPoint, [](const GraphVertex& v) { return static_cast<long>(v.landmark_id); });
          },
          "Each point's id among the landmarks (iSAM's LANDMARK numbers, an id space apart from the "
          "poses'): equal to point_ids unless read_pose_graph moved an iSAM landmark whose number a pose "
          "uses; write_isam writes these.")
      .def_property_readonly("poses", [](const PoseGraph2D& g) { return values_of(g, VertexKind::kPose); },
                             "(P, 3) pose values (x m, y m, theta rad) in the order of pose_ids, a copy.")
      .def_property_readonly("points", [](const PoseGraph2D& g) { return values_of(g, VertexKind::kPoint); },
                             "(L, 2) point values (x, y) m in the order of point_ids, a copy.")
      .def("edge_ids", &all_edge_ids<PoseGraph2D>,
           "(E, 2) int64 end ids of every edge: pose edges (from, to) first, then point edges (pose, point).")
      .def("pose_edges",
           [](const PoseGraph2D& g) {
             return edge_arrays<3>(g, g.pose_edges(), [](const PoseEdge& e) { return std::pair{e.from, e.to}; });
           },
           "(ids (E, 2) (from, to), measurements (E, 3) (m, m, rad), information (E, 3, 3)) of the pose edges.")
      .def("point_edges",
           [](const PoseGraph2D& g) {
             return edge_arrays<2>(g, g.point_edges(), [](const PointEdge& e) { return std::pair{e.pose, e.point}; });
           },
           "(ids (E, 2) (pose, point), measurements (E, 2) m, information (E, 2, 2)) of the point edges.")
      .def("chi2", getter(&PoseGraph2D::chi2),
           "Sum over edges of e^T Omega e at the current values (g2o's chi2); ValueError if not finite.")
      .def("__repr__", [](py::handle self) {
        const PoseGraph2D& g = self.cast<const PoseGraph2D&>();
        return repr_of(self, locked(g, [&] {
          std::size_t points = 0;
          for (const GraphVertex& v : g.vertices()) points += v.kind == VertexKind::kPoint;
          const std::size_t poses = g.vertices().size() - points;
          return std::to_string(poses) + " poses, " + std::to_string(points) + " landmarks, " +
                 std::to_string(g.pose_edges().size() + g.point_edges().size()) + " edges";
        }));
      });
  define_common_graph_methods(graph_class, "Whether a pose or point vertex has this id.");
  define_persistence<PoseGraph2D>(graph_class);

  py::class_<OptimizationReport>(m, "OptimizationReport", "What optimize did.")
      .def_readonly("iterations", &OptimizationReport::iterations, "Iterations run.")
      .def_readonly("initial_chi2", &OptimizationReport::initial_chi2, "chi2 at the start.")
      .def_readonly("chi2", &OptimizationReport::chi2, "Sum of e^T Omega e at the end (g2o's chi2).")
      .def_readonly("objective", &OptimizationReport::objective,
                    "The robust objective at the end (equals chi2 without a kernel).")
      .def_readonly("converged", &OptimizationReport::converged, "Whether a tolerance was met.")
      .def_readonly("stop_reason", &OptimizationReport::stop_reason, "Why it stopped, in words.")
      .def_readonly("chi2_history", &OptimizationReport::chi2_history, "chi2 after each iteration (list).")
      .def_readonly("iteration_seconds", &OptimizationReport::iteration_seconds,
                    "Seconds of each iteration (linearise, factorise, solve, update).")
      .def_readonly("factor_nonzeros", &OptimizationReport::factor_nonzeros, "Non-zeros of the Cholesky factor.")
      .def("__repr__", [](py::handle self) {
        const OptimizationReport& r = self.cast<const OptimizationReport&>();
        return repr_of(self, std::to_string(r.iterations) + " iterations, chi2 " + num(r.initial_chi2) + " -> " +
                                 num(r.chi2) + (r.converged ? ", converged" : ", not converged") + " (" +
                                 r.stop_reason + ")");
      });

  py::class_<IncrementalReport>(m, "IncrementalReport", "What optimize_incremental did.")
      .def_readonly("steps", &IncrementalReport::steps, "Optimisations run (one per poses_per_step poses).")
      .def_readonly("iterations", &IncrementalReport::iterations, "Iterations summed over the steps.")
      .def_readonly("chi2", &IncrementalReport::chi2, "chi2 of the whole graph at the end.")
      .def_readonly("step_chi2", &IncrementalReport::step_chi2, "chi2 of the optimised part after each step (list).")
      .def("__repr__", [](py::handle self) {
        const IncrementalReport& r = self.cast<const IncrementalReport&>();
        return repr_of(self, std::to_string(r.steps) + " steps, " + std::to_string(r.iterations) + " iterations, chi2 " +
                                 num(r.chi2));
      });

  py::class_<PoseGraphReadReport>(m, "PoseGraphReadReport",
                                  "What read_pose_graph_with_report did with the file's records.")
      .def_readonly("rows", &PoseGraphReadReport::rows,
                    "Records read (lines neither blank nor '#'), skipped ones included.")
      .def_readonly("skipped_rows", &PoseGraphReadReport::skipped_rows, "Records skipped (0 under rows=\"strict\").")
      .def_readonly("equivalences", &PoseGraphReadReport::equivalences,
                    "TORO EQUIV records read (applied under equivalences=\"merge\" only).")
      .def_readonly("merged_vertices", &PoseGraphReadReport::merged_vertices,
                    "Vertex ids merged into another by EQUIV records.")
      .def_readonly("collapsed_edges", &PoseGraphReadReport::collapsed_edges,
                    "Edges dropped because EQUIV records made their two ends one vertex.")
      .def_property_readonly(
          "skipped_lines",
          [](const PoseGraphReadReport& r) { return line_numbers(r.skipped_lines); },
          "Line numbers (1-based) of the first POSE_GRAPH_MAX_REPORTED_LINES skipped records.")
      .def_property_readonly(
          "skipped_reasons",
          [](const PoseGraphReadReport& r) { return reasons_of(r.skipped_lines); },
          "Why each of skipped_lines was skipped.")
      .def_readonly("repaired_rows", &PoseGraphReadReport::repaired_rows,
                    "Records whose information matrix was not positive definite and was repaired: eigenvalues\n"
                    "raised to INFORMATION_EIGENVALUE_FLOOR times the largest (docs/pose_graphs.md).")
      .def_property_readonly(
          "repaired_lines",
          [](const PoseGraphReadReport& r) { return line_numbers(r.repaired_lines); },
          "Line numbers (1-based) of the first POSE_GRAPH_MAX_REPORTED_LINES repaired records.")
      .def_property_readonly(
          "repaired_reasons",
          [](const PoseGraphReadReport& r) { return reasons_of(r.repaired_lines); },
          "What was repaired in each of repaired_lines.")
      .def("__repr__", [](py::handle self) {
        const PoseGraphReadReport& r = self.cast<const PoseGraphReadReport&>();
        return repr_of(self, std::to_string(r.rows) + " rows, " + std::to_string(r.skipped_rows) + " skipped" +
                                 (r.repaired_rows ? ", " + std::to_string(r.repaired_rows) + " repaired" : ""));
      });
  m.attr("MAX_BAD_ROW_FRACTION") = kMaxBadRowFraction;
  m.attr("INFORMATION_EIGENVALUE_FLOOR") = kInformationEigenvalueFloor;
  // static: pybind11 keeps the docstrings' pointers
  static const std::string graph_doc = std::string("Reads a pose graph file into a PoseGraph2D. ") + kReadDoc;
  static const std::string report_doc =
      std::string("Reads a pose graph file: (PoseGraph2D, PoseGraphReadReport). ") + kReadDoc;
  m.attr("POSE_GRAPH_MAX_REPORTED_LINES") = kPoseGraphMaxReportedLines;

  m.def("read_pose_graph",
        [](const std::string& path, const std::string& format, const std::string& noise, const std::string& rows,
           const std::string& equivalences) {
          return std::move(read_graph(path, format, noise, rows, equivalences).graph);
        },
        py::arg("path"), py::arg("format") = "auto", py::arg("noise") = "default", py::arg("rows") = "strict",
        py::arg("equivalences") = "merge", graph_doc.c_str());
  m.def("read_pose_graph_with_report",
        [](const std::string& path, const std::string& format, const std::string& noise, const std::string& rows,
           const std::string& equivalences) {
          PoseGraphRead read = read_graph(path, format, noise, rows, equivalences);
          return py::make_tuple(std::move(read.graph), std::move(read.report));
        },
        py::arg("path"), py::arg("format") = "auto", py::arg("noise") = "default", py::arg("rows") = "skip",
        py::arg("equivalences") = "merge", report_doc.c_str());
  m.def("write_g2o", [](const std::string& path, const PoseGraph2D& g) { locked(g, [&] { write_g2o(path, g); }); },
        py::arg("path"), py::arg("graph"),
        "Writes graph to path as g2o text: vertices with their current values, FIX lines, edges.");
  m.def("write_isam", [](const std::string& path, const PoseGraph2D& g) { locked(g, [&] { write_isam(path, g); }); },
        py::arg("path"), py::arg("graph"),
        "iSAM text: pose edges, then LANDMARK edges under each point's landmark id (see "
        "PoseGraph2D.landmark_ids); no vertex values (reading back dead-reckons them).");
  define_edge_linearization(m);
}

}  // namespace probslam::bindings
