#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <pybind11/stl/filesystem.h>

#include "args.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "persistence.hpp"
#include "repr.hpp"
#include "probslam/core/check.hpp"
#include "probslam/grid/occupancy_grid_3d.hpp"
#include "probslam/core/worker_pool.hpp"
#include "probslam/io/octomap_bt.hpp"

namespace probslam::bindings {

namespace {

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;
constexpr double kFloatMax = std::numeric_limits<float>::max();

/// Finite doubles beyond float range become +-FLT_MAX (a far point, outside the key range)
/// rather than inf (which would read as "no return"); NaN and inf stay as they are.
float to_float(double v) { return static_cast<float>(std::isfinite(v) ? std::min(std::max(v, -kFloatMax), kFloatMax) : v); }

/// (n, 3) float32 copy of d's values (d holds 3n of them), through to_float.
FloatArray float_points(const DoubleArray& d) {
  FloatArray f({d.size() / 3, py::ssize_t{3}});
  std::transform(d.data(), d.data() + d.size(), f.mutable_data(), to_float);
  return f;
}

/// (n, 3) points as a C-contiguous float32 array: float32 input is used in place, anything
/// else is converted (OctoMap's points are float, so coordinates are rounded to float anyway).
FloatArray points_arg(py::handle obj, const char* name) {
  if (obj.is_none()) throw py::type_error(std::string(name) + " must be an array of numbers, not None");
  if (is_complex(obj)) throw py::type_error(std::string(name) + " must hold real numbers, got complex values");
  const bool is_float32 = py::isinstance<py::array_t<float>>(obj);
  const DoubleArray d = is_float32 ? DoubleArray() : DoubleArray::ensure(obj);
  const FloatArray a = is_float32 ? FloatArray::ensure(obj) : FloatArray();
  if (!is_float32 && !d) throw py::type_error(std::string(name) + " must be an array of numbers");
  const py::array& any = is_float32 ? static_cast<const py::array&>(a) : static_cast<const py::array&>(d);
  if (any.ndim() != 2 || any.shape(1) != 3)
    throw py::value_error(std::string(name) + " must have shape (n, 3), got " + shape_of(any));
  return is_float32 ? a : float_points(d);
}

/// (n, 3) query points, or one (3,) point (then `single`), as float32 (the grid's point type).
/// NaN and infinite coordinates are refused (checked before the cast, so that a finite double
/// beyond float range becomes a far point, outside the key range, rather than an error).
FloatArray query_arg(py::handle obj, bool& single) {
  if (obj.is_none()) throw py::type_error("points must be an array of numbers, not None");
  if (is_complex(obj)) throw py::type_error("points must hold real numbers, got complex values");
  DoubleArray d = DoubleArray::ensure(obj);
  if (!d) throw py::type_error("points must be an array of numbers");
  single = d.ndim() == 1;
  if (single && d.shape(0) != 3)
    throw py::value_error("points must have shape (3,) or (n, 3), got " + shape_of(d));
  if (!single && (d.ndim() != 2 || d.shape(1) != 3))
    throw py::value_error("points must have shape (3,) or (n, 3), got " + shape_of(d));
  if (!ConstVectorMap(d.data(), d.size()).allFinite())
    throw py::value_error("points must contain only finite values");
  return float_points(d);
}

/// query(x, y, z) of every point of (n, 3) points as an (n,) array, or a Python scalar for one
/// (3,) point; run under the grid's lock with the GIL released.
template <typename T, class Query>
py::object per_point(const OccupancyGrid3D& g, py::handle points, Query&& query) {
  bool single = false;
  const FloatArray p = query_arg(points, single);
  const py::ssize_t n = p.shape(0);
  py::array_t<T> out(n);
  T* o = out.mutable_data();
  const float* q = p.data();
  locked(g, [&] {
    for (py::ssize_t i = 0; i < n; ++i) o[i] = query(q[3 * i], q[3 * i + 1], q[3 * i + 2]);
  });
  if (single) return py::cast(o[0]);
  return std::move(out);
}

py::tuple voxels(const OccupancyGrid3D& g, bool occupied_only) {
  // Collected under the lock (the count and the walk must see the same map), copied out after.
  std::vector<double> c;
  std::vector<float> v;
  locked(g, [&] {
    const float occ = g.occupancy_log_odds();
    const std::size_t n = occupied_only ? g.num_occupied_voxels() : g.num_known_voxels();
    c.reserve(3 * n);
    v.reserve(n);
    g.for_each_known([&](const CellKey<3>& k, float l) {
      if (occupied_only && !(l >= occ)) return;
      const Eigen::Vector3d p = g.key_center(k);
      c.insert(c.end(), {p.x(), p.y(), p.z()});
      v.push_back(l);
    });
  });
  const auto n = static_cast<py::ssize_t>(v.size());
  py::array_t<double> centres({n, py::ssize_t{3}});
  py::array_t<float> values(n);
  std::copy(c.begin(), c.end(), centres.mutable_data());
  std::copy(v.begin(), v.end(), values.mutable_data());
  return py::make_tuple(centres, values);
}

/// The sensor model's probabilities, with clamp = (p_min, p_max) as OccupancyGrid2D takes it.
OccupancyParams3D params_of(double p_hit, double p_miss, py::handle clamp, double occupancy_threshold) {
  const Eigen::Vector2d c = fixed_vector<2>(clamp, "clamp");
  require_probability(c[0], "clamp");
  require_probability(c[1], "clamp");
  require(c[0] < c[1], "clamp", "must be (p_min, p_max) with p_min < p_max");
  return {p_hit, p_miss, c[0], c[1], occupancy_threshold};
}

}  // namespace

void define_grid3d(py::module_& m) {
  using Grid = OccupancyGrid3D;
  m.def(
      "_fail_worker_thread_start_after", [](int successes) { testing::worker_start_failure_after.store(successes); },
      py::arg("successes"),
      "Test hook: after `successes` more worker-thread starts the next one fails as if the system\n"
      "refused it (std::system_error -> RuntimeError); negative turns it off.");
  py::class_<InsertStats3D>(m, "InsertStats3D", "What one OccupancyGrid3D.insert_point_cloud did with its points.")
      .def_readonly("points", &InsertStats3D::points, "Points given.")
      .def_readonly("skipped_nonfinite", &InsertStats3D::skipped_nonfinite,
                    "Points with a NaN or infinite coordinate: left out entirely.")
      .def_readonly("out_of_bounds", &InsertStats3D::out_of_bounds,
                    "Points whose end (or max-range cut) voxel lies outside OctoMap's key range.")
      .def_readonly("max_range_cut", &InsertStats3D::max_range_cut,
                    "Points beyond max_range: they only clear their ray, up to max_range.")
      .def_readonly("voxels_updated", &InsertStats3D::voxels_updated, "Voxels this scan changed (each at most once).")
      .def("__repr__", [](py::handle self) {
        const InsertStats3D& s = self.cast<const InsertStats3D&>();
        return repr_of(self, std::to_string(s.points) + " points, " + std::to_string(s.voxels_updated) +
                                 " voxels updated, " + std::to_string(s.skipped_nonfinite) + " non-finite, " +
                                 std::to_string(s.out_of_bounds) + " out of bounds, " + std::to_string(s.max_range_cut) +
                                 " cut at max_range");
      });
  const OccupancyParams3D d;  // the sensor model's defaults (OctoMap's)
  auto grid_class = py::class_<Grid>(m, "OccupancyGrid3D",
                   "Sparse 3-D occupancy grid (ch. 9.2 in 3-D) updated with OctoMap 1.9.7's\n"
                   "OcTree::insertPointCloud rules: same voxel keys, same float log-odds.")
      .def(py::init([](double resolution, double p_hit, double p_miss, py::handle clamp, double occupancy_threshold) {
             return new Grid(resolution, params_of(p_hit, p_miss, clamp, occupancy_threshold));
           }),
           py::arg("resolution"), py::arg("p_hit") = d.p_hit, py::arg("p_miss") = d.p_miss,
           py::arg("clamp") = py::make_tuple(d.clamp_min, d.clamp_max), py::arg("occupancy_threshold") = d.occupancy_threshold,
           "resolution: voxel edge (m). Probabilities: hit and miss of the sensor model, clamp (p_min,\n"
           "p_max) the bounds the log-odds are clamped to, and the occupancy threshold (OctoMap's\n"
           "defaults).")
      .def_property_readonly("resolution", getter(&Grid::resolution), "Voxel edge, metres.")
      .def_property_readonly("p_hit", [](const Grid& g) { return locked(g, [&] { return g.params().p_hit; }); },
                             "Occupancy probability of the voxel holding an end point.")
      .def_property_readonly("p_miss", [](const Grid& g) { return locked(g, [&] { return g.params().p_miss; }); },
                             "Occupancy probability of the voxels a ray passes through.")
      .def_property_readonly("clamp", [](const Grid& g) {
        const OccupancyParams3D p = locked(g, [&] { return g.params(); });
        return py::make_tuple(p.clamp_min, p.clamp_max);
      }, "(p_min, p_max) probabilities the log-odds are clamped to.")
      .def_property_readonly("occupancy_threshold",
                             [](const Grid& g) { return locked(g, [&] { return g.params().occupancy_threshold; }); },
                             "Probability at or above which a known voxel is occupied.")
      .def_property_readonly("log_odds_hit", getter(&Grid::hit_log_odds), "float32 logit(p_hit), added per hit.")
      .def_property_readonly("log_odds_miss", getter(&Grid::miss_log_odds), "float32 logit(p_miss), added per miss.")
      .def_property_readonly("log_odds_clamp", [](const Grid& g) {
        const auto [lo, hi] = locked(g, [&] { return std::make_pair(g.clamp_min_log_odds(), g.clamp_max_log_odds()); });
        return py::make_tuple(lo, hi);
      }, "(min, max) float32 log-odds of the clamp.")
      .def_property_readonly("num_known_voxels", getter(&Grid::num_known_voxels), "Voxels updated at least once.")
      .def_property_readonly("num_occupied_voxels", getter(&Grid::num_occupied_voxels),
                             "Known voxels with log-odds >= logit(occupancy_threshold).")
      .def_property_readonly("num_blocks", getter(&Grid::num_blocks), "Allocated 8 x 8 x 8-voxel blocks.")
      .def_property_readonly("memory_bytes", getter(&Grid::memory_bytes), "Bytes held by the map's blocks and hash table.")
      .def(
          "insert_point_cloud",
          [](Grid& g, py::handle points, py::handle origin, double max_range, IntArg threads_arg) {
            const int threads = threads_arg.get("threads");
            const FloatArray p = points_arg(points, "points");
            const Eigen::Vector3d o = fixed_vector<3>(origin, "origin");
            if (!o.allFinite()) throw py::value_error("origin must contain only finite values");
            const float of[3] = {to_float(o.x()), to_float(o.y()), to_float(o.z())};
            const InsertStats3D s = locked(g, [&] {
              return g.insert_point_cloud(p.data(), static_cast<std::size_t>(p.shape(0)), of, max_range, threads);
            });
            return s;
          },
          py::arg("points"), py::arg("origin"), py::arg("max_range") = -1.0, py::arg("threads") = 1,
          "One scan: points (n, 3) m and the sensor origin (3,) m in the map frame, both rounded to\n"
          "float32. Points within max_range (m; < 0: unlimited) clear their ray and hit their voxel;\n"
          "farther ones clear the ray up to max_range only. Each voxel changes at most once per\n"
          "scan, a hit beating a miss. NaN/inf points are skipped and counted. threads > 1 walks the\n"
          "rays concurrently with an identical result. Returns an InsertStats3D of counts.")
      .def(
          "log_odds_at",
          [](const Grid& g, py::handle points) {
            return per_point<float>(g, points, [&](float x, float y, float z) { return g.log_odds_at(x, y, z); });
          },
          py::arg("points"), "Log-odds (float32) of the voxels holding points (n, 3) or (3,); NaN where unknown.")
      .def(
          "is_occupied",
          [](const Grid& g, py::handle points) {
            return per_point<bool>(g, points, [&](float x, float y, float z) { return g.is_occupied(x, y, z); });
          },
          py::arg("points"), "Known and log-odds >= logit(occupancy_threshold); unknown is False.")
      .def(
          "cast_ray",
          [](const Grid& g, py::handle origin, py::handle direction, double max_range) -> py::object {
            const Eigen::Vector3d o = fixed_vector<3>(origin, "origin"), d = fixed_vector<3>(direction, "direction");
            const auto hit = locked(g, [&] { return g.cast_ray(o, d, max_range); });
            if (!hit) return py::none();
            return py::cast(Eigen::Vector3d(*hit));
          },
          py::arg("origin"), py::arg("direction"), py::arg("max_range"),
          "Centre (3,) of the first occupied voxel along the ray within max_range (m), or None.\n"
          "Unknown voxels are passed through. The walk is clipped to the key range first.")
      .def("known_voxels", [](const Grid& g) { return voxels(g, false); },
           "(centres (n, 3) m, log_odds (n,) float32) of every known voxel.")
      .def("occupied_voxels", [](const Grid& g) { return voxels(g, true); },
           "(centres (n, 3) m, log_odds (n,) float32) of the occupied voxels.")
      .def(
          "project_2d",
          [](const Grid& g, double z_min, double z_max) { return locked(g, [&] { return g.project_2d(z_min, z_max); }); },
          py::arg("z_min") = -std::numeric_limits<double>::max(), py::arg("z_max") = std::numeric_limits<double>::max(),
          "OccupancyGrid2D on the same x-y lattice: per column the largest log-odds of the known\n"
          "voxels with centre z in [z_min, z_max] (eq. 9.9); unobserved columns hold 0.")
      .def(
          "write_bt",
          [](const Grid& g, py::handle path_arg) {
            const std::string path = path_argument(path_arg);
            return locked(g, [&] { return write_octomap_bt(g, path); });
          },
          py::arg("path"),
          "Writes an OctoMap .bt file (maximum-likelihood: occupied or free per voxel). Returns the\n"
          "number of tree nodes.")
      .def_static(
          "read_bt",
          [](py::handle path_arg, RealArg p_hit, RealArg p_miss, py::handle clamp, RealArg occupancy_threshold) {
            const std::string path = path_argument(path_arg);
            const OccupancyParams3D params = params_of(p_hit.get("p_hit"), p_miss.get("p_miss"), clamp,
                                                       occupancy_threshold.get("occupancy_threshold"));
            py::gil_scoped_release release;
            return new Grid(read_octomap_bt(path, params));
          },
          py::arg("path"), py::arg("p_hit") = d.p_hit, py::arg("p_miss") = d.p_miss,
          py::arg("clamp") = py::make_tuple(d.clamp_min, d.clamp_max), py::arg("occupancy_threshold") = d.occupancy_threshold,
          "Reads an OctoMap .bt file (OcTree). The format stores occupancy only: voxels get the\n"
          "clamped log-odds logit(p_max) or logit(p_min) of clamp. A missing file raises FileNotFoundError,\n"
          "a malformed one ValueError.")
      .def("clear", [](Grid& g) { locked(g, [&] { g.clear(); }); }, "Forgets every voxel (all unknown again).")
      // The grid holds a block pool it does not share: a copy goes through its state bytes.
      .def("copy", [](const Grid& g) {
        const std::string bytes = locked(g, [&] { return state_bytes(g); });
        return object_from_state<Grid>(bytes, "OccupancyGrid3D copy");
      }, "An independent deep copy.")
      .def("__repr__", [](py::handle self) {
        const Grid& g = self.cast<const Grid&>();
        return repr_of(self, locked(g, [&] {
          return num(g.resolution()) + " m voxels, " + std::to_string(g.num_known_voxels()) + " known, " +
                 std::to_string(g.num_occupied_voxels()) + " occupied, " + std::to_string(g.num_blocks()) + " blocks";
        }));
      });
  define_persistence<Grid>(grid_class);
}

}  // namespace probslam::bindings
