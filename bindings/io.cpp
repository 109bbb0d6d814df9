#include <pybind11/stl.h>

#include <cmath>
#include <limits>
#include <sstream>

#include "exceptions.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "pose_graph_options.hpp"
#include "probslam/io/carmen_log.hpp"
#include "probslam/io/pose_graph_file_3d.hpp"
#include "probslam/io/ros_map.hpp"

namespace probslam::bindings {

namespace {

py::dict log_to_dict(CarmenLog&& log) {
  py::dict scans;
  scans["ranges"] = py::cast(std::move(log.scans.ranges));
  scans["laser_poses"] = py::cast(std::move(log.scans.laser_poses));
  scans["robot_poses"] = py::cast(std::move(log.scans.robot_poses));
  scans["start_angles"] = py::cast(std::move(log.scans.start_angles));
  scans["angular_resolutions"] = py::cast(std::move(log.scans.angular_resolutions));
  scans["max_ranges"] = py::cast(std::move(log.scans.max_ranges));
  scans["num_beams"] = py::cast(std::move(log.scans.num_beams));
  scans["timestamps"] = py::cast(std::move(log.scans.timestamps));
  scans["ipc_timestamps"] = py::cast(std::move(log.scans.ipc_timestamps));
  py::dict odometry;
  odometry["poses"] = py::cast(std::move(log.odometry.poses));
  odometry["velocities"] = py::cast(std::move(log.odometry.velocities));
  odometry["timestamps"] = py::cast(std::move(log.odometry.timestamps));
  odometry["ipc_timestamps"] = py::cast(std::move(log.odometry.ipc_timestamps));
  py::dict out;
  out["scans"] = scans;
  out["odometry"] = odometry;
  py::dict params;
  for (const auto& [key, value] : log.params) params[escaped_text(key)] = escaped_text(value);
  out["params"] = params;
  out["skipped_wide_scans"] = log.skipped_wide_scans;
  out["skipped_rows"] = log.skipped_rows;
  py::list lines, reasons;
  for (const SkippedLine& s : log.skipped_lines) {
    lines.append(s.line);
    reasons.append(escaped_text(s.reason));
  }
  out["skipped_lines"] = lines;
  out["skipped_reasons"] = reasons;
  return out;
}

// Quaternions cross to Python as (x, y, z, w) rows: the order of g2o files and of
// scipy.spatial.transform.Rotation.from_quat.
py::dict graph_3d_to_dict(const PoseGraph3DData& g) {
  const auto nv = static_cast<py::ssize_t>(g.vertices.size());
  const auto ne = static_cast<py::ssize_t>(g.edges.size());
  const auto np = static_cast<py::ssize_t>(g.priors.size());
  py::array_t<long> ids(nv), edges({ne, py::ssize_t{2}}), prior_ids(np);
  py::array_t<bool> fixed(nv);
  py::array_t<double> q({nv, py::ssize_t{4}}), t({nv, py::ssize_t{3}}), eq({ne, py::ssize_t{4}}),
      et({ne, py::ssize_t{3}}), info({ne, py::ssize_t{6}, py::ssize_t{6}}), pq({np, py::ssize_t{4}}),
      pt({np, py::ssize_t{3}}), pinfo({np, py::ssize_t{6}, py::ssize_t{6}});
  auto put_pose = [](double* qo, double* to, const Eigen::Quaterniond& qi, const Eigen::Vector3d& ti) {
    qo[0] = qi.x(), qo[1] = qi.y(), qo[2] = qi.z(), qo[3] = qi.w();
    to[0] = ti.x(), to[1] = ti.y(), to[2] = ti.z();
  };
  auto put_information = [](double* out, const Matrix6d& m) {
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) out[6 * i + j] = m(i, j);
  };
  for (py::ssize_t i = 0; i < nv; ++i) {
    const Vertex3D& v = g.vertices[i];
    ids.mutable_data()[i] = v.id;
    fixed.mutable_data()[i] = v.fixed;
    put_pose(q.mutable_data() + 4 * i, t.mutable_data() + 3 * i, v.q, v.t);
  }
  for (py::ssize_t i = 0; i < ne; ++i) {
    const Edge3D& e = g.edges[i];
    edges.mutable_data()[2 * i] = e.from_id;
    edges.mutable_data()[2 * i + 1] = e.to_id;
    put_pose(eq.mutable_data() + 4 * i, et.mutable_data() + 3 * i, e.q, e.t);
    put_information(info.mutable_data() + 36 * i, e.information);
  }
  for (py::ssize_t i = 0; i < np; ++i) {
    const Prior3D& p = g.priors[i];
    prior_ids.mutable_data()[i] = p.id;
    put_pose(pq.mutable_data() + 4 * i, pt.mutable_data() + 3 * i, p.q, p.t);
    put_information(pinfo.mutable_data() + 36 * i, p.information);
  }
  py::dict out;
  out["vertex_ids"] = ids;
  out["quaternions"] = q;
  out["translations"] = t;
  out["fixed"] = fixed;
  out["edges"] = edges;
  out["edge_quaternions"] = eq;
  out["edge_translations"] = et;
  out["information"] = info;
  out["prior_ids"] = prior_ids;
  out["prior_quaternions"] = pq;
  out["prior_translations"] = pt;
  out["prior_information"] = pinfo;
  const auto nl = static_cast<py::ssize_t>(g.points.size());
  const auto nm = static_cast<py::ssize_t>(g.point_edges.size());
  py::array_t<long> point_ids(nl), point_edges({nm, py::ssize_t{2}});
  py::array_t<bool> point_fixed(nl);
  py::array_t<double> points({nl, py::ssize_t{3}}), z({nm, py::ssize_t{3}}),
      zinfo({nm, py::ssize_t{3}, py::ssize_t{3}}), oq({nm, py::ssize_t{4}}), ot({nm, py::ssize_t{3}});
  for (py::ssize_t i = 0; i < nl; ++i) {
    point_ids.mutable_data()[i] = g.points[i].id;
    point_fixed.mutable_data()[i] = g.points[i].fixed;
    Eigen::Map<Eigen::Vector3d>(points.mutable_data() + 3 * i) = g.points[i].p;
  }
  for (py::ssize_t i = 0; i < nm; ++i) {
    const PointEdge3D& e = g.point_edges[i];
    point_edges.mutable_data()[2 * i] = e.pose_id;
    point_edges.mutable_data()[2 * i + 1] = e.point_id;
    Eigen::Map<Eigen::Vector3d>(z.mutable_data() + 3 * i) = e.z;
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(zinfo.mutable_data() + 9 * i) = e.information;
    put_pose(oq.mutable_data() + 4 * i, ot.mutable_data() + 3 * i, e.offset_q, e.offset_t);
  }
  out["point_ids"] = point_ids;
  out["points"] = points;
  out["point_fixed"] = point_fixed;
  out["point_edges"] = point_edges;
  out["point_measurements"] = z;
  out["point_information"] = zinfo;
  out["point_offset_quaternions"] = oq;
  out["point_offset_translations"] = ot;
  return out;
}

// An int array of `rows` entries, or of shape (rows, cols) when cols > 0: ValueError naming it.
py::array_t<long, py::array::c_style | py::array::forcecast> ids_arg(py::handle obj, const char* name, py::ssize_t cols) {
  auto a = py::array_t<long, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a) throw py::type_error(std::string(name) + " must be an array of integers");
  if (cols > 0 ? (a.ndim() != 2 || a.shape(1) != cols) : a.ndim() != 1)
    throw py::value_error(std::string(name) + " must have shape " + (cols > 0 ? "(n, " + std::to_string(cols) + ")" : "(n,)") +
                          ", got " + shape_of(a));
  return a;
}

