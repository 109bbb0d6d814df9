#include <pybind11/stl.h>

#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "args.hpp"
#include "numpy.hpp"
#include "object_lock.hpp"
#include "persistence.hpp"
#include "repr.hpp"
#include "probslam/core/check.hpp"
#include "probslam/grid/inverse_range_sensor_model.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam::bindings {

namespace {

LogOddsClamp clamp_arg(py::handle clamp) {
  if (clamp.is_none()) return LogOddsClamp::none();
  const Eigen::Vector2d p = fixed_vector<2>(clamp, "clamp");
  require_probability(p[0], "clamp");
  require_probability(p[1], "clamp");
  require(p[0] < p[1], "clamp", "must be (p_min, p_max) with p_min < p_max");
  return LogOddsClamp::from_probabilities(p[0], p[1]);
}

py::object clamp_value(const LogOddsClamp& c) {
  if (!c.enabled) return py::none();
  return py::make_tuple(probability_from_log_odds(c.min), probability_from_log_odds(c.max));
}

struct Scan {
  DoubleArray ranges, angles;
};

Scan scan_args(py::handle ranges, py::handle beam_angles, const char* angles_name = "beam_angles") {
  Scan s{vector_arg(ranges, "ranges"), vector_arg(beam_angles, angles_name)};
  if (s.ranges.shape(0) == 0) throw py::value_error("ranges must not be empty");
  if (s.angles.shape(0) != s.ranges.shape(0))
    throw py::value_error(std::string(angles_name) + " must have the same length as ranges (" +
                          std::to_string(s.ranges.shape(0)) + "), got " + std::to_string(s.angles.shape(0)));
  if (!as_vector(s.angles).allFinite()) throw py::value_error(std::string(angles_name) + " must contain only finite values");
  return s;
}

}  // namespace

