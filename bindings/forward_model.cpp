// Bindings of the forward beam model (ch. 6.3) and MAP occupancy grid mapping (Table 9.3).
#include <pybind11/stl.h>

#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "interrupt.hpp"
#include "args.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "repr.hpp"
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
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    const std::int64_t v = a.data()[i];
    // 2 or -1 is no occupancy: reading it as "occupied" would hide a wrong array (a label map).
    if (v != 0 && v != 1)
      throw py::value_error("occupied must hold only 0 and 1 (or booleans), got " + std::to_string(v));
    out[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v);
  }
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
  py::class_<BinaryMap2D>(m, "BinaryMap2D",
                          "A binary occupancy map on an OccupancyGrid2D's lattice (what forward models see).")
      .def(py::init([](ClassArg<OccupancyGrid2D> grid_arg, py::handle occupied) {
             const OccupancyGrid2D& grid = grid_arg.get("grid");
             std::vector<std::uint8_t> cells = occupancy_arg(occupied, grid);  // the shape is fixed for the grid's life
             return locked(grid, [&] { return BinaryMap2D(grid, std::move(cells)); });
           }),
           py::arg("grid"), py::arg("occupied"),
           "grid's geometry with occupied (height, width) bool (or 0/1 integers; floats: TypeError).")
      .def_static("from_grid",
                  [](ClassArg<OccupancyGrid2D> grid) {
                    const OccupancyGrid2D& g = grid.get("grid");
                    return locked(g, [&] { return BinaryMap2D::thresholded(g); });
                  },
                  py::arg("grid"), "grid thresholded: occupied iff p > 0.5 (log-odds > 0).")
      .def_property_readonly("shape", [](const BinaryMap2D& b) { return py::make_tuple(b.height(), b.width()); },
                             "(height, width) in cells.")
      .def_property_readonly("resolution", [](const BinaryMap2D& b) { return b.lattice().res; }, "Cell side, metres.")
      .def_property_readonly("origin", [](const BinaryMap2D& b) { return py::make_tuple(b.lattice().x0, b.lattice().y0); },
                             "(x0, y0) metres of cell (0, 0)'s lower-left corner.")
      .def_property_readonly("occupied", [](const BinaryMap2D& b) { return occupancy_array(b.cells(), b.height(), b.width()); },
                             "(height, width) bool array, a copy.")
      .def("__repr__", [](py::handle self) {
        const BinaryMap2D& b = self.cast<const BinaryMap2D&>();
        std::size_t occupied = 0;
        for (const std::uint8_t c : b.cells()) occupied += c != 0;
        return repr_of(self, std::to_string(b.width()) + " x " + std::to_string(b.height()) + " cells of " +
                                 num(b.lattice().res) + " m, " + std::to_string(occupied) + " occupied");
      });

  py::class_<BeamSensorModel>(m, "BeamSensorModel",
                              "Beam-based forward model p(z | x, m) of a range finder (ch. 6.3, Table 6.1): z_hit *\n"
                              "truncated N(z*, sigma_hit^2) on [0, max_range] + z_short * truncated exponential\n"
                              "(lambda_short) on [0, z*] + z_max * [z >= max_range] + z_rand / max_range, z* the\n"
                              "expected range on a binary map (\"laser\": where the ray enters the first occupied\n"
                              "cell; \"sonar\": the nearest occupied cell centre within beta / 2 of the beam). z_max\n"
                              "is the *weight* of max readings; the range limit is max_range (m). Weights >= 0 sum\n"
                              "to 1; sigma_hit (m), lambda_short (1/m), max_range (m) > 0; beta (rad) in (0, 2 pi]\n"
                              "for a sonar. Maps: BinaryMap2D or OccupancyGrid2D (thresholded at p > 0.5).")
      .def(py::init([](StrArg shape, RealArg max_range, RealArg beta, RealArg z_hit, RealArg z_short, RealArg z_max,
                       RealArg z_rand, RealArg sigma_hit, RealArg lambda_short) {
             BeamMixture mix{z_hit.get("z_hit"),         z_short.get("z_short"),       z_max.get("z_max"),
                             z_rand.get("z_rand"),       sigma_hit.get("sigma_hit"),   lambda_short.get("lambda_short"),
                             max_range.get("max_range")};
             return BeamSensorModel(mix, shape_arg(shape.get("shape")), beta.get("beta"));
           }),
           py::arg("shape"), py::arg("max_range"), py::arg("beta") = 0.0, py::arg("z_hit") = 0.85,
           py::arg("z_short") = 0.05, py::arg("z_max") = 0.05, py::arg("z_rand") = 0.05, py::arg("sigma_hit") = 0.05,
           py::arg("lambda_short") = 1.0,
           "shape: \"laser\" or \"sonar\"; max_range m; beta: sonar cone width rad; mixture weights;\n"
           "sigma_hit m; lambda_short 1/m. ValueError naming the parameter when one is out of range.")
      .def_property_readonly("shape", [](const BeamSensorModel& s) {
        return std::string(s.geometry().shape == BeamShape::kLaser ? "laser" : "sonar");
      }, "\"laser\" or \"sonar\".")
      .def_property_readonly("max_range", [](const BeamSensorModel& s) { return s.mixture().max_range; },
                             "Range limit, metres (readings >= it are max readings).")
      .def_property_readonly("beta", [](const BeamSensorModel& s) { return s.geometry().beta; },
                             "Sonar cone width, radians (0 for a laser).")
      .def_property_readonly("z_hit", [](const BeamSensorModel& s) { return s.mixture().z_hit; },
                             "Weight of the Gaussian hit component.")
      .def_property_readonly("z_short", [](const BeamSensorModel& s) { return s.mixture().z_short; },
                             "Weight of the exponential short-reading component.")
      .def_property_readonly("z_max", [](const BeamSensorModel& s) { return s.mixture().z_max; },
                             "Weight of the max-reading component (not a range).")
      .def_property_readonly("z_rand", [](const BeamSensorModel& s) { return s.mixture().z_rand; },
                             "Weight of the uniform random component.")
      .def_property_readonly("sigma_hit", [](const BeamSensorModel& s) { return s.mixture().sigma_hit; },
                             "Standard deviation of the hit component, metres.")
      .def_property_readonly("lambda_short", [](const BeamSensorModel& s) { return s.mixture().lambda_short; },
                             "Rate of the short-reading exponential, 1/metres.")
      .def("__repr__", [](py::handle self) {
        const BeamSensorModel& s = self.cast<const BeamSensorModel&>();
        const BeamMixture& b = s.mixture();
        std::string body = std::string(s.geometry().shape == BeamShape::kLaser ? "laser" : "sonar") + ", max_range " +
                           num(b.max_range) + " m";
        if (s.geometry().shape == BeamShape::kSonar) body += ", beta " + num(s.geometry().beta) + " rad";
        return repr_of(self, body + ", z_hit " + num(b.z_hit) + ", z_short " + num(b.z_short) + ", z_max " +
                                 num(b.z_max) + ", z_rand " + num(b.z_rand) + ", sigma_hit " + num(b.sigma_hit) +
                                 " m, lambda_short " + num(b.lambda_short) + " 1/m");
      })
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
          py::arg("z"), py::arg("z_expected"),
          "Eq. 6.12 for readings z (n,) m given expected ranges z_expected (n,) m: densities per metre,\n"
          "plus the max-reading indicator's weight (eq. 6.10) where z >= max_range.")
      .def(
          "expected_ranges",
          [](const BeamSensorModel& s, py::handle pose, py::handle beam_angles, py::handle map) {
            const Eigen::Vector3d x = pose_arg(pose);
            DoubleArray a = vector_arg(beam_angles, "beam_angles");
            const BinaryMap2D b = map_arg(map);
            py::gil_scoped_release release;
            return s.expected_ranges(x, as_vector(a), b);
          },
          py::arg("pose"), py::arg("beam_angles"), py::arg("map"),
          "Expected ranges z* (B,) m of each beam from pose (3,) at beam_angles (B,) rad relative to the\n"
          "heading, on map (BinaryMap2D or OccupancyGrid2D).")
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
          py::arg("ranges"), py::arg("pose"), py::arg("beam_angles"), py::arg("map"),
          "log p(z_k | x, m) (B,) per beam, nats. ranges (B,) m (>= 0, no NaN: ValueError; inf is a max\n"
          "reading), pose (3,), beam_angles (B,) rad.")
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
          py::arg("pose"), py::arg("beam_angles"), py::arg("map"), py::arg("rng"),
          "One reading (B,) m per beam drawn from p(z | x, m); pose (3,), beam_angles (B,) rad; rng: a\n"
          "seed >= 0 or a numpy.random.Generator.");

  m.def(
      "map_occupancy_grid_mapping",
      [](py::handle poses, py::handle scans, py::handle beam_angles, ClassArg<BeamSensorModel> model_arg,
         ClassArg<OccupancyGrid2D> grid_arg, py::handle prior, IntArg max_sweeps_arg, const std::string& scoring,
         std::size_t max_evaluations, bool record_trace, bool sensitivity) {
        const BeamSensorModel& model = model_arg.get("model");
        const OccupancyGrid2D& grid = grid_arg.get("grid");
        const int max_sweeps = max_sweeps_arg.get("max_sweeps");
        const Scans s = scans_args(poses, scans, beam_angles);
        MapMappingOptions o;
        o.max_sweeps = max_sweeps;
        if (scoring == "incremental") o.scoring = FlipScoring::kIncremental;
        else if (scoring == "full") o.scoring = FlipScoring::kFull;
        else throw py::value_error("scoring must be 'incremental' or 'full', got '" + scoring + "'");
        o.max_evaluations = max_evaluations;
        o.record_trace = record_trace;
        o.sensitivity = sensitivity;
        o.interrupt = python_interrupt();
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
      py::arg("max_evaluations") = 0, py::arg("record_trace") = false, py::arg("sensitivity") = true,
      "Table 9.3, MAP occupancy grid mapping by coordinate ascent over binary maps on grid's lattice.\n"
      "poses (T, 3), scans (T, B) m, beam_angles (B,) or (T, B) rad; prior: None (grid.p_prior), a\n"
      "probability or (H, W) probabilities. Returns a dict: occupied, field (H, W) bool, sensitivity\n"
      "(H, W) nats or None, objective (nats), sweeps, converged, flips, evaluations, readings,\n"
      "field_cells, index_entries, trace_cells, trace_objective. probslam.map_occupancy_grid_mapping\n"
      "wraps it in a dataclass.");

  m.def(
      "map_log_posterior",
      [](py::handle map, py::handle poses, py::handle scans, py::handle beam_angles, ClassArg<BeamSensorModel> model_arg,
         py::handle prior) {
        const BinaryMap2D b = map_arg(map);
        const BeamSensorModel& model = model_arg.get("model");
        const Scans s = scans_args(poses, scans, beam_angles);
        if (prior.is_none()) throw py::type_error("prior must be given: a number or a (height, width) array");
        const RowMatrixXd p = prior_arg(prior, b.height(), b.width(), 0.5);
        py::gil_scoped_release release;
        return map_log_posterior(b, poses_view(s.poses), as_matrix(s.ranges), as_matrix(s.angles), model, p);
      },
      py::arg("map"), py::arg("poses"), py::arg("scans"), py::arg("beam_angles"), py::arg("model"), py::arg("prior"),
      "Eq. 9.24 of a binary map, nats: sum of log p(z | x, m) over readings plus sum of\n"
      "logit(prior_i) over occupied cells. poses (T, 3), scans (T, B) m, beam_angles (B,) or (T, B)\n"
      "rad, prior a probability or (H, W) probabilities.");
}

}  // namespace probslam::bindings
