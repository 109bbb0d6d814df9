// Bindings of the forward beam model (ch. 6.3) and MAP occupancy grid mapping (Table 9.3).
#include <pybind11/stl.h>

#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "numpy.hpp"
#include "object_lock.hpp"
#include "probslam/core/check.hpp"
#include "probslam/grid/beam_sensor_model.hpp"
#include "probslam/grid/binary_map_2d.hpp"
#include "probslam/grid/map_occupancy_mapping.hpp"

namespace probslam::bindings {

namespace {

using BoolArray = py::array_t<std::uint8_t, py::array::c_style>;

// A boolean (or 0/1 integer) array of the grid's shape as row-major bytes; floats are refused
// rather than truncated (0.7 would otherwise read as free).
std::vector<std::uint8_t> occupancy_arg(py::handle obj, const OccupancyGrid2D& grid) {
  py::array raw = obj.is_none() ? py::array() : py::array::ensure(obj);
  if (!raw || !(raw.dtype().kind() == 'b' || raw.dtype().kind() == 'i' || raw.dtype().kind() == 'u'))
    throw py::type_error("occupied must be an array of booleans (or 0/1 integers)");
  if (raw.ndim() != 2 || raw.shape(0) != grid.height() || raw.shape(1) != grid.width())
    throw py::value_error("occupied must have the grid's shape (" + std::to_string(grid.height()) + ", " +
                          std::to_string(grid.width()) + "), got " + shape_of(raw));
  const py::array_t<std::int64_t, py::array::c_style | py::array::forcecast> a(raw);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(a.size()));
  for (py::ssize_t i = 0; i < a.size(); ++i) out[static_cast<std::size_t>(i)] = a.data()[i] != 0;
  return out;
}

// The map argument of the forward model: a BinaryMap2D, or an OccupancyGrid2D thresholded at 0.5.
BinaryMap2D map_arg(py::handle obj) {
  if (py::isinstance<BinaryMap2D>(obj)) return obj.cast<const BinaryMap2D&>();
  if (py::isinstance<OccupancyGrid2D>(obj)) {
    const OccupancyGrid2D& g = obj.cast<const OccupancyGrid2D&>();
    return locked(g, [&] { return BinaryMap2D::thresholded(g); });
  }
  throw py::type_error("map must be a BinaryMap2D or an OccupancyGrid2D");
}

py::array_t<bool> occupancy_array(const std::vector<std::uint8_t>& cells, int height, int width) {
  py::array_t<bool> out({height, width});
  bool* p = out.mutable_data();
  for (std::size_t i = 0; i < cells.size(); ++i) p[i] = cells[i] != 0;
  return out;
}

BeamShape shape_arg(const std::string& shape) {
  if (shape == "laser") return BeamShape::kLaser;
  if (shape == "sonar") return BeamShape::kSonar;
  throw py::value_error("shape must be 'laser' or 'sonar', got '" + shape + "'");
}

// A seed, or a numpy Generator (anything with .integers) from which one is drawn.
std::uint64_t seed_arg(py::handle rng) {
  if (py::isinstance<py::bool_>(rng)) throw py::type_error("rng must be an int seed or a numpy.random.Generator");
  if (py::isinstance<py::int_>(rng)) {
    const py::object value = py::reinterpret_borrow<py::object>(rng);
    if (value < py::int_(0)) throw py::value_error("rng: a seed must be >= 0");
    return (value & py::int_(~std::uint64_t{0})).cast<std::uint64_t>();
  }
  if (py::hasattr(rng, "integers")) return rng.attr("integers")(0, py::int_(std::int64_t{1} << 62)).cast<std::uint64_t>();
  throw py::type_error("rng must be an int seed or a numpy.random.Generator");
}

struct Scans {
  DoubleArray poses, ranges, angles;
};

// poses (T, 3), scans (T, B), beam_angles (B,) or (T, B), checked here for messages that name
// the Python argument; values are checked by the library.
Scans scans_args(py::handle poses, py::handle scans, py::handle beam_angles) {
  Scans s{matrix_arg(poses, "poses", 3), matrix_arg(scans, "scans"), as_array(beam_angles, "beam_angles")};
  if (s.ranges.shape(0) != s.poses.shape(0))
    throw py::value_error("scans must have one row per pose: got " + shape_of(s.ranges) + " for poses " +
                          shape_of(s.poses));
  if (s.angles.ndim() == 1) s.angles = DoubleArray(s.angles.reshape({py::ssize_t{1}, s.angles.shape(0)}));
  else s.angles = matrix_arg(beam_angles, "beam_angles");
  if (s.angles.shape(1) != s.ranges.shape(1) || (s.angles.shape(0) != 1 && s.angles.shape(0) != s.ranges.shape(0)))
    throw py::value_error("beam_angles must have shape (" + std::to_string(s.ranges.shape(1)) + ",) or " +
                          shape_of(s.ranges) + ", got " + shape_of(s.angles));
  return s;
}

// The prior p(m_i = 1): None (the grid's p_prior), a number, or a (height, width) array.
RowMatrixXd prior_arg(py::handle prior, int height, int width, double fallback) {
  if (prior.is_none()) return RowMatrixXd::Constant(height, width, fallback);
  DoubleArray a = as_array(prior, "prior");
  if (a.ndim() == 0) return RowMatrixXd::Constant(height, width, *a.data());
  if (a.ndim() != 2 || a.shape(0) != height || a.shape(1) != width)
    throw py::value_error("prior must be a number or have the grid's shape (" + std::to_string(height) + ", " +
                          std::to_string(width) + "), got " + shape_of(a));
  return as_matrix(a);
}

Eigen::Map<const Poses2> poses_view(const DoubleArray& a) { return {a.data(), a.shape(0), 3}; }

}  // namespace