void require_rows(const py::array& a, py::ssize_t rows, const char* name, const char* of) {
  if (a.shape(0) != rows)
    throw py::value_error(std::string(name) + " has " + std::to_string(a.shape(0)) + " rows, " + of + " has " +
                          std::to_string(rows));
}

int id_value(long id, const char* name) {
  if (id < std::numeric_limits<int>::min() || id > std::numeric_limits<int>::max())
    throw py::value_error(std::string(name) + ": id " + std::to_string(id) + " out of range");
  return static_cast<int>(id);
}

Eigen::Quaterniond quaternion_row(const double* xyzw, const char* name) {
  const Eigen::Quaterniond q(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
  if (!q.coeffs().allFinite() || std::abs(q.norm() - 1.0) > kQuaternionNormTolerance)
    throw py::value_error(std::string(name) + " must hold finite unit quaternions (x, y, z, w)");
  return q;
}

Matrix6d information_block(const double* m, const char* name) {
  const Matrix6d info = Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(m);
  if (!info.allFinite() || info != info.transpose())
    throw py::value_error(std::string(name) + " must hold finite symmetric (6, 6) matrices");
  return info;
}

DoubleArray stack_arg(py::handle obj, const char* name) {
  DoubleArray a = as_array(obj, name);
  if (a.ndim() != 3 || a.shape(1) != 6 || a.shape(2) != 6)
    throw py::value_error(std::string(name) + " must have shape (n, 6, 6), got " + shape_of(a));
  return a;
}

// The pose of each row of one kind (vertices, edges or priors): an (n, 4) quaternion array and an
// (n, 3) translation array, as many rows as `of` has; ValueError naming the array at fault.
class PoseColumns {
 public:
  PoseColumns(const py::dict& d, const char* q_name, const char* t_name, py::ssize_t rows, const char* of)
      : q_(matrix_arg(d[q_name], q_name, 4)), t_(matrix_arg(d[t_name], t_name, 3)), q_name_(q_name), t_name_(t_name) {
    require_rows(q_, rows, q_name, of);
    require_rows(t_, rows, t_name, of);
  }
  void get(py::ssize_t i, Eigen::Quaterniond& q, Eigen::Vector3d& t) const {
    q = quaternion_row(q_.data() + 4 * i, q_name_);
    t = Eigen::Map<const Eigen::Vector3d>(t_.data() + 3 * i);
    if (!t.allFinite()) throw py::value_error(std::string(t_name_) + " must be finite");
  }

 private:
  DoubleArray q_, t_;
  const char* q_name_;
  const char* t_name_;
};

PoseGraph3DData graph_3d_from_arrays(const py::dict& d) {
  PoseGraph3DData g;
  auto ids = ids_arg(d["vertex_ids"], "vertex_ids", 0);
  const py::ssize_t nv = ids.shape(0);
  const PoseColumns poses(d, "quaternions", "translations", nv, "vertex_ids");
  auto fixed = py::array_t<bool, py::array::c_style | py::array::forcecast>::ensure(d["fixed"]);
  if (!fixed || fixed.ndim() != 1) throw py::value_error("fixed must be a 1-D array of booleans");
  require_rows(fixed, nv, "fixed", "vertex_ids");
  for (py::ssize_t i = 0; i < nv; ++i) {
    Vertex3D v;
    v.id = id_value(ids.data()[i], "vertex_ids");
    poses.get(i, v.q, v.t);
    v.fixed = fixed.data()[i];
    g.vertices.push_back(v);
  }
  auto edges = ids_arg(d["edges"], "edges", 2);
  const py::ssize_t ne = edges.shape(0);
  const PoseColumns measurements(d, "edge_quaternions", "edge_translations", ne, "edges");
  const DoubleArray info = stack_arg(d["information"], "information");
  require_rows(info, ne, "information", "edges");
  for (py::ssize_t i = 0; i < ne; ++i) {
    Edge3D e;
    e.from_id = id_value(edges.data()[2 * i], "edges");
    e.to_id = id_value(edges.data()[2 * i + 1], "edges");
    measurements.get(i, e.q, e.t);
    e.information = information_block(info.data() + 36 * i, "information");
    g.edges.push_back(e);
  }
  auto prior_ids = ids_arg(d["prior_ids"], "prior_ids", 0);
  const py::ssize_t np = prior_ids.shape(0);
  const PoseColumns prior_poses(d, "prior_quaternions", "prior_translations", np, "prior_ids");
  const DoubleArray pinfo = stack_arg(d["prior_information"], "prior_information");
  require_rows(pinfo, np, "prior_information", "prior_ids");
  for (py::ssize_t i = 0; i < np; ++i) {
    Prior3D p;
    p.id = id_value(prior_ids.data()[i], "prior_ids");
    prior_poses.get(i, p.q, p.t);
    p.information = information_block(pinfo.data() + 36 * i, "prior_information");
    g.priors.push_back(p);
  }
  if (!d.contains("point_ids")) return g;  // a pose graph without points
  auto point_ids = ids_arg(d["point_ids"], "point_ids", 0);
  const py::ssize_t nl = point_ids.shape(0);
  const DoubleArray points = matrix_arg(d["points"], "points", 3);
  require_rows(points, nl, "points", "point_ids");
  auto point_fixed = py::array_t<bool, py::array::c_style | py::array::forcecast>::ensure(d["point_fixed"]);
  if (!point_fixed || point_fixed.ndim() != 1) throw py::value_error("point_fixed must be a 1-D array of booleans");
  require_rows(point_fixed, nl, "point_fixed", "point_ids");
  for (py::ssize_t i = 0; i < nl; ++i) {
    Point3D p;
    p.id = id_value(point_ids.data()[i], "point_ids");
    p.p = Eigen::Map<const Eigen::Vector3d>(points.data() + 3 * i);
    if (!p.p.allFinite()) throw py::value_error("points must be finite");
    p.fixed = point_fixed.data()[i];
    g.points.push_back(p);
  }
  auto point_edges = ids_arg(d["point_edges"], "point_edges", 2);
  const py::ssize_t nm = point_edges.shape(0);
  const DoubleArray z = matrix_arg(d["point_measurements"], "point_measurements", 3);
  require_rows(z, nm, "point_measurements", "point_edges");
  const PoseColumns offsets(d, "point_offset_quaternions", "point_offset_translations", nm, "point_edges");
  DoubleArray zinfo = as_array(d["point_information"], "point_information");
  if (zinfo.ndim() != 3 || zinfo.shape(1) != 3 || zinfo.shape(2) != 3)
    throw py::value_error("point_information must have shape (n, 3, 3), got " + shape_of(zinfo));
  require_rows(zinfo, nm, "point_information", "point_edges");
  for (py::ssize_t i = 0; i < nm; ++i) {
    PointEdge3D e;
    e.pose_id = id_value(point_edges.data()[2 * i], "point_edges");
    e.point_id = id_value(point_edges.data()[2 * i + 1], "point_edges");
    e.z = Eigen::Map<const Eigen::Vector3d>(z.data() + 3 * i);
    if (!e.z.allFinite()) throw py::value_error("point_measurements must be finite");
    e.information = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(zinfo.data() + 9 * i);
    if (!e.information.allFinite() || e.information != e.information.transpose())
      throw py::value_error("point_information must hold finite symmetric (3, 3) matrices");
    offsets.get(i, e.offset_q, e.offset_t);
    g.point_edges.push_back(e);
  }
  return g;
}

}  // namespace