void define_grid(py::module_& m) {
  using Grid = OccupancyGrid2D;
  // Every call runs under the grid's lock with the GIL released (object_lock.hpp): arguments are
  // converted before, Python results built after. Only the zero-copy log_odds view is unguarded.
  auto grid_class = py::class_<Grid>(m, "OccupancyGrid2D",
                   "2-D occupancy grid in log-odds (Probabilistic Robotics ch. 9.2). Cell (row i, col j)\n"
                   "covers x in [x0 + j res, x0 + (j + 1) res), y in [y0 + i res, y0 + (i + 1) res), metres;\n"
                   "arrays are (height, width), row 0 at the lowest y. Updates are clamped to `clamp`\n"
                   "(probabilities) unless it is None; p_hit / p_miss are the laser update's probabilities.\n"
                   "OccupancyGrid2D.max_cells: the largest number of cells a grid may have.")
      .def(py::init([](double resolution, IntArg width_arg, IntArg height_arg, py::handle origin, double p_prior,
                       py::handle clamp, double p_hit, double p_miss) {
             const int width = width_arg.get("width");
             const int height = height_arg.get("height");
             Grid g(resolution, width, height, fixed_vector<2>(origin, "origin"), p_prior, clamp_arg(clamp));
             g.set_beam_model({p_hit, p_miss});
             return g;
           }),
           py::arg("resolution"), py::arg("width"), py::arg("height"),
           py::arg("origin") = py::make_tuple(0.0, 0.0), py::arg("p_prior") = 0.5,
           py::arg("clamp") = py::make_tuple(0.1192, 0.971), py::arg("p_hit") = 0.7, py::arg("p_miss") = 0.4,
           "resolution: cell side (m); width, height: cells; origin (2,): (x0, y0) m of cell (0, 0)'s\n"
           "lower-left corner; p_prior: prior occupancy probability (log-odds l0 = logit(p_prior));\n"
           "clamp: (p_min, p_max) probabilities or None; p_hit, p_miss: probabilities of insert_rays.")
      .def_static(
          "covering",
          [](py::handle bounds, double resolution, double p_prior, py::handle clamp, double p_hit, double p_miss) {
            const Eigen::Vector4d b = fixed_vector<4>(bounds, "bounds");
            Grid g = Grid::covering(b[0], b[1], b[2], b[3], resolution, p_prior, clamp_arg(clamp));
            g.set_beam_model({p_hit, p_miss});
            return g;
          },
          py::arg("bounds"), py::arg("resolution"), py::arg("p_prior") = 0.5,
          py::arg("clamp") = py::make_tuple(0.1192, 0.971), py::arg("p_hit") = 0.7, py::arg("p_miss") = 0.4,
          "A grid of the given resolution (m) covering bounds (xmin, ymin, xmax, ymax) m; other\n"
          "arguments as for the constructor.")
      .def_property_readonly_static("max_cells", [](py::object) { return Grid::kMaxCells; },
                                    "Largest number of cells a grid may have (constructor, covering, grown, project_2d).")
      .def_property_readonly("resolution", getter(&Grid::resolution), "Cell side, metres.")
      .def_property_readonly("width", getter(&Grid::width), "Number of columns (cells along x).")
      .def_property_readonly("height", getter(&Grid::height), "Number of rows (cells along y).")
      .def_property_readonly("shape", [](const Grid& g) {
        const auto [h, w] = locked(g, [&] { return std::make_pair(g.height(), g.width()); });
        return py::make_tuple(h, w);
      }, "(height, width) in cells, the shape of log_odds.")
      .def_property_readonly("origin", [](const Grid& g) {
        const Eigen::Vector2d o = locked(g, [&] { return g.origin(); });
        return py::make_tuple(o.x(), o.y());
      }, "(x0, y0) metres: the lower-left corner of cell (0, 0).")
      .def_property_readonly("p_prior", getter(&Grid::p_prior), "Prior occupancy probability of every cell.")
      .def_property_readonly("l0", getter(&Grid::prior_log_odds), "Prior log-odds logit(p_prior) (eq. 9.7).")
      .def_property(
          "clamp", [](const Grid& g) { return clamp_value(locked(g, [&] { return g.clamp(); })); },
          [](Grid& g, py::handle c) {
            const LogOddsClamp clamp = clamp_arg(c);
            locked(g, [&] { g.set_clamp(clamp); });
          },
          "(p_min, p_max) probabilities that updates clamp the log-odds to, or None (the textbook\n"
          "update, unbounded). Settable.")
      .def_property(
          "p_hit", [](const Grid& g) { return locked(g, [&] { return g.beam_model().p_hit; }); },
          [](Grid& g, RealArg p_arg) {
            const double p = p_arg.get("p_hit");
            locked(g, [&] { g.set_beam_model({p, g.beam_model().p_miss}); });
          },
          "Probability of occupancy at a beam's end point in insert_rays / insert_scans. Settable.")
      .def_property(
          "p_miss", [](const Grid& g) { return locked(g, [&] { return g.beam_model().p_miss; }); },
          [](Grid& g, RealArg p_arg) {
            const double p = p_arg.get("p_miss");
            locked(g, [&] { g.set_beam_model({g.beam_model().p_hit, p}); });
          },
          "Probability of occupancy of the cells a beam passes through in insert_rays. Settable.")
      .def_property_readonly(
          "log_odds",
          [](py::object self) {
            Grid& g = self.cast<Grid&>();
            const py::ssize_t w = g.width(), h = g.height();  // fixed for the grid's life
            return py::array_t<double>({h, w}, {w * static_cast<py::ssize_t>(sizeof(double)), static_cast<py::ssize_t>(sizeof(double))},
                                       g.data(), self);
          },
          "(height, width) float64 log-odds, a writable zero-copy view of the grid's cells (alive as\n"
          "long as the grid); not guarded by the grid's lock.")
      .def("probability", getter(&Grid::probability),
           "(height, width) occupancy probabilities 1 - 1 / (1 + exp(l)) (eq. 9.6), a copy.")
      .def(
          "cell_of",
          [](const Grid& g, py::handle points) {
            DoubleArray a = matrix_arg(points, "points", 2);
            const auto p = as_matrix(a);
            return locked(g, [&] {
              // Exact 64-bit indices; points too far for an exact index are refused, never wrapped.
              Eigen::Matrix<std::int64_t, Eigen::Dynamic, 2, Eigen::RowMajor> out(p.rows(), 2);
              for (Eigen::Index i = 0; i < p.rows(); ++i) out.row(i) = g.cell_index(p(i, 0), p(i, 1), "points").transpose();
              return out;
            });
          },
          py::arg("points"),
          "(row, col) int64 of the cell holding each point (n, 2); may lie outside the grid.\n"
          "Points more than 2^53 cells away are refused.")
      .def("cell_centers",
           [](const Grid& g) {
             return locked(g, [&] {
               Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> out(static_cast<Eigen::Index>(g.width()) * g.height(), 2);
               for (int r = 0; r < g.height(); ++r)
                 for (int c = 0; c < g.width(); ++c)
                   out.row(static_cast<Eigen::Index>(r) * g.width() + c) = g.cell_center(r, c).transpose();
               return out;
             });
           },
           "(height * width, 2) centres (x, y) m of every cell, row-major (row 0 first).")
      .def(
          "insert_cone_scan",
          [](Grid& g, py::handle pose, py::handle ranges, py::handle beam_angles, double z_max, double alpha,
             double beta, double l_occ, double l_free) {
            const Eigen::Vector3d x = pose_arg(pose);
            const Scan s = scan_args(ranges, beam_angles);
            return locked(g, [&] {
              return g.insert_cone_scan(x, as_vector(s.ranges), as_vector(s.angles), z_max, alpha, beta, l_occ, l_free);
            });
          },
          py::arg("pose"), py::arg("ranges"), py::arg("beam_angles"), py::arg("z_max"), py::arg("alpha"),
          py::arg("beta"), py::arg("l_occ"), py::arg("l_free"),
          "Table 9.1 with the cone model of Table 9.2: l += ism - l0 in the perceptual field.\n"
          "pose (3,), ranges (n,) m, beam_angles (n,) rad relative to theta; z_max, alpha m; beta rad.\n"
          "NaN, inf and negative readings are left out. Returns the number of cells changed.")
      .def(
          "insert_rays",
          [](Grid& g, py::handle pose, py::handle ranges, py::handle angles, double max_range) {
            const Eigen::Vector3d x = pose_arg(pose);
            const Scan s = scan_args(ranges, angles, "angles");
            return locked(g, [&] { return g.insert_rays(x, as_vector(s.ranges), as_vector(s.angles), max_range); });
          },
          py::arg("pose"), py::arg("ranges"), py::arg("angles"), py::arg("max_range"),
          "Laser-beam update: exact cell walk, misses along each ray, a hit at the end of readings\n"
          "< max_range (m); readings >= max_range clear up to it. Each cell changes once per scan,\n"
          "a hit beats a miss (OctoMap's rules). NaN, inf, negative readings are skipped. Rays are\n"
          "clipped to the grid before the walk. pose (3,), ranges (n,) m, angles (n,) rad. Returns\n"
          "the number of cells updated.")
      .def(
          "insert_scans",
          [](Grid& g, py::handle poses, py::handle ranges, py::handle angles, double max_range) {
            DoubleArray p = matrix_arg(poses, "poses", 3);
            DoubleArray r = matrix_arg(ranges, "ranges");
            DoubleArray a = as_array(angles, "angles");
            if (a.ndim() == 1) a = DoubleArray(a.reshape({py::ssize_t{1}, a.shape(0)}));
            else a = matrix_arg(angles, "angles");
            if (r.shape(0) != p.shape(0))
              throw py::value_error("ranges must have one row per pose: got " + shape_of(r) + " for poses " + shape_of(p));
            if (r.shape(1) == 0) throw py::value_error("ranges must not be empty");
            if (!as_matrix(a).allFinite()) throw py::value_error("angles must contain only finite values");
            if (a.shape(1) != r.shape(1) || (a.shape(0) != 1 && a.shape(0) != r.shape(0)))
              throw py::value_error("angles must have shape (" + std::to_string(r.shape(1)) + ",) or " + shape_of(r) +
                                    ", got " + shape_of(a));
            const Eigen::Map<const Poses2> x(p.data(), p.shape(0), 3);
            return locked(g, [&] { return g.insert_scans(x, as_matrix(r), as_matrix(a), max_range); });
          },
          py::arg("poses"), py::arg("ranges"), py::arg("angles"), py::arg("max_range"),
          "insert_rays for every scan: poses (S, 3), ranges (S, B), angles (B,) or (S, B). Every\n"
          "row is checked before the first is applied.")
      .def(
          "clear_footprint",
          [](Grid& g, py::handle pose, double radius, py::object l_free) {
            const Eigen::Vector3d x = pose_arg(pose);
            const std::optional<double> given = l_free.is_none() ? std::nullopt : std::optional<double>(l_free.cast<double>());
            return locked(g, [&] {
              const double lf = given ? *given : (g.clamp().enabled ? g.clamp().min : logit(0.05));
              return g.clear_footprint(x, radius, lf);
            });
          },
          py::arg("pose"), py::arg("radius"), py::arg("l_free") = py::none(),
          "Cells whose centre is within radius (m) of the pose are free: l += l_free - l0\n"
          "(default l_free: the lower clamp, else logit(0.05)). Returns the cells changed.")
      .def(
          "add_log_odds",
          [](Grid& g, py::handle cells, py::handle deltas) {
            LongArray c = integer_array_arg(cells, "cells");
            DoubleArray d = vector_arg(deltas, "deltas");
            if (c.ndim() != 1) throw py::value_error("cells must be a 1-D array of flat cell indices");
            const std::vector<long> index(c.data(), c.data() + c.shape(0));
            const Eigen::Map<const Eigen::VectorXd> delta(d.data(), d.shape(0));
            return locked(g, [&] { return g.add_log_odds(index, delta); });
          },
          py::arg("cells"), py::arg("deltas"),
          "Table 9.1 line 4 with an inverse model evaluated elsewhere (ch. 9.3): l += deltas (n,) at\n"
          "the flat cell indices cells (n,) (row * width + col), clamped; all checked first.\n"
          "Returns the cells updated.")
      .def(
          "grown",
          [](const Grid& g, py::handle bounds) {
            const Eigen::Vector4d b = fixed_vector<4>(bounds, "bounds");
            return locked(g, [&] { return g.grown_to_include(b[0], b[1], b[2], b[3]); });
          },
          py::arg("bounds"),
          "An enlarged copy on the same lattice covering bounds (xmin, ymin, xmax, ymax) m.")
      .def("copy", [](const Grid& g) { return locked(g, [&] { return Grid(g); }); }, "An independent deep copy.")
      .def(
          "same_geometry", [](const Grid& g, const Grid& other) { return locked(g, other, [&] { return g.same_geometry(other); }); },
          py::arg("other"), "Whether other has the same resolution, origin, width and height.")
      .def("__repr__", [](py::handle self) {
        const Grid& g = self.cast<const Grid&>();
        return repr_of(self, locked(g, [&] {
          return std::to_string(g.width()) + " x " + std::to_string(g.height()) + " cells of " + num(g.resolution()) +
                 " m, origin (" + num(g.origin().x()) + ", " + num(g.origin().y()) + ") m";
        }));
      });
  define_persistence<Grid>(grid_class);

  m.def(
      "fuse_max",
      [](py::handle grids_arg) {
        if (py::isinstance<py::str>(grids_arg) || !PySequence_Check(grids_arg.ptr()))
          throw py::type_error("grids: expected a sequence of OccupancyGrid2D, got " + type_name_of(grids_arg));
        const py::sequence seq = py::reinterpret_borrow<py::sequence>(grids_arg);
        std::vector<py::object> held;  // the grids stay alive while the GIL is released, whatever the sequence does
        std::vector<const Grid*> grids;
        for (std::size_t k = 0; k < seq.size(); ++k) {
          held.emplace_back(seq[k]);
          grids.push_back(&ClassArg<Grid>{held.back()}.get("grids[" + std::to_string(k) + "]"));
        }
        require(!grids.empty(), "grids", "must not be empty");
        // One grid locked at a time (never two: no lock order to get wrong), the GIL released.
        py::gil_scoped_release release;
        std::optional<Grid> fused;
        for (const Grid* g : grids) {
          std::lock_guard<std::mutex> lock(g->mutex());
          if (!fused) fused.emplace(*g);
          else fuse_max_into(*fused, *g);
        }
        return std::move(*fused);
      },
      py::arg("grids"), "Eq. 9.9: the cell-wise maximum of grids of equal geometry.");

  m.def(
      "inverse_range_sensor_model",
      [](py::handle cells, py::handle pose, py::handle ranges, py::handle beam_angles, double z_max, double alpha,
         double beta, double l0, double l_occ, double l_free) -> py::object {
        const ConeModel model{z_max, alpha, beta, l0, l_occ, l_free};
        const Eigen::Vector3d x = pose_arg(pose);
        const Scan s = scan_args(ranges, beam_angles);
        DoubleArray c = as_array(cells, "cells_xy");
        const bool single = c.ndim() == 1;
        if (single) c = DoubleArray(vector_arg(cells, "cells_xy", 2).reshape({py::ssize_t{1}, py::ssize_t{2}}));
        else c = matrix_arg(cells, "cells_xy", 2);
        const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>> xy(c.data(), c.shape(0), 2);
        Eigen::VectorXd out;
        {
          py::gil_scoped_release release;
          out = inverse_range_sensor_model(xy, x, as_vector(s.ranges), as_vector(s.angles), model);
        }
        if (single) return py::float_(out[0]);
        return py::cast(std::move(out));
      },
      py::arg("cells_xy"), py::arg("pose"), py::arg("ranges"), py::arg("beam_angles"), py::arg("z_max"),
      py::arg("alpha"), py::arg("beta"), py::arg("l0"), py::arg("l_occ"), py::arg("l_free"),
      "Table 9.2's inverse range sensor model (cone model) for cell centres cells_xy (n, 2) m ->\n"
      "(n,) log-odds, or one (2,) cell -> float. pose (3,); ranges (k,) m and beam_angles (k,) rad\n"
      "relative to the heading; z_max, alpha (obstacle thickness) m; beta (beam width) rad;\n"
      "l0, l_occ, l_free log-odds.");

  m.def("logit", py::vectorize(&logit), py::arg("p"), "log(p / (1 - p)), eq. 9.5.");
  m.def("probability_from_log_odds", py::vectorize(&probability_from_log_odds), py::arg("l"), "Eq. 9.6.");
}

}  // namespace probslam::bindings
