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
}

}  // namespace probslam::bindings
