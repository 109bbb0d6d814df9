#include <cmath>
#include <limits>
#include <string>

#include "numpy.hpp"
#include "probslam/grid/occupancy_grid_3d.hpp"
#include "probslam/io/octomap_bt.hpp"

namespace probslam::bindings {

namespace {

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

/// (n, 3) points as a C-contiguous float32 array: float32 input is used in place, anything
/// else is converted (OctoMap's points are float, so coordinates are rounded to float anyway).
FloatArray points_arg(py::handle obj, const char* name) {
  if (obj.is_none()) throw py::type_error(std::string(name) + " must be an array of numbers, not None");
  FloatArray a = FloatArray::ensure(obj);
  if (!a) throw py::type_error(std::string(name) + " must be an array of numbers");
  if (a.ndim() != 2 || a.shape(1) != 3) {
    std::string shape = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) shape += (i ? ", " : "") + std::to_string(a.shape(i));
    throw py::value_error(std::string(name) + " must have shape (n, 3), got " + shape + (a.ndim() == 1 ? ",)" : ")"));
  }
  return a;
}

/// (n, 3) query points, or one (3,) point (then `single`).
FloatArray query_arg(py::handle obj, bool& single) {
  FloatArray a = FloatArray::ensure(obj);
  single = a && a.ndim() == 1;
  if (single) {
    if (a.shape(0) != 3) throw py::value_error("points must have shape (3,) or (n, 3), got (" + std::to_string(a.shape(0)) + ",)");
    return FloatArray(a.reshape({py::ssize_t{1}, py::ssize_t{3}}));
  }
  return points_arg(obj, "points");
}

/// query(x, y, z) of every point of (n, 3) points as an (n,) array, or a Python scalar for one
/// (3,) point.
template <typename T, class Query>
py::object per_point(py::handle points, Query&& query) {
  bool single = false;
  const FloatArray p = query_arg(points, single);
  const py::ssize_t n = p.shape(0);
  py::array_t<T> out(n);
  T* o = out.mutable_data();
  const float* q = p.data();
  for (py::ssize_t i = 0; i < n; ++i) o[i] = query(q[3 * i], q[3 * i + 1], q[3 * i + 2]);
  if (single) return py::cast(o[0]);
  return std::move(out);
}

py::dict stats_dict(const InsertStats3D& s) {
  py::dict d;
  d["points"] = s.points;
  d["skipped_nonfinite"] = s.skipped_nonfinite;
  d["out_of_bounds"] = s.out_of_bounds;
  d["max_range_cut"] = s.max_range_cut;
  d["voxels_updated"] = s.voxels_updated;
  return d;
}

py::tuple voxels(const OccupancyGrid3D& g, bool occupied_only) {
  const float occ = g.occupancy_log_odds();
  const std::size_t n = occupied_only ? g.num_occupied_voxels() : g.num_known_voxels();
  py::array_t<double> centres({static_cast<py::ssize_t>(n), py::ssize_t{3}});
  py::array_t<float> values(static_cast<py::ssize_t>(n));
  double* c = centres.mutable_data();
  float* v = values.mutable_data();
  {
    py::gil_scoped_release release;
    std::size_t i = 0;
    g.for_each_known([&](const CellKey<3>& k, float l) {
      if (occupied_only && !(l >= occ)) return;
      const Eigen::Vector3d p = g.key_center(k);
      c[3 * i] = p.x(), c[3 * i + 1] = p.y(), c[3 * i + 2] = p.z();
      v[i++] = l;
    });
  }
  return py::make_tuple(centres, values);
}

OccupancyParams3D params_of(double p_hit, double p_miss, double clamp_min, double clamp_max, double threshold) {
  return {p_hit, p_miss, clamp_min, clamp_max, threshold};
}

}  // namespace