void define_forward_model(py::module_& m) {
  py::class_<BinaryMap2D>(m, "BinaryMap2D")
      .def(py::init([](const OccupancyGrid2D& grid, py::handle occupied) {
             std::vector<std::uint8_t> cells = occupancy_arg(occupied, grid);  // the shape is fixed for the grid's life
             return locked(grid, [&] { return BinaryMap2D(grid, std::move(cells)); });
           }),
           py::arg("grid"), py::arg("occupied"))
      .def_static("from_grid", [](const OccupancyGrid2D& g) { return locked(g, [&] { return BinaryMap2D::thresholded(g); }); },
                  py::arg("grid"))
      .def_property_readonly("shape", [](const BinaryMap2D& b) { return py::make_tuple(b.height(), b.width()); })
      .def_property_readonly("resolution", [](const BinaryMap2D& b) { return b.lattice().res; })
      .def_property_readonly("origin", [](const BinaryMap2D& b) { return py::make_tuple(b.lattice().x0, b.lattice().y0); })
      .def_property_readonly("occupied", [](const BinaryMap2D& b) { return occupancy_array(b.cells(), b.height(), b.width()); });

  py::class_<BeamSensorModel>(m, "BeamSensorModel")
      .def(py::init([](const std::string& shape, double max_range, double beta, double z_hit, double z_short,
                       double z_max, double z_rand, double sigma_hit, double lambda_short) {
             BeamMixture mix{z_hit, z_short, z_max, z_rand, sigma_hit, lambda_short, max_range};
             return BeamSensorModel(mix, shape_arg(shape), beta);
           }),
           py::arg("shape"), py::arg("max_range"), py::arg("beta") = 0.0, py::arg("z_hit") = 0.85,
           py::arg("z_short") = 0.05, py::arg("z_max") = 0.05, py::arg("z_rand") = 0.05, py::arg("sigma_hit") = 0.05,
           py::arg("lambda_short") = 1.0)
      .def_property_readonly("shape", [](const BeamSensorModel& s) {
        return std::string(s.geometry().shape == BeamShape::kLaser ? "laser" : "sonar");
      })
      .def_property_readonly("max_range", [](const BeamSensorModel& s) { return s.mixture().max_range; })
      .def_property_readonly("beta", [](const BeamSensorModel& s) { return s.geometry().beta; })
      .def_property_readonly("z_hit", [](const BeamSensorModel& s) { return s.mixture().z_hit; })
      .def_property_readonly("z_short", [](const BeamSensorModel& s) { return s.mixture().z_short; })
      .def_property_readonly("z_max", [](const BeamSensorModel& s) { return s.mixture().z_max; })
      .def_property_readonly("z_rand", [](const BeamSensorModel& s) { return s.mixture().z_rand; })
      .def_property_readonly("sigma_hit", [](const BeamSensorModel& s) { return s.mixture().sigma_hit; })
      .def_property_readonly("lambda_short", [](const BeamSensorModel& s) { return s.mixture().lambda_short; })
      .def(
          "probability",
          [](const BeamSensorModel& s, py::handle z, py::handle z_expected) {
            DoubleArray zs = vector_arg(z, "z"), es = vector_arg(z_expected, "z_expected");
            if (zs.shape(0) != es.shape(0)) throw py::value_error("z_expected must have the same length as z");
            require_valid_ranges(as_vector(zs), "z");
            require_all_finite(as_vector(es), "z_expected");
            Eigen::VectorXd out(zs.shape(0));
            for (py::ssize_t k = 0; k < zs.shape(0); ++k) out[k] = s.mixture().probability(zs.data()[k], es.data()[k]);
            return out;
          },
          py::arg("z"), py::arg("z_expected"))
      .def(
          "expected_ranges",
          [](const BeamSensorModel& s, py::handle pose, py::handle beam_angles, py::handle map) {
            const Eigen::Vector3d x = pose_arg(pose);
            DoubleArray a = vector_arg(beam_angles, "beam_angles");
            const BinaryMap2D b = map_arg(map);
            py::gil_scoped_release release;
            return s.expected_ranges(x, as_vector(a), b);
          },
          py::arg("pose"), py::arg("beam_angles"), py::arg("map"))
      .def(
          "log_likelihood",
          [](const BeamSensorModel& s, py::handle ranges, py::handle pose, py::handle beam_angles, py::handle map) {
            DoubleArray z = vector_arg(ranges, "ranges");
            const Eigen::Vector3d x = pose_arg(pose);
            DoubleArray a = vector_arg(beam_angles, "beam_angles");
            if (a.shape(0) != z.shape(0))
              throw py::value_error("beam_angles must have the same length as ranges (" + std::to_string(z.shape(0)) +
                                    "), got " + std::to_string(a.shape(0)));
            const BinaryMap2D b = map_arg(map);
            py::gil_scoped_release release;
            return s.log_likelihoods(as_vector(z), x, as_vector(a), b);
          },
          py::arg("ranges"), py::arg("pose"), py::arg("beam_angles"), py::arg("map"))
      .def(
          "sample",
          [](const BeamSensorModel& s, py::handle pose, py::handle beam_angles, py::handle map, py::handle rng) {
            const Eigen::Vector3d x = pose_arg(pose);
            DoubleArray a = vector_arg(beam_angles, "beam_angles");
            const BinaryMap2D b = map_arg(map);
            std::mt19937_64 engine(seed_arg(rng));
            py::gil_scoped_release release;
            return s.sample(x, as_vector(a), b, engine);
          },
          py::arg("pose"), py::arg("beam_angles"), py::arg("map"), py::arg("rng"));

  m.def(
      "map_occupancy_grid_mapping",
      [](py::handle poses, py::handle scans, py::handle beam_angles, const BeamSensorModel& model,
         const OccupancyGrid2D& grid, py::handle prior, int max_sweeps, const std::string& scoring,
         std::size_t max_evaluations, bool record_trace, bool sensitivity) {
        const Scans s = scans_args(poses, scans, beam_angles);
        MapMappingOptions o;
        o.max_sweeps = max_sweeps;
        if (scoring == "incremental") o.scoring = FlipScoring::kIncremental;
        else if (scoring == "full") o.scoring = FlipScoring::kFull;
        else throw py::value_error("scoring must be 'incremental' or 'full', got '" + scoring + "'");
        o.max_evaluations = max_evaluations;
        o.record_trace = record_trace;
        o.sensitivity = sensitivity;
        const OccupancyGrid2D geometry = locked(grid, [&] { return OccupancyGrid2D(grid); });
        const RowMatrixXd p = prior_arg(prior, geometry.height(), geometry.width(), geometry.p_prior());
        MapMappingResult r;
        {
          py::gil_scoped_release release;
          r = map_occupancy_grid_mapping(geometry, poses_view(s.poses), as_matrix(s.ranges), as_matrix(s.angles), model,
                                         p, o);
        }
        py::dict out;
        out["occupied"] = occupancy_array(r.occupied, geometry.height(), geometry.width());
        if (sensitivity) {
          py::array_t<double> sens({geometry.height(), geometry.width()});
          std::copy(r.sensitivity.begin(), r.sensitivity.end(), sens.mutable_data());
          out["sensitivity"] = sens;
        } else {
          out["sensitivity"] = py::none();
        }
        std::vector<std::uint8_t> in_field(r.occupied.size(), 0);
        for (const std::int32_t c : r.field) in_field[static_cast<std::size_t>(c)] = 1;
        out["field"] = occupancy_array(in_field, geometry.height(), geometry.width());
        out["objective"] = r.objective;
        out["sweeps"] = r.sweeps;
        out["converged"] = r.converged;
        out["flips"] = r.flips;
        out["evaluations"] = r.evaluations;
        out["readings"] = r.readings;
        out["field_cells"] = r.field_cells;
        out["index_entries"] = r.index_entries;
        out["trace_cells"] = py::array_t<std::int32_t>(static_cast<py::ssize_t>(r.trace_cells.size()), r.trace_cells.data());
        out["trace_objective"] =
            py::array_t<double>(static_cast<py::ssize_t>(r.trace_objective.size()), r.trace_objective.data());
        return out;
      },
      py::arg("poses"), py::arg("scans"), py::arg("beam_angles"), py::arg("model"), py::arg("grid"),
      py::arg("prior") = py::none(), py::kw_only(), py::arg("max_sweeps") = 1000, py::arg("scoring") = "incremental",
      py::arg("max_evaluations") = 0, py::arg("record_trace") = false, py::arg("sensitivity") = true);

  m.def(
      "map_log_posterior",
      [](py::handle map, py::handle poses, py::handle scans, py::handle beam_angles, const BeamSensorModel& model,
         py::handle prior) {
        const BinaryMap2D b = map_arg(map);
        const Scans s = scans_args(poses, scans, beam_angles);
        if (prior.is_none()) throw py::type_error("prior must be given: a number or a (height, width) array");
        const RowMatrixXd p = prior_arg(prior, b.height(), b.width(), 0.5);
        py::gil_scoped_release release;
        return map_log_posterior(b, poses_view(s.poses), as_matrix(s.ranges), as_matrix(s.angles), model, p);
      },
      py::arg("map"), py::arg("poses"), py::arg("scans"), py::arg("beam_angles"), py::arg("model"), py::arg("prior"));
}

}  // namespace probslam::bindings
