// probslam.PoseGraph3D, its initialisers and readers; the optimiser's and marginals' bindings for both
// graph types (graph_options.hpp).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "args.hpp"
#include "graph_common.hpp"
#include "graph_options.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "persistence.hpp"
#include "repr.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_3d.hpp"
#include "probslam/graph/pose_graph_3d_initialization.hpp"
#include "probslam/io/pose_graph_3d_graph.hpp"
#include "pose_graph_options.hpp"

namespace probslam::bindings {

namespace {

// A pose as Python sees it: (7,) [x, y, z, qx, qy, qz, qw], g2o's VERTEX_SE3:QUAT order.
constexpr int kPoseWidth = 7;

Pose3 pose_of(const double* p) {
  return {Eigen::Quaterniond(p[6], p[3], p[4], p[5]), Eigen::Vector3d(p[0], p[1], p[2])};
}

void write_pose(const Pose3& pose, double* out) {
  for (int k = 0; k < 3; ++k) out[k] = pose.translation[k];
  out[3] = pose.rotation.x();
  out[4] = pose.rotation.y();
  out[5] = pose.rotation.z();
  out[6] = pose.rotation.w();
}

Pose3 pose3_arg(py::handle obj, const char* name) {
  const Eigen::Matrix<double, kPoseWidth, 1> v = fixed_vector<kPoseWidth>(obj, name);
  return pose_of(v.data());
}

py::array_t<double> pose_rows(const std::vector<Pose3>& poses) {
  py::array_t<double> out({static_cast<py::ssize_t>(poses.size()), py::ssize_t{kPoseWidth}});
  for (size_t k = 0; k < poses.size(); ++k) write_pose(poses[k], out.mutable_data() + kPoseWidth * k);
  return out;
}

// The (n, 7) measurements and the (n, 6, 6) information matrices of edges or priors.
template <class Factor>
py::array_t<double> measurements(const std::vector<Factor>& factors) {
  py::array_t<double> out({static_cast<py::ssize_t>(factors.size()), py::ssize_t{kPoseWidth}});
  for (size_t k = 0; k < factors.size(); ++k) write_pose(factors[k].measurement, out.mutable_data() + kPoseWidth * k);
  return out;
}

template <class Factor>
py::array_t<double> informations(const std::vector<Factor>& factors) {
  py::array_t<double> out({static_cast<py::ssize_t>(factors.size()), py::ssize_t{6}, py::ssize_t{6}});
  for (size_t k = 0; k < factors.size(); ++k)
    Eigen::Map<Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(out.mutable_data() + 36 * k) = factors[k].information;
  return out;
}

// The values of the vertices of one kind, in index order.
std::vector<Pose3> values_of(const PoseGraph3D& g, VertexKind kind) {
  return locked(g, [&] {
    std::vector<Pose3> out;
    for (const Pose3Vertex& v : g.vertices())
      if (v.kind == kind) out.push_back(v.value);
    return out;
  });
}


}  // namespace

void define_graph3d(py::module_& m) {
  // Every method runs its C++ work under the graph's lock (object_lock.hpp).
  auto graph_class = py::class_<PoseGraph3D>(
      m, "PoseGraph3D",
      "A 3-D pose graph: pose vertices (7,) [x, y, z, qx, qy, qz, qw] (m; a unit quaternion, g2o's\n"
      "VERTEX_SE3:QUAT order) and pose edges (the pose of `to` in `from`'s frame, same layout, with\n"
      "(6, 6) information in g2o's EDGE_SE3:QUAT order [translation, rotation]). The error of an\n"
      "edge is [t_e, Log(R_e)] of z^-1 x_from^-1 x_to (m, rad); optimisers perturb poses on the right,\n"
      "x (+) [v, w] = (R Exp(w), t + R v). Every add_* refuses repeated or unknown ids, non-finite\n"
      "values, quaternions whose norm is not 1 within QUATERNION_NORM_TOLERANCE (stored normalised) and\n"
      "information that is not symmetric positive definite (ValueError, graph unchanged).\n"
      "Point landmarks (3,) [x, y, z] m share the poses' id space; a point edge (g2o EDGE_SE3_TRACKXYZ)\n"
      "measures the point in the frame of a sensor at `offset` on its pose: error\n"
      "(x_pose * offset)^-1 p - z (m), (3, 3) information; points move additively.")
      .def(py::init<>(), "An empty graph.")
      .def("add_pose",
           [](PoseGraph3D& g, IntArg id_arg, py::handle pose) {
             const int id = id_arg.get("id");
             const Pose3 p = pose3_arg(pose, "pose");
             locked(g, [&] { g.add_pose(id, p); });
           },
           py::arg("id"), py::arg("pose"), "Adds pose vertex id with value pose (7,) [x, y, z, qx, qy, qz, qw].")
      .def("add_point",
           [](PoseGraph3D& g, IntArg id_arg, py::handle point) {
             const int id = id_arg.get("id");
             const Eigen::Vector3d p = fixed_vector<3>(point, "point");
             locked(g, [&] { g.add_point(id, p); });
           },
           py::arg("id"), py::arg("point"), "Adds point (landmark) vertex id at point (3,) [x, y, z] m.")
      .def("add_point_edge",
           [](PoseGraph3D& g, IntArg pose_id, IntArg point_id, py::handle z, py::handle info, py::handle offset) {
             const int pose = pose_id.get("pose_id");
             const int point = point_id.get("point_id");
             const Eigen::Vector3d zv = fixed_vector<3>(z, "measurement");
             const Eigen::Matrix3d omega = square_matrix_arg(info, "information", 3);
             const Pose3 sensor = offset.is_none() ? Pose3{} : pose3_arg(offset, "offset");
             locked(g, [&] { g.add_point_edge(pose, point, zv, omega, sensor); });
           },
           py::arg("pose_id"), py::arg("point_id"), py::arg("measurement"), py::arg("information"),
           py::arg("offset") = py::none(),
           "Adds a pose-point edge (g2o EDGE_SE3_TRACKXYZ): measurement (3,) the point in the frame of the\n"
           "sensor at offset (7,) [x, y, z, qx, qy, qz, qw] in pose_id's frame (None: the pose itself), m;\n"
           "information (3, 3). Error (x_pose * offset)^-1 p - z.")
      .def("add_pose_edge",
           [](PoseGraph3D& g, IntArg from_id, IntArg to_id, py::handle z, py::handle info) {
             const int from = from_id.get("from_id");
             const int to = to_id.get("to_id");
             const Pose3 zv = pose3_arg(z, "measurement");
             const Matrix6d omega = square_matrix_arg(info, "information", 6);
             locked(g, [&] { g.add_pose_edge(from, to, zv, omega); });
           },
           py::arg("from_id"), py::arg("to_id"), py::arg("measurement"), py::arg("information"),
           "Adds a pose-pose edge: measurement (7,) the pose of to_id in from_id's frame, information\n"
           "(6, 6) in the order [x, y, z, rotation vector].")
      .def("add_pose_prior",
           [](PoseGraph3D& g, IntArg id_arg, py::handle z, py::handle info) {
             const int id = id_arg.get("id");
             const Pose3 zv = pose3_arg(z, "measurement");
             const Matrix6d omega = square_matrix_arg(info, "information", 6);
             locked(g, [&] { g.add_pose_prior(id, zv, omega); });
           },
           py::arg("id"), py::arg("measurement"), py::arg("information"),
           "Adds a prior on pose id (g2o's EDGE_SE3_PRIOR): error [t_e, Log(R_e)] of z^-1 x, information\n"
           "(6, 6) in the order [x, y, z, rotation vector]. A vertex with a prior holds its part of the\n"
           "graph as a fixed vertex does (softly): with any prior, optimisers no longer hold the first pose.")
      .def("set_poses",
           [](PoseGraph3D& g, py::handle ids_obj, py::handle poses_obj) {
             const RowsPerId a = rows_per_id(ids_obj, poses_obj, "poses", kPoseWidth);
             std::vector<Pose3> poses;
             for (size_t k = 0; k < a.ids.size(); ++k) poses.push_back(pose_of(a.rows.data() + kPoseWidth * k));
             locked(g, [&] { g.set_poses(a.ids, poses); });
           },
           py::arg("ids"), py::arg("poses"),
           "Replaces the values of pose vertices ids (N,) with poses (N, 7), all or nothing.")
      .def("set_points",
           [](PoseGraph3D& g, py::handle ids_obj, py::handle points_obj) {
             const RowsPerId a = rows_per_id(ids_obj, points_obj, "points", 3);
             std::vector<Eigen::Vector3d> points;
             for (size_t k = 0; k < a.ids.size(); ++k)
               points.emplace_back(Eigen::Map<const Eigen::Vector3d>(a.rows.data() + 3 * k));
             locked(g, [&] { g.set_points(a.ids, points); });
           },
           py::arg("ids"), py::arg("points"),
           "Replaces the values of point vertices ids (N,) with points (N, 3) m, all or nothing.")
      .def_property_readonly("num_points", getter(&PoseGraph3D::num_points), "Number of point vertices.")
      .def_property_readonly(
          "poses", [](const PoseGraph3D& g) { return pose_rows(values_of(g, VertexKind::kPose)); },
          "(P, 7) pose values [x, y, z, qx, qy, qz, qw] in the order of pose_ids, a copy.")
      .def_property_readonly(
          "points",
          [](const PoseGraph3D& g) {
            const std::vector<Pose3> points = values_of(g, VertexKind::kPoint);
            py::array_t<double> out({static_cast<py::ssize_t>(points.size()), py::ssize_t{3}});
            for (size_t k = 0; k < points.size(); ++k)
              Eigen::Map<Eigen::Vector3d>(out.mutable_data() + 3 * k) = points[k].translation;
            return out;
          },
          "(L, 3) point values [x, y, z] m in the order of point_ids, a copy.")
      .def("edge_ids", &all_edge_ids<PoseGraph3D>,
           "(E + M, 2) int64 end ids of every edge, as PoseGraph2D.edge_ids: the pose edges (from, to), then the\n"
           "point edges (pose, point), in the order of edge_chi2.")
      .def("pose_edges",
           [](const PoseGraph3D& g) {
             const auto [ids, edges] =
                 edges_with_ids(g, g.pose_edges(), [](const Pose3Edge& e) { return std::pair{e.from, e.to}; });
             return py::make_tuple(ids, measurements(edges), informations(edges));
           },
           "(ids (E, 2) (from, to), measurements (E, 7), information (E, 6, 6)) of the edges.")
      .def("point_edges",
           [](const PoseGraph3D& g) {
             const auto [ids, edges] =
                 edges_with_ids(g, g.point_edges(), [](const Point3Edge& e) { return std::pair{e.pose, e.point}; });
             const auto n = static_cast<py::ssize_t>(edges.size());
             py::array_t<double> z({n, py::ssize_t{3}}), info({n, py::ssize_t{3}, py::ssize_t{3}}),
                 offsets({n, py::ssize_t{kPoseWidth}});
             for (py::ssize_t k = 0; k < n; ++k) {
               Eigen::Map<Eigen::Vector3d>(z.mutable_data() + 3 * k) = edges[k].measurement;
               Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(info.mutable_data() + 9 * k) = edges[k].information;
               write_pose(edges[k].offset, offsets.mutable_data() + kPoseWidth * k);
             }
             return py::make_tuple(ids, z, info, offsets);
           },
           "(ids (E, 2) (pose, point), measurements (E, 3) m, information (E, 3, 3), offsets (E, 7)) of the\n"
           "point edges.")
      .def_property_readonly("num_pose_priors",
                             [](const PoseGraph3D& g) { return locked(g, [&] { return g.pose_priors().size(); }); },
                             "Number of priors.")
      .def("pose_priors",
           [](const PoseGraph3D& g) {
             std::vector<long> ids;
             const std::vector<Pose3Prior> priors = locked(g, [&] {
               for (const Pose3Prior& p : g.pose_priors()) ids.push_back(g.vertex(p.vertex).id);
               return g.pose_priors();
             });
             const auto n = static_cast<py::ssize_t>(priors.size());
             py::array_t<long> id_array(n);
             std::copy(ids.begin(), ids.end(), id_array.mutable_data());
             return py::make_tuple(id_array, measurements(priors), informations(priors));
           },
           "(ids (P,), measurements (P, 7), information (P, 6, 6)) of the priors.")
      .def("prior_chi2",
           [](const PoseGraph3D& g) { return locked(g, [&] { return Eigen::VectorXd(g.prior_chi2()); }); },
           "(P,) e^T Omega e of each prior at the current values.")
      .def("edge_chi2",
           [](const PoseGraph3D& g) { return locked(g, [&] { return Eigen::VectorXd(g.edge_chi2()); }); },
           "(E,) e^T Omega e of each edge at the current values: pose edges, then point edges.")
      .def("chi2", getter(&PoseGraph3D::chi2),
           "Sum over edges and priors of e^T Omega e at the current values; ValueError if not finite.")
      .def("__repr__", [](py::handle self) {
        const PoseGraph3D& g = self.cast<const PoseGraph3D&>();
        return repr_of(self, locked(g, [&] {
          std::string text = std::to_string(g.num_vertices() - g.num_points()) + " poses, ";
          if (g.num_points() > 0) text += std::to_string(g.num_points()) + " points, ";
          return text + std::to_string(g.pose_edges().size() + g.point_edges().size()) + " edges";
        }));
      });
  define_common_graph_methods(graph_class, "Whether a vertex has this id.");
  define_persistence<PoseGraph3D>(graph_class);
  graph_class.attr("QUATERNION_NORM_TOLERANCE") = kQuaternionNormTolerance;

  m.def("read_pose_graph_3d",
        [](const std::string& path, const std::string& format, const std::string& noise, const std::string& rows) {
          const PoseGraphReadOptions options = read_options(format, noise, rows);
          PoseGraph3DFileRead read;
          {
            py::gil_scoped_release release;  // a new graph: nothing else can see it yet
            read = read_pose_graph_3d_graph(path, options);
          }
          return py::make_tuple(std::move(read.graph), std::move(read.report));
        },
        py::arg("path"), py::arg("format") = "auto", py::arg("noise") = "default", py::arg("rows") = "strict",
        "Reads a 3-D pose graph file (formats and options as probslam.graph.read_pose_graph_3d) into a PoseGraph3D:\n"
        "(PoseGraph3D, PoseGraphReadReport); FIX records fix vertices, EDGE_SE3_PRIOR records are priors,\n"
        "VERTEX_TRACKXYZ / EDGE_SE3_TRACKXYZ points and point edges.");
  m.def("write_g2o_3d",
        [](const std::string& path, ClassArg<PoseGraph3D> graph_arg) {
          const PoseGraph3D& graph = graph_arg.get("graph");
          const PoseGraph3DData data = locked(graph, [&] { return pose_graph_3d_data(graph); });
          py::gil_scoped_release release;
          write_g2o_3d(path, data);
        },
        py::arg("path"), py::arg("graph"),
        "Writes a PoseGraph3D at its current values as g2o text (VERTEX_SE3:QUAT, VERTEX_TRACKXYZ, FIX,\n"
        "EDGE_SE3:QUAT, PARAMS_SE3OFFSET, EDGE_SE3_PRIOR, EDGE_SE3_TRACKXYZ; 17 significant digits).");

  // One optimize / marginals / initialize_odometry each for PoseGraph2D and PoseGraph3D (both classes
  // are defined by now: define_graph runs first).
  def_optimizers(
      m, {"Minimises a PoseGraph2D's or PoseGraph3D's objective in place from its current values and returns\n"
          "an OptimizationReport. Fixed vertices keep their values; with none fixed the first pose is held.\n"
          "options: an OptimizerOptions (None: its defaults); a field given by keyword replaces options'\n"
          "field (max_iterations=5, algorithm=\"levenberg-marquardt\", linear_solver={\"ordering\": \"amd\"}).\n"
          "The fill ordering \"default\" is \"amd\" for a PoseGraph2D and \"metis\" for a PoseGraph3D, the\n"
          "faster on the graphs measured. A 3-D step is on the manifold (x (+) [v, w] = (R Exp(w), t + R v)).\n"
          "callback(iteration, chi2), optional: called after each completed iteration (1 for the first)\n"
          "with the chi2 after it, on the calling thread; returning False stops there (stop_reason \"stopped\n"
          "by the callback\"). An exception it raises (KeyboardInterrupt on Ctrl-C) propagates with the graph\n"
          "at the last completed iteration's values. The callback may read the graph (it holds the values\n"
          "of the iteration just completed); changing it there raises RuntimeError.\n"
          "TypeError naming graph for anything but a PoseGraph2D or PoseGraph3D; TypeError / ValueError\n"
          "naming an option's path (\"linear_solver.ordering\"); ValueError for an empty graph or a part\n"
          "not connected to a fixed vertex.",
          "Marginal covariances at the current values, one per id, from the sparse inverse of the\n"
          "information matrix; a fixed vertex has zero covariance. PoseGraph2D: (3, 3) for a pose (m, m,\n"
          "rad), (2, 2) for a point (m). PoseGraph3D: (6, 6) per pose in its tangent [translation m in its\n"
          "own frame, rotation vector rad] (right perturbation), (3, 3) per point (m, world frame).\n"
          "options: a SparseCholeskyOptions (None: its defaults, the ordering as for optimize), fields by\n"
          "keyword as for optimize. Returns a list of arrays.",
          "Joint marginal covariances at the current values, one per group of vertex ids: the covariance\n"
          "of the group's variables stacked in the order given (PoseGraph2D: 3 per pose, 2 per point;\n"
          "PoseGraph3D: 6 per pose and 3 per point, in the tangent of marginal_covariances),\n"
          "cross-covariances included, from one factorisation (e.g. a landmark pair's (4, 4) for ch.\n"
          "11.6's correspondence test). A fixed vertex's rows and columns are zero. ValueError for an\n"
          "unknown id or a group naming a vertex twice. options as for marginal_covariances. Returns a\n"
          "list of arrays.",
          "Incremental batch optimisation: poses join in the order they were added (each composed from\n"
          "its first edge to an earlier pose, each point with the earliest pose that sees it, placed by\n"
          "that pose's first edge to it), and after every poses_per_step poses the part seen so far (its\n"
          "edges and priors) is optimised with options.step (an OptimizerOptions; from a warm start its\n"
          "defaults stop sooner than optimize's). options: an IncrementalOptions (None: its defaults), fields\n"
          "by keyword as for optimize (poses_per_step=25, step={\"max_iterations\": 3}); errors name the\n"
          "field's path (\"step.kernel\"). Returns an IncrementalReport.",
          "Initial values by composing pose edges outward from the fixed vertices (or the first pose)\n"
          "along a breadth-first spanning tree; then each free point is placed by its first edge from a\n"
          "reached pose (3-D: p = x * offset * z). For an odometry chain this is dead reckoning.\n"
          "Unreached vertices keep their values. PoseGraph2D or PoseGraph3D."});

  {
    py::options signatures;  // the fields' keywords are written from describe(), not **kwargs
    signatures.disable_function_signatures();
    m.def("initialize_chordal",
          [](ClassArg<PoseGraph3D> graph_arg, py::handle options, const py::kwargs& fields) {
            const auto o = options_arg<SparseCholeskyOptions>(options, fields, "initialize_chordal()");
            PoseGraph3D& graph = graph_arg.get("graph");
            locked(graph, [&] { initialize_chordal(graph, o); });
          },
          py::arg("graph"), py::kw_only(), py::arg("options") = py::none(),
          options_signature<SparseCholeskyOptions>("initialize_chordal", "PoseGraph3D", "", "", "None",
        "Chordal initialisation of a PoseGraph3D (Carlone et al. 2015): the rotations from the linear\n"
        "least-squares relaxation of R_to = R_from R_z (each 3x3 then projected onto SO(3)), then the\n"
        "translations by a second linear solve with those rotations; then each free point placed by its\n"
        "first edge (p = x * offset * z). Exact for noise-free edges; the\n"
        "held vertices (fixed, or the first) keep their values. ValueError for a part of the graph not\n"
        "connected to a held vertex. options: the linear solves' SparseCholeskyOptions, fields by keyword\n"
        "as for optimize.").c_str());
  }
}

}  // namespace probslam::bindings