void define_grid3d(py::module_& m) {
  using Grid = OccupancyGrid3D;
  py::class_<Grid>(m, "OccupancyGrid3D",
                   "Sparse 3-D occupancy grid (ch. 9.2 in 3-D) updated with OctoMap 1.9.7's\n"
                   "OcTree::insertPointCloud rules: same voxel keys, same float log-odds.")
      .def(py::init([](double resolution, double p_hit, double p_miss, double clamp_min, double clamp_max,
                       double occupancy_threshold) {
             return new Grid(resolution, params_of(p_hit, p_miss, clamp_min, clamp_max, occupancy_threshold));
           }),
           py::arg("resolution"), py::arg("p_hit") = 0.7, py::arg("p_miss") = 0.4, py::arg("clamp_min") = 0.1192,
           py::arg("clamp_max") = 0.971, py::arg("occupancy_threshold") = 0.5,
           "resolution: voxel edge (m). Probabilities: hit and miss of the sensor model, the\n"
           "clamping bounds, and the occupancy threshold (OctoMap's defaults).")
      .def_property_readonly("resolution", &Grid::resolution)
      .def_property_readonly("p_hit", [](const Grid& g) { return g.params().p_hit; })
      .def_property_readonly("p_miss", [](const Grid& g) { return g.params().p_miss; })
      .def_property_readonly("clamp", [](const Grid& g) { return py::make_tuple(g.params().clamp_min, g.params().clamp_max); })
      .def_property_readonly("occupancy_threshold", [](const Grid& g) { return g.params().occupancy_threshold; })
      .def_property_readonly("log_odds_hit", &Grid::hit_log_odds)
      .def_property_readonly("log_odds_miss", &Grid::miss_log_odds)
      .def_property_readonly("log_odds_clamp", [](const Grid& g) {
        return py::make_tuple(g.clamp_min_log_odds(), g.clamp_max_log_odds());
      })
      .def_property_readonly("num_known_voxels", &Grid::num_known_voxels)
      .def_property_readonly("num_occupied_voxels", &Grid::num_occupied_voxels)
      .def_property_readonly("num_blocks", &Grid::num_blocks)
      .def_property_readonly("memory_bytes", &Grid::memory_bytes)
      .def(
          "insert_point_cloud",
          [](Grid& g, py::handle points, py::handle origin, double max_range, int threads) {
            const FloatArray p = points_arg(points, "points");
            const Eigen::Vector3d o = fixed_vector<3>(origin, "origin");
            const float of[3] = {static_cast<float>(o.x()), static_cast<float>(o.y()), static_cast<float>(o.z())};
            InsertStats3D s;
            {
              py::gil_scoped_release release;
              s = g.insert_point_cloud(p.data(), static_cast<std::size_t>(p.shape(0)), of, max_range, threads);
            }
            return stats_dict(s);
          },
          py::arg("points"), py::arg("origin"), py::arg("max_range") = -1.0, py::arg("threads") = 1,
          "One scan: points (n, 3) m and the sensor origin (3,) m in the map frame, both rounded to\n"
          "float32. Points within max_range (m; < 0: unlimited) clear their ray and hit their voxel;\n"
          "farther ones clear the ray up to max_range only. Each voxel changes at most once per\n"
          "scan, a hit beating a miss. NaN/inf points are skipped and counted. threads > 1 walks the\n"
          "rays concurrently with an identical result. Returns a dict of counts.")
      .def(
          "log_odds_at",
          [](const Grid& g, py::handle points) {
            return per_point<float>(points, [&](float x, float y, float z) { return g.log_odds_at(x, y, z); });
          },
          py::arg("points"), "Log-odds (float32) of the voxels holding points (n, 3) or (3,); NaN where unknown.")
      .def(
          "is_occupied",
          [](const Grid& g, py::handle points) {
            return per_point<bool>(points, [&](float x, float y, float z) { return g.is_occupied(x, y, z); });
          },
          py::arg("points"), "Known and log-odds >= logit(occupancy_threshold); unknown is False.")
      .def(
          "cast_ray",
          [](const Grid& g, py::handle origin, py::handle direction, double max_range) -> py::object {
            const auto hit = g.cast_ray(fixed_vector<3>(origin, "origin"), fixed_vector<3>(direction, "direction"), max_range);
            if (!hit) return py::none();
            return py::cast(Eigen::Vector3d(*hit));
          },
          py::arg("origin"), py::arg("direction"), py::arg("max_range"),
          "Centre (3,) of the first occupied voxel along the ray within max_range (m), or None.\n"
          "Unknown voxels are passed through.")
      .def("known_voxels", [](const Grid& g) { return voxels(g, false); },
           "(centres (n, 3) m, log_odds (n,) float32) of every known voxel.")
      .def("occupied_voxels", [](const Grid& g) { return voxels(g, true); },
           "(centres (n, 3) m, log_odds (n,) float32) of the occupied voxels.")
      .def(
          "project_2d", [](const Grid& g, double z_min, double z_max) { return g.project_2d(z_min, z_max); },
          py::arg("z_min") = -std::numeric_limits<double>::max(), py::arg("z_max") = std::numeric_limits<double>::max(),
          "OccupancyGrid2D on the same x-y lattice: per column the largest log-odds of the known\n"
          "voxels with centre z in [z_min, z_max] (eq. 9.9); unobserved columns hold 0.")
      .def(
          "write_bt",
          [](const Grid& g, const std::string& path) {
            py::gil_scoped_release release;
            return write_octomap_bt(g, path);
          },
          py::arg("path"),
          "Writes an OctoMap .bt file (maximum-likelihood: occupied or free per voxel). Returns the\n"
          "number of tree nodes.")
      .def_static(
          "read_bt",
          [](const std::string& path, double p_hit, double p_miss, double clamp_min, double clamp_max,
             double occupancy_threshold) {
            const OccupancyParams3D params = params_of(p_hit, p_miss, clamp_min, clamp_max, occupancy_threshold);
            py::gil_scoped_release release;
            return new Grid(read_octomap_bt(path, params));
          },
          py::arg("path"), py::arg("p_hit") = 0.7, py::arg("p_miss") = 0.4, py::arg("clamp_min") = 0.1192,
          py::arg("clamp_max") = 0.971, py::arg("occupancy_threshold") = 0.5,
          "Reads an OctoMap .bt file (OcTree). The format stores occupancy only: voxels get the\n"
          "clamped log-odds logit(clamp_max) or logit(clamp_min). Raises ValueError on a bad file.")
      .def("clear", &Grid::clear)
      .def("__repr__", [](const Grid& g) {
        return "OccupancyGrid3D(resolution=" + std::to_string(g.resolution()) +
               ", known_voxels=" + std::to_string(g.num_known_voxels()) + ")";
      });
}

}  // namespace probslam::bindings