void define_io(py::module_& m) {
  m.attr("QUATERNION_NORM_TOLERANCE") = kQuaternionNormTolerance;
  m.attr("CARMEN_MAX_REPORTED_LINES") = kCarmenMaxReportedLines;
  m.def(
      "read_carmen_log",
      [](const std::string& path) {
        CarmenLog log;
        {
          py::gil_scoped_release release;
          log = read_carmen_log(path);
        }
        return log_to_dict(std::move(log));
      },
      py::arg("path"),
      "Reads a CARMEN log (FLASER, ROBOTLASER1, ODOM, PARAM lines; .gz read transparently).\n"
      "Returns a dict: scans (ranges (S, B) m, laser_poses and robot_poses (S, 3), start_angles and\nangular_resolutions (S,) rad, max_ranges (S,) m, num_beams (S,), timestamps (S,) s: logger time,\nipc_timestamps (S,) s), odometry (poses (K, 3), velocities (K, 2) (v m/s, w rad/s), timestamps and\nipc_timestamps (K,) s), params\n(PARAM lines, str -> str), skipped_wide_scans, skipped_rows, and the first\nCARMEN_MAX_REPORTED_LINES skipped_lines with their skipped_reasons. probslam.io.read_carmen_log\nwraps it in dataclasses.");
  m.def(
      "parse_carmen_log",
      [](const std::string& text, const std::string& source) {  // text: str or bytes
        CarmenLog log;
        {
          py::gil_scoped_release release;
          std::istringstream in(text);
          log = parse_carmen_log(in, source);
        }
        return log_to_dict(std::move(log));
      },
      py::arg("text"), py::arg("source") = "<text>",
      "As read_carmen_log for the log's text (str or bytes); source names it in error messages.\n"
      "Returns a dict: scans (ranges (S, B) m, laser_poses and robot_poses (S, 3), start_angles and\nangular_resolutions (S,) rad, max_ranges (S,) m, num_beams (S,), timestamps (S,) s: logger time,\nipc_timestamps (S,) s), odometry (poses (K, 3), velocities (K, 2) (v m/s, w rad/s), timestamps and\nipc_timestamps (K,) s), params\n(PARAM lines, str -> str), skipped_wide_scans, skipped_rows, and the first\nCARMEN_MAX_REPORTED_LINES skipped_lines with their skipped_reasons. probslam.io.read_carmen_log\nwraps it in dataclasses.");
  m.def(
      "save_ros_map",
      [](const OccupancyGrid2D& grid, const std::string& yaml_path, double occupied_thresh, double free_thresh) {
        locked(grid, [&] { save_ros_map(grid, yaml_path, {occupied_thresh, free_thresh}); });
      },
      py::arg("grid"), py::arg("yaml_path"), py::arg("occupied_thresh") = 0.65, py::arg("free_thresh") = 0.196,
      "Writes grid as a ROS map_server map: yaml_path and a trinary PGM beside it (same stem):\n"
      "occupied where p > occupied_thresh, free where p < free_thresh, unknown between.");
  m.def(
      "load_ros_map",
      [](const std::string& yaml_path) {
        py::gil_scoped_release release;
        return load_ros_map(yaml_path);
      },
      py::arg("yaml_path"),
      "Reads a ROS map_server map (YAML + PGM; modes trinary and scale) into an OccupancyGrid2D:\n"
      "resolution and origin (m) from the YAML; occupied and free cells get logit(0.971) and\n"
      "logit(0.1192), unknown ones the prior (p = 0.5). Errors name the file and line.");
  m.def(
      "read_pose_graph_3d",
      [](const std::string& path, const std::string& format, const std::string& noise, const std::string& rows) {
        const PoseGraphReadOptions options = read_options(format, noise, rows);
        PoseGraph3DRead read;
        {
          py::gil_scoped_release release;
          read = read_pose_graph_3d(path, options);
        }
        return py::make_tuple(graph_3d_to_dict(read.graph), std::move(read.report));
      },
      py::arg("path"), py::arg("format") = "auto", py::arg("noise") = "default", py::arg("rows") = "strict",
      "Reads a 3-D pose graph: (dict of numpy arrays, PoseGraphReadReport). format: \"g2o\"\n"
      "(VERTEX_SE3:QUAT / EDGE_SE3:QUAT / EDGE_SE3_PRIOR / FIX), \"isam\" (EDGE3 with roll pitch yaw,\n"
      "square-root information by default; VERTEX3), \"toro\" (VERTEX3 / EDGE3, information) or \"auto\".\n"
      "noise and rows as read_pose_graph. Quaternions are rows (x, y, z, w); information (E, 6, 6) in\n"
      "the order [translation, rotation]. g2o's VERTEX_TRACKXYZ / EDGE_SE3_TRACKXYZ give point_ids,\n"
      "points (L, 3), point_fixed, point_edges (M, 2) (pose, point), point_measurements (M, 3),\n"
      "point_information (M, 3, 3) and the sensor offsets point_offset_quaternions (M, 4) and\n"
      "point_offset_translations (M, 3).");
  m.def(
      "write_g2o_3d",
      [](const std::string& path, const py::dict& arrays) {
        const PoseGraph3DData graph = graph_3d_from_arrays(arrays);
        py::gil_scoped_release release;
        write_g2o_3d(path, graph);
      },
      py::arg("path"), py::arg("arrays"),
      "Writes a 3-D graph given as read_pose_graph_3d's dict of arrays to path as g2o text\n"
      "(17 significant digits: it reads back bit for bit).");
}

}  // namespace probslam::bindings
