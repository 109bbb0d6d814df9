// Scan matching (slam2d/): thin conversions only. LikelihoodField and CorrelativeScanMatcher
// are immutable once built, so their calls need no object lock; long work releases the GIL.
#include <pybind11/stl.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>

#include "args.hpp"
#include "numpy.hpp"
#include "probslam/core/check.hpp"
#include "object_lock.hpp"
#include "options_class.hpp"
#include "persistence.hpp"
#include "repr.hpp"
#include "probslam/slam2d/correlative_scan_matcher.hpp"
#include "probslam/slam2d/incremental_scan_matcher.hpp"
#include "probslam/slam2d/likelihood_field.hpp"
#include "probslam/slam2d/range_scan.hpp"
#include "probslam/fastslam/grid_fast_slam.hpp"
#include "probslam/slam2d/submap_slam.hpp"
#include "probslam/core/update_trigger.hpp"

namespace probslam::bindings {

namespace {

using FloatImage = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

Points2 points_arg(py::handle obj, const char* name = "points") {
  const DoubleArray a = matrix_arg(obj, name, 2);
  return as_matrix(a);
}

ScanFilter filter_args(double max_range, double min_range, double max_usable_range, bool clear_no_return,
                       double min_point_spacing) {
  ScanFilter f{max_range, min_range, max_usable_range, clear_no_return, min_point_spacing};
  f.validate();
  return f;
}

MatchOptions match_options(double linear_window, double angular_window, double angular_step,
                           py::handle prior_covariance, bool refine, bool brute_force,
                           double min_translation_std, double min_rotation_std,
                           double min_score = -std::numeric_limits<double>::infinity()) {
  MatchOptions o;
  o.min_score = min_score;
  o.window = {linear_window, angular_window, angular_step};
  if (!prior_covariance.is_none()) {
    o.use_prior = true;
    o.prior_covariance = square_matrix_arg(prior_covariance, "prior_covariance", 3);
  }
  o.refine = refine;
  o.brute_force = brute_force;
  o.min_translation_std = min_translation_std;
  o.min_rotation_std = min_rotation_std;
  try {
    o.validate();
  } catch (const std::invalid_argument& e) {
    // The window's fields are match()'s keywords linear_window, angular_window and angular_step.
    std::string what = e.what();
    for (const auto& [path, keyword] : {std::pair{"window.linear", "linear_window"}, std::pair{"window.angular_step", "angular_step"},
                                        std::pair{"window.angular", "angular_window"}}) {
      const std::string prefix = std::string(path) + " ";
      if (what.rfind(prefix, 0) == 0) {
        what = std::string(keyword) + what.substr(std::string(path).size());
        break;
      }
    }
    throw std::invalid_argument(what);
  }
  return o;
}

/// `Owner(*, options=None, **fields)` for a class built from one options struct T, and its
/// `options` property (a copy of what it runs with).
template <class Owner, class T>
void def_options_init(py::class_<Owner>& c, const char* owner, const char* options_name) {
  py::options signatures;  // the fields' keywords are written from describe(), not **kwargs
  signatures.disable_function_signatures();
  const std::string call = std::string(owner) + "()";
  c.def(py::init([call](py::handle options, const py::kwargs& fields) {
          return std::make_unique<Owner>(options_arg<T>(options, fields, call.c_str()));
        }),
        py::kw_only(), py::arg("options") = py::none(),
        options_init_signature<T>(owner, "*, ").c_str());
  signatures.enable_function_signatures();
  c.def_property_readonly("options", [](const Owner& self) { return locked(self, [&] { return self.options(); }); },
                          ("A copy of the " + std::string(options_name) + " it runs with.").c_str());
}

/// add_scans of the laser SLAM classes: shapes checked here, then the class's own add_scans
/// checks every row (check_scan) before the first is added, so a bad batch changes nothing.
template <typename Mapper>
void add_scans(Mapper& self, py::handle ranges, py::handle beam_angles, py::handle odometry, py::handle timestamps) {
  const DoubleArray r = matrix_arg(ranges, "ranges");
  const DoubleArray o = matrix_arg(odometry, "odometry", 3);
  const DoubleArray t = vector_arg(timestamps, "timestamps");
  const DoubleArray a = as_array(beam_angles, "beam_angles");
  const auto S = r.shape(0), B = r.shape(1);
  if (o.shape(0) != S || t.shape(0) != S)
    throw py::value_error("odometry and timestamps must have one row per scan (" + std::to_string(S) + ")");
  const bool per_scan = a.ndim() == 2;
  if (!((a.ndim() == 1 && a.shape(0) == B) || (per_scan && a.shape(0) == S && a.shape(1) == B)))
    throw py::value_error("beam_angles must have shape (" + std::to_string(B) + ",) or (" + std::to_string(S) +
                          ", " + std::to_string(B) + "), got " + shape_of(a));
  const auto R = as_matrix(r), O = as_matrix(o);
  const auto T = as_vector(t);
  const Eigen::Map<const RowMatrixXd> A(a.data(), per_scan ? S : 1, B);
  locked(self, [&] { self.add_scans(R, A, O, T); });
}

/// A laser SLAM class with its add_scans; the constructor is defined by the caller.
template <typename Mapper>
py::class_<Mapper> mapper_class(py::module_& m, const char* name, const char* doc) {
  py::class_<Mapper> c(m, name, doc);
  c.def("add_scans", &add_scans<Mapper>, py::arg("ranges"), py::arg("beam_angles"), py::arg("odometry"),
        py::arg("timestamps"),
        "Adds scans in order: ranges (S, B) m, beam_angles (B,) or (S, B) rad relative to the sensor's\n"
        "heading, odometry (S, 3) sensor poses (m, m, rad), timestamps (S,) s. Every row is checked\n"
        "before the first is used.")
      .def("copy", [](const Mapper& self) { return locked(self, [&] { return std::make_unique<Mapper>(self); }); },
           "An independent deep copy: options, scans, maps and random streams (the same scans then give\n"
           "the same results).");
  return c;
}

/// SubmapSlam2D.constraints: one row per constraint between submaps.
struct SubmapConstraintArrays {
  py::array_t<int> from_submap, to_submap, scan;
  py::array_t<double> measurement, covariance, match_quality;
  py::array_t<bool> loop, active;
};

SubmapConstraintArrays constraint_arrays(const std::vector<SubmapConstraint>& cs) {
  const auto n = static_cast<py::ssize_t>(cs.size());
  SubmapConstraintArrays out{py::array_t<int>(n), py::array_t<int>(n), py::array_t<int>(n),
                             py::array_t<double>({n, py::ssize_t(3)}), py::array_t<double>({n, py::ssize_t(3), py::ssize_t(3)}),
                             py::array_t<double>(n), py::array_t<bool>(n), py::array_t<bool>(n)};
  for (py::ssize_t k = 0; k < n; ++k) {
    const SubmapConstraint& c = cs[static_cast<std::size_t>(k)];
    out.from_submap.mutable_at(k) = c.from, out.to_submap.mutable_at(k) = c.to, out.scan.mutable_at(k) = c.scan;
    out.loop.mutable_at(k) = c.loop, out.active.mutable_at(k) = c.active;
    out.match_quality.mutable_at(k) = c.match_quality;
    for (int i = 0; i < 3; ++i) {
      out.measurement.mutable_at(k, i) = c.measurement[i];
      for (int j = 0; j < 3; ++j) out.covariance.mutable_at(k, i, j) = c.covariance(i, j);
    }
  }
  return out;
}

/// The laser SLAM classes' options, groups before the structs that hold them (a signature names
/// a group's class). UpdateTrigger is MonteCarloLocalizationOptions' too (bound after this).
void define_laser_options(py::module_& m) {
  bind_options<UpdateTrigger>(m, "UpdateTrigger",
                              "When a filter or scan matcher works on a scan: after this much travel or turn since it last did.");
  bind_options<ScanFilter>(m, "ScanFilter", "How raw laser readings become hits, and the usable range.");
  bind_options<LikelihoodFieldOptions>(m, "LikelihoodFieldOptions",
                                       "The blurred likelihood field of a grid (ch. 6.4) scans are matched against.");
  bind_options<SearchWindow>(m, "SearchWindow", "The correlative search window around the prior pose.");
  bind_options<MatchOptions>(m, "MatchOptions", "Correlative scan matching's window, refinement and covariance floors.");
  bind_options<OdometryNoise>(m, "OdometryNoise",
                              "The laser SLAM classes' odometry noise: stds growing with the distance travelled and the angle turned.");
  bind_options<IncrementalScanMatcherOptions>(m, "IncrementalScanMatcherOptions",
                                              "The options of IncrementalScanMatcher (and SubmapSlam2D's frontend).");
  bind_options<LoopClosureOptions>(m, "LoopClosureOptions", "SubmapSlam2D's loop-closure search.");
  bind_options<SubmapSlamOptions>(m, "SubmapSlamOptions", "The options of SubmapSlam2D (ch. 11.7).");
  bind_options<EndpointLikelihoodOptions>(m, "EndpointLikelihoodOptions",
                                          "GridFastSlam's end-point likelihood p(z | x, m) (ch. 6.4).");
  bind_options<ScanProposalOptions>(m, "ScanProposalOptions",
                                    "GridFastSlam's scan-matching proposal (Grisetti et al. 2007): hill climb and Gaussian fit.");
  bind_options<GridFastSlamOptions>(m, "GridFastSlamOptions", "The options of GridFastSlam.");
}

void define_laser_results(py::module_& m) {
  bind_report<SubmapSlamTimings>(m, "SubmapSlamTimings",
                                 "Processor seconds per stage of a SubmapSlam2D since construction or loading, and what it built.");
  bind_report<SubmapSlamMemory>(m, "SubmapSlamMemory", "The bytes a SubmapSlam2D's large buffers hold.")
      .def_property_readonly("total", &SubmapSlamMemory::total, "total (bytes): the sum of the fields.");
  bind_report<GridFastSlamTimings>(m, "GridFastSlamTimings",
                                   "Processor seconds per stage of a GridFastSlam since construction or loading.");
  using C = SubmapConstraintArrays;
  py::class_<C>(m, "SubmapConstraints",
                "SubmapSlam2D.constraints: the constraints between submaps, row k one constraint (C rows).")
      .def_readonly("from_submap", &C::from_submap, "(C,) int32 submap the measurement is taken from.")
      .def_readonly("to_submap", &C::to_submap, "(C,) int32 submap whose origin is measured.")
      .def_readonly("measurement", &C::measurement, "(C, 3) to_submap's origin in from_submap's frame (m, m, rad).")
      .def_readonly("covariance", &C::covariance, "(C, 3, 3) covariance of the measurement.")
      .def_readonly("loop", &C::loop, "(C,) bool: a loop closure (else consecutive submaps).")
      .def_readonly("scan", &C::scan, "(C,) int32 loop closures: the scan matched against from_submap; -1 otherwise.")
      .def_readonly("match_quality", &C::match_quality, "(C,) mean hit likelihood of the match, 0 .. 1.")
      .def_readonly("active", &C::active, "(C,) bool: False once dissolved.")
      .def("__len__", [](const C& c) { return c.loop.shape(0); })
      .def("__repr__", [](py::handle self) {
        const C& c = self.cast<const C&>();
        long loops = 0;
        for (py::ssize_t k = 0; k < c.loop.shape(0); ++k) loops += c.loop.at(k) && c.active.at(k);
        return repr_of(self, std::to_string(c.loop.shape(0)) + " constraints, " + std::to_string(loops) +
                                 " active loop closures");
      });
  using S = SubmapSlamSummary;
  py::class_<S>(m, "SubmapSlamSummary", "SubmapSlam2D.summary: counts of the run so far.")
      .def_readonly("scans", &S::scans, "Scans added.")
      .def_readonly("submaps", &S::submaps, "Submaps (pose graph nodes).")
      .def_readonly("matched_scans", &S::matched_scans, "Scans placed by scan matching (else by odometry).")
      .def_readonly("closures_searched", &S::closures_searched, "Scan-submap pairs searched for a loop closure.")
      .def_readonly("closures_accepted", &S::closures_accepted, "Closures added to the graph and still active.")
      .def_readonly("closures_rejected", &S::closures_rejected, "Closures that failed the quality or consistency test.")
      .def_readonly("closures_dissolved", &S::closures_dissolved, "Closures added, then undone by the optimised graph.")
      .def_readonly("rounds", &S::rounds, "Rounds of search, optimisation and dissolution in finish().")
      .def_readonly("optimizations", &S::optimizations, "Graph optimisations run.")
      .def_readonly("final_chi2", &S::final_chi2, "chi2 of the optimised graph.")
      .def("__repr__", [](py::handle self) {
        const S& s = self.cast<const S&>();
        return repr_of(self, std::to_string(s.scans) + " scans, " + std::to_string(s.submaps) + " submaps, " +
                                 std::to_string(s.closures_accepted) + " loop closures, chi2 " + num(s.final_chi2));
      });
  using G = GridFastSlamSummary;
  py::class_<G>(m, "GridFastSlamSummary", "GridFastSlam.summary: counts of the run so far.")
      .def_readonly("scans", &G::scans, "Scans added.")
      .def_readonly("updates", &G::updates, "Filter updates (scans after update.distance / update.angle of travel).")
      .def_readonly("resamples", &G::resamples, "Resamplings.")
      .def_readonly("matched", &G::matched, "Particle updates drawn from the scan-matching proposal.")
      .def_readonly("fallbacks", &G::fallbacks, "Particle updates whose match failed (motion model instead).")
      .def_readonly("effective_sample_size", &G::effective_sample_size,
                    "N_eff after the last update, before any resampling.")
      .def("__repr__", [](py::handle self) {
        const G& s = self.cast<const G&>();
        return repr_of(self, std::to_string(s.scans) + " scans, " + std::to_string(s.updates) + " updates, " +
                                 std::to_string(s.resamples) + " resamples, N_eff " + num(s.effective_sample_size));
      });
  py::class_<TileSharing>(m, "TileSharing", "GridFastSlam.tile_sharing: map tiles held and allocated.")
      .def_readonly("references", &TileSharing::references, "Tiles held over all particles (a shared tile once per holder).")
      .def_readonly("distinct", &TileSharing::distinct, "Tiles allocated.")
      .def_readonly("bytes", &TileSharing::bytes, "Bytes of the distinct tiles.")
      .def("__repr__", [](py::handle self) {
        const TileSharing& t = self.cast<const TileSharing&>();
        return repr_of(self, std::to_string(t.distinct) + " distinct tiles of " + std::to_string(t.references) +
                                 " held, " + std::to_string(t.bytes) + " bytes");
      });
}

/// (N, 5) per scan: matched, fallback, submap, match_quality, points.
RowMatrixXd scan_info(const IncrementalScanMatcher& frontend) {
  RowMatrixXd info(frontend.num_scans(), 5);
  for (int k = 0; k < frontend.num_scans(); ++k) {
    const ScanEstimate& e = frontend.estimates()[k];
    info.row(k) << e.matched, e.fallback, e.submap, e.match_quality, e.points;
  }
  return info;
}

Eigen::VectorXd timestamps_of(const IncrementalScanMatcher& frontend) {
  return Eigen::Map<const Eigen::VectorXd>(frontend.timestamps().data(), frontend.num_scans());
}

/// (S, 3) the frontend's pose of every scan.
Poses2 estimate_poses(const IncrementalScanMatcher& frontend) {
  Poses2 p(frontend.num_scans(), 3);
  for (int k = 0; k < frontend.num_scans(); ++k) p.row(k) = frontend.estimates()[k].pose.transpose();
  return p;
}

Poses2 rows_of(const std::vector<Eigen::Vector3d>& poses) {
  Poses2 p(static_cast<Eigen::Index>(poses.size()), 3);
  for (std::size_t k = 0; k < poses.size(); ++k) p.row(static_cast<Eigen::Index>(k)) = poses[k].transpose();
  return p;
}

// The map argument of start_from_map: an OccupancyGrid2D, else TypeError naming it.
const OccupancyGrid2D& grid_arg(py::handle map, const char* name) {
  if (!py::isinstance<OccupancyGrid2D>(map))
    throw py::type_error(std::string(name) + ": expected an OccupancyGrid2D, got " +
                         std::string(py::str(py::type::of(map).attr("__name__"))));
  return map.cast<const OccupancyGrid2D&>();
}

// start_from_map(map, initial_pose) of a SLAM class: the arguments checked by name with the GIL
// held, the call under both objects' locks.
template <typename T>
auto start_from_map_method() {
  return [](T& self, py::handle map, py::handle initial_pose) {
    const OccupancyGrid2D& grid = grid_arg(map, "map");
    const Eigen::Vector3d pose = fixed_vector<3>(initial_pose, "initial_pose");
    locked(self, grid, [&] { self.start_from_map(grid, pose); });
  };
}

// A copy of the map a run started from, or None.
template <typename T>
std::optional<OccupancyGrid2D> start_map_of(const T& self) {
  return locked(self, [&]() -> std::optional<OccupancyGrid2D> {
    if (const OccupancyGrid2D* m = self.start_map()) return *m;
    return std::nullopt;
  });
}

}  // namespace

void define_slam2d(py::module_& m) {
  const double inf = std::numeric_limits<double>::infinity();
  m.def(
      "scan_hits",
      [](py::handle ranges, py::handle beam_angles, double max_range, double min_range, double max_usable_range,
         double min_point_spacing) {
        const DoubleArray r = vector_arg(ranges, "ranges"), a = vector_arg(beam_angles, "beam_angles");
        const ScanFilter f = filter_args(max_range, min_range, max_usable_range, true, min_point_spacing);
        py::gil_scoped_release release;
        return scan_hits(as_vector(r), as_vector(a), f);
      },
      py::arg("ranges"), py::arg("beam_angles"), py::arg("max_range") = inf, py::arg("min_range") = 0.0,
      py::arg("max_usable_range") = 30.0, py::arg("min_point_spacing") = 0.0,
      "(N, 2) hit points (x, y) m in the sensor frame of ranges (B,) m at beam_angles (B,) rad: readings\n"
      "in [min_range, max_usable_range] below max_range, at least min_point_spacing (m) apart;\n"
      "no-return readings (>= max_range, inf, NaN) never hit.");
  m.def(
      "ranges_for_insertion",
      [](py::handle ranges, double max_range, double min_range, double max_usable_range, bool clear_no_return) {
        const DoubleArray r = vector_arg(ranges, "ranges");
        const ScanFilter f = filter_args(max_range, min_range, max_usable_range, clear_no_return, 0.0);
        return py::make_tuple(ranges_for_insertion(as_vector(r), f), f.usable_range());
      },
      py::arg("ranges"), py::arg("max_range") = inf, py::arg("min_range") = 0.0, py::arg("max_usable_range") = 30.0,
      py::arg("clear_no_return") = true,
      "(ranges (B,) m, usable_range m) for OccupancyGrid2D.insert_rays(max_range=usable_range): hits\n"
      "stay; no-return beams and far hits become usable_range (clear only) or, without\n"
      "clear_no_return, NaN (skipped); readings below min_range become NaN.");

  py::class_<LikelihoodField>(m, "LikelihoodField",
                              "The blurred likelihood field of a grid (ch. 6.4): log((1 - p_rand) exp(-d^2 / 2 sigma^2)\n"
                              "+ p_rand), d the distance (m) to the nearest occupied cell; immutable once built.")
      .def(py::init([](ClassArg<OccupancyGrid2D> grid_arg, double sigma, double p_rand, double occupied_threshold,
                       double max_distance, py::handle region) {
             const OccupancyGrid2D& grid = grid_arg.get("grid");
             const LikelihoodFieldOptions o{sigma, p_rand, occupied_threshold, max_distance};
             if (region.is_none())
               return locked(grid, [&] { return LikelihoodField::from_grid(grid, o); });
             const Eigen::Vector4d box = fixed_vector<4>(region, "region");
             return locked(grid, [&] { return LikelihoodField::from_grid(grid, box, o); });
           }),
           py::arg("grid"), py::arg("sigma") = 0.05, py::arg("p_rand") = 0.05, py::arg("occupied_threshold") = 0.5,
           py::arg("max_distance") = 0.0, py::arg("region") = py::none(),
           "From grid's cells with p > occupied_threshold; sigma m; max_distance m (0: 6 sigma), the\n"
           "truncation; region (xmin, ymin, xmax, ymax) m limits it to part of the grid.")
      .def_property_readonly("resolution", &LikelihoodField::resolution, "Cell side, metres.")
      .def_property_readonly("origin", &LikelihoodField::origin, "(x0, y0) m of cell (0, 0)'s lower-left corner.")
      .def_property_readonly("shape", [](const LikelihoodField& f) { return py::make_tuple(f.height(), f.width()); },
                             "(rows, cols) in cells.")
      .def_property_readonly("num_occupied", &LikelihoodField::num_occupied, "Occupied cells the field was built from.")
      .def_property_readonly("floor_value", &LikelihoodField::floor_value, "log p_rand: the value far from obstacles.")
      .def_property_readonly("sigma", [](const LikelihoodField& f) { return f.options().sigma; },
                             "Standard deviation of the blur, metres.")
      .def_property_readonly("p_rand", [](const LikelihoodField& f) { return f.options().p_rand; },
                             "Weight of the uniform floor.")
      .def_property_readonly("truncation", [](const LikelihoodField& f) { return f.options().truncation(); },
                             "Distance (m) beyond which the field is at its floor.")
      .def_property_readonly("distance", [](const LikelihoodField& f) { return FloatImage(f.distance()); },
                             "(rows, cols) float32 distance (m) to the nearest occupied cell, a copy.")
      .def_property_readonly("log_likelihood", [](const LikelihoodField& f) { return FloatImage(f.log_likelihood()); },
                             "(rows, cols) float32 field values (log-likelihood), a copy.")
      .def("__repr__", [](py::handle self) {
        const LikelihoodField& f = self.cast<const LikelihoodField&>();
        return repr_of(self, std::to_string(f.width()) + " x " + std::to_string(f.height()) + " cells of " +
                                 num(f.resolution()) + " m, " + std::to_string(f.num_occupied()) + " occupied, sigma " +
                                 num(f.options().sigma) + " m");
      })
      .def(
          "interpolate_distance",
          [](const LikelihoodField& f, py::handle points) {
            const Points2 p = points_arg(points);
            Eigen::VectorXd d(p.rows());
            Points2 g(p.rows(), 2);
            {
              py::gil_scoped_release release;
              for (Eigen::Index i = 0; i < p.rows(); ++i) {
                Eigen::Vector2d grad;
                d[i] = f.interpolate_distance(p(i, 0), p(i, 1), &grad);
                g.row(i) = grad.transpose();
              }
            }
            return py::make_tuple(d, g);
          },
          py::arg("points"), "(distances (N,) m, gradients (N, 2)) bilinear at world points (N, 2) m.");

  py::class_<MatchResult>(m, "MatchResult", "The result of CorrelativeScanMatcher.match.")
      .def_readonly("found", &MatchResult::found, "False: no lattice pose reached min_score (pose = prior).")
      .def_readonly("pose", &MatchResult::pose, "(3,) best pose (x m, y m, theta rad), refined if asked.")
      .def_readonly("search_pose", &MatchResult::search_pose, "(3,) best pose on the search lattice.")
      .def_readonly("covariance", &MatchResult::covariance, "(3, 3) covariance of pose (response surface).")
      .def_readonly("score", &MatchResult::score, "Sum of log p over the points (+ log prior) at pose.")
      .def_readonly("search_score", &MatchResult::search_score, "The same at search_pose on the lattice.")
      .def_readonly("match_quality", &MatchResult::match_quality,
                    "Mean over the points of exp(-d^2 / 2 sigma^2) at pose, 0 .. 1.")
      .def_readonly("num_points", &MatchResult::num_points, "Points matched.")
      .def_readonly("candidates_scored", &MatchResult::candidates_scored, "Poses and pyramid nodes the search scored.")
      .def_readonly("angular_steps", &MatchResult::angular_steps, "Rotations searched.")
      .def_readonly("angular_step", &MatchResult::angular_step, "Angular lattice step, radians.")
      .def("__repr__", [](py::handle self) {
        const MatchResult& r = self.cast<const MatchResult&>();
        return repr_of(self, std::string(r.found ? "" : "not found, ") + "pose (" + num(r.pose.x()) + ", " +
                                 num(r.pose.y()) + ", " + num(r.pose.z()) + "), score " + num(r.score) +
                                 ", match_quality " + num(r.match_quality) + ", " + std::to_string(r.num_points) +
                                 " points");
      });

  py::class_<CorrelativeScanMatcher>(m, "CorrelativeScanMatcher",
                                     "Correlative scan matching (Olson 2009): branch and bound over a max-pooled pyramid of\n"
                                     "a LikelihoodField (Hess 2016). Immutable once built.")
      .def(py::init([](ClassArg<LikelihoodField> field_arg, IntArg max_level_arg) {
             const LikelihoodField& field = field_arg.get("field");
             const int max_level = max_level_arg.get("max_level");
             py::gil_scoped_release release;
             return CorrelativeScanMatcher(field, max_level);
           }),
           py::arg("field"), py::arg("max_level") = 6, "A matcher on field with pyramid levels up to max_level.")
      .def_property_readonly("max_level", &CorrelativeScanMatcher::max_level, "Highest pyramid level.")
      .def_property_readonly("field", &CorrelativeScanMatcher::field, "The LikelihoodField matched against.")
      .def(
          "match",
          [](const CorrelativeScanMatcher& self, py::handle points, py::handle prior, double linear_window,
             double angular_window, double angular_step, py::handle prior_covariance, bool refine, bool brute_force,
             double min_translation_std, double min_rotation_std, double min_score) {
            const Points2 p = points_arg(points);
            const Eigen::Vector3d x0 = pose_arg(prior, "prior");
            const MatchOptions o = match_options(linear_window, angular_window, angular_step, prior_covariance,
                                                 refine, brute_force, min_translation_std, min_rotation_std, min_score);
            py::gil_scoped_release release;
            return self.match(p, x0, o);
          },
          py::arg("points"), py::arg("prior"), py::arg("linear_window") = 0.3, py::arg("angular_window") = 0.35,
          py::arg("angular_step") = 0.0, py::arg("prior_covariance") = py::none(), py::arg("refine") = true,
          py::arg("brute_force") = false, py::arg("min_translation_std") = 0.0, py::arg("min_rotation_std") = 0.0,
          py::arg("min_score") = -std::numeric_limits<double>::infinity(),
          "Best pose of points (N, 2) m (sensor frame) within +-linear_window m and +-angular_window rad\n"
          "of prior (3,); angular_step rad (0: from the scan's extent); prior_covariance (3, 3) adds a\n"
          "Gaussian prior term; refine: Gauss-Newton on the interpolated field; brute_force: no\n"
          "pyramid; min_translation_std (m) / min_rotation_std (rad) floor the covariance. Returns a\n"
          "MatchResult.")
      .def(
          "smooth_score",
          [](const CorrelativeScanMatcher& self, py::handle points, py::handle pose, py::handle prior,
             py::handle prior_covariance) {
            const Points2 p = points_arg(points);
            const Eigen::Vector3d x = pose_arg(pose, "pose");
            const Eigen::Vector3d x0 = prior.is_none() ? x : pose_arg(prior, "prior");
            const MatchOptions o = match_options(0.3, 0.35, 0.0, prior_covariance, false, false, 0.0, 0.0);
            py::gil_scoped_release release;
            return self.smooth_score(p, x, x0, o);
          },
          py::arg("points"), py::arg("pose"), py::arg("prior") = py::none(), py::arg("prior_covariance") = py::none(),
          "Score (sum of log p over points (N, 2) m, plus the prior term) at pose (3,) on the bilinear field.")
      .def(
          "runner_up",
          [](const CorrelativeScanMatcher& self, py::handle points, py::handle prior, const MatchResult& best,
             double distinct_chi2, double linear_window, double angular_window, double angular_step, bool refine,
             bool brute_force, double min_score, py::handle admitted) {
            const Points2 p = points_arg(points);
            const Eigen::Vector3d x0 = pose_arg(prior, "prior");
            const MatchOptions o = match_options(linear_window, angular_window, angular_step, py::none(), refine,
                                                 brute_force, 0.0, 0.0, min_score);
            const Eigen::Matrix3d a =
                admitted.is_none() ? Eigen::Matrix3d::Zero() : square_matrix_arg(admitted, "admitted", 3);
            py::gil_scoped_release release;
            return self.runner_up(p, x0, o, best, distinct_chi2, a);
          },
          py::arg("points"), py::arg("prior"), py::arg("best"), py::arg("distinct_chi2"),
          py::arg("linear_window") = 0.3, py::arg("angular_window") = 0.35, py::arg("angular_step") = 0.0,
          py::arg("refine") = true, py::arg("brute_force") = false,
          py::arg("min_score") = -std::numeric_limits<double>::infinity(), py::arg("admitted") = py::none(),
          "The best pose of the window (match()'s arguments) that is another place than best (match()'s\n"
          "MatchResult): beyond chi2 distinct_chi2 of best's covariance and beyond the field's reach of its\n"
          "points (rms); admitted (3, 3): only poses p with (p - prior)^T admitted (p - prior) <= 1. A\n"
          "MatchResult (found False when there is none; its covariance is not computed).")
      .def(
          "closeness",
          [](const CorrelativeScanMatcher& self, py::handle points, py::handle a, py::handle b) {
            const Points2 p = points_arg(points);
            const Eigen::Vector3d xa = pose_arg(a, "a"), xb = pose_arg(b, "b");
            py::gil_scoped_release release;
            return self.closeness(p, xa, xb);
          },
          py::arg("points"), py::arg("a"), py::arg("b"),
          "Vuong's statistic of poses a and b (3,) for points (N, 2): the sum of the points' log p(a) -\n"
          "log p(b) over its standard error (standard normal when both explain the scan equally well).");

  define_laser_options(m);
  define_laser_results(m);

  using ISM = IncrementalScanMatcher;
  auto ism = mapper_class<ISM>(
      m, "IncrementalScanMatcher",
      "Each scan matched against the map built so far (incremental scan matching into local submaps).\n"
      "\n"
      "IncrementalScanMatcher(*, options=None, **fields):\n"
      "    options: an IncrementalScanMatcherOptions (None: the defaults); **fields set fields of it by name\n"
      "        (resolution=0.1, filter={\"max_range\": 8.0}, update=UpdateTrigger(distance=0.1)).\n"
      "Errors name the field's path (\"filter.max_range\"). A failed call (add_scans included) changes nothing.");
  def_options_init<ISM, IncrementalScanMatcherOptions>(ism, "IncrementalScanMatcher", "IncrementalScanMatcherOptions");
  define_persistence<ISM>(ism);
  ism.def_property_readonly("num_scans", getter(&ISM::num_scans), "Scans added.")
      .def_property_readonly("pose", [](const ISM& self) {
        return locked(self, [&] {
          return self.num_scans() ? Eigen::Vector3d(self.estimates().back().pose) : Eigen::Vector3d::Zero().eval();
        });
      }, "(3,) the last scan's estimated pose (m, m, rad); zeros before the first scan.")
      .def_property_readonly("scan_poses", [](const ISM& self) { return locked(self, [&] { return estimate_poses(self); }); },
                             "(S, 3) estimated pose of every scan (m, m, rad).")
      .def_property_readonly("timestamps", [](const ISM& self) { return locked(self, [&] { return timestamps_of(self); }); },
                             "(S,) scan timestamps, seconds.")
      .def_property_readonly("scan_info", [](const ISM& self) { return locked(self, [&] { return scan_info(self); }); },
                             "(S, 5) per scan: matched, fallback, submap, match_quality, points.")
      .def_property_readonly("num_submaps", [](const ISM& self) { return locked(self, [&] { return self.submaps().size(); }); },
                             "Local submaps started so far.")
      .def("__repr__", [](py::handle self) {
        const ISM& s = self.cast<const ISM&>();
        return repr_of(self, locked(s, [&] {
          return std::to_string(s.num_scans()) + " scans, " + std::to_string(s.submaps().size()) + " submaps";
        }));
      })
      .def("submap_grid", [](const ISM& self, IntArg k_arg) {
        const int k = k_arg.get("index");
        return locked(self, [&] {
          require(k >= 0 && k < static_cast<int>(self.submaps().size()), "index", "is not a submap index");
          return self.submaps()[k].grid;
        });
      }, py::arg("index"), "A copy of submap index's OccupancyGrid2D.");

  using Slam = SubmapSlam2D;
  auto slam = mapper_class<Slam>(
      m, "SubmapSlam2D",
      "GraphSLAM over scan-matched submaps with correlative loop closures (ch. 11.7).\n"
      "probslam.slam.run_slam drives it from a log.\n"
      "\n"
      "SubmapSlam2D(*, options=None, **fields):\n"
      "    options: a SubmapSlamOptions (None: the defaults); **fields set fields of it by name\n"
      "        (closures={\"min_match_quality\": 0.7}, frontend=IncrementalScanMatcherOptions(resolution=0.1)).\n"
      "Errors name the field's path (\"closures.min_match_quality\"). A failed call (add_scans included)\n"
      "changes nothing.");
  def_options_init<Slam, SubmapSlamOptions>(slam, "SubmapSlam2D", "SubmapSlamOptions");
  define_persistence<Slam>(slam);
  slam.def("start_from_map",
           start_from_map_method<Slam>(),
           py::arg("map"), py::arg("initial_pose") = py::make_tuple(0.0, 0.0, 0.0),
           "Starts the run on a saved map, before the first scan: the map is submap 0, its node fixed\n"
           "at the map's origin (the run's frame is the map's); the first scan is matched against it\n"
           "around initial_pose (x, y, theta in the map's frame; a guess within the match window), the\n"
           "scans of the first stretch are matched against and inserted into a copy of it, and loop\n"
           "closures search it over its whole extent; map() draws every scan into it. ValueError\n"
           "naming map (scans already added, another resolution than the scan matcher's, no occupied\n"
           "cell) or initial_pose (not finite, outside the map); nothing changed then.")
      .def_property_readonly("start_map", [](const Slam& self) { return start_map_of(self); },
                             "A copy of the saved map the run started from (start_from_map), or None.")
      .def("finish", [](Slam& self) { locked(self, [&] { self.finish(); }); },
           "Closes the last submap, searches its loop closures and optimises the graph.")
      .def_property_readonly("num_scans", getter(&Slam::num_scans), "Scans added.")
      .def_property_readonly("num_submaps", getter(&Slam::num_submaps), "Submaps so far.")
      .def_property_readonly("pose", [](const Slam& self) {
        return locked(self, [&] {
          const std::vector<Eigen::Vector3d> p = self.scan_poses();
          return p.empty() ? Eigen::Vector3d::Zero().eval() : p.back();
        });
      }, "(3,) the last scan's optimised pose (m, m, rad); zeros before the first scan.")
      .def_property_readonly("scan_poses", [](const Slam& self) { return locked(self, [&] { return rows_of(self.scan_poses()); }); },
                             "(S, 3) optimised pose of every scan (m, m, rad).")
      .def_property_readonly("frontend_poses",
                             [](const Slam& self) { return locked(self, [&] { return estimate_poses(self.frontend()); }); },
                             "(S, 3) poses from scan matching alone.")
      .def_property_readonly("submap_poses", [](const Slam& self) { return locked(self, [&] { return rows_of(self.submap_poses()); }); },
                             "(N, 3) optimised submap origins.")
      .def_property_readonly("timestamps", [](const Slam& self) { return locked(self, [&] { return timestamps_of(self.frontend()); }); },
                             "(S,) scan timestamps, seconds.")
      .def_property_readonly("scan_info", [](const Slam& self) { return locked(self, [&] { return scan_info(self.frontend()); }); },
                             "(S, 5) per scan: matched, fallback, submap, match_quality, points.")
      .def("graph", [](const Slam& self) { return locked(self, [&] { return self.graph(); }); },
           "A copy of the submap pose graph (PoseGraph2D).")
      .def("map", [](const Slam& self, RealArg resolution_arg) {
        const double resolution = resolution_arg.get("resolution");
        return locked(self, [&] { return self.map(resolution); });
      }, py::arg("resolution") = 0.0,
           "Occupancy grid of every scan at its optimised pose; resolution m (0: the submaps').")
      .def("__repr__", [](py::handle self) {
        const Slam& s = self.cast<const Slam&>();
        return repr_of(self, locked(s, [&] {
          const SubmapSlamSummary sum = s.summary();
          return std::to_string(s.num_scans()) + " scans, " + std::to_string(s.num_submaps()) + " submaps, " +
                 std::to_string(sum.closures_accepted) + " loop closures";
        }));
      })
      .def_property_readonly("constraints", [](const Slam& self) {
        return constraint_arrays(locked(self, [&] { return self.constraints(); }));
      }, "SubmapConstraints: the constraints between submaps (C,) (measurement, covariance, loop, ...).")
      .def_property_readonly("summary", getter(&Slam::summary),
                             "SubmapSlamSummary: scans, submaps, matched_scans, closures searched / accepted /\n"
                             "rejected / dissolved, rounds, optimizations, final_chi2.")
      .def_property_readonly("timings", getter(&Slam::timings),
                             "SubmapSlamTimings: processor seconds per stage since construction or loading, and the\n"
                             "fields and matches built (not saved).")
      .def_property_readonly("memory", getter(&Slam::memory),
                             "SubmapSlamMemory: the bytes the large buffers hold, and their total.");

  using Rbpf = GridFastSlam;
  auto rbpf = mapper_class<Rbpf>(
      m, "GridFastSlam",
      "Grid-based FastSLAM from a raw laser log: particles with a pose, a log weight and their own\n"
      "occupancy grid (32 x 32-cell tiles shared copy-on-write).\n"
      "\n"
      "GridFastSlam(*, options=None, **fields):\n"
      "    options: a GridFastSlamOptions (None: the defaults); **fields set fields of it by name\n"
      "        (num_particles=50, proposal=\"motion\", likelihood={\"sigma\": 0.1}).\n"
      "Errors name the field's path (\"likelihood.sigma\"); a num_particles whose maps could exceed\n"
      "max_map_bytes raises ValueError. Results are identical for any thread count. A failed call\n"
      "(add_scans included) changes nothing.");
  def_options_init<Rbpf, GridFastSlamOptions>(rbpf, "GridFastSlam", "GridFastSlamOptions");
  define_persistence<Rbpf>(rbpf);
  rbpf.def_property_readonly("num_scans", getter(&Rbpf::num_scans), "Scans added.")
      .def_property_readonly("num_particles", getter(&Rbpf::num_particles), "M, the number of particles.")
      .def_property_readonly("pose", [](const Rbpf& self) {
        return locked(self, [&] { return Eigen::Vector3d(self.poses().row(self.best_index()).transpose()); });
      }, "(3,) the best particle's pose (m, m, rad).")
      .def_property_readonly("poses", [](const Rbpf& self) { return locked(self, [&] { return self.poses(); }); },
                             "(M, 3) particle poses (m, m, rad).")
      .def_property_readonly("log_weights", [](const Rbpf& self) { return locked(self, [&] { return self.log_weights(); }); },
                             "(M,) normalised log weights.")
      .def_property_readonly("best_index", getter(&Rbpf::best_index), "Index of the particle of highest weight.")
      .def_property_readonly("timestamps", [](const Rbpf& self) {
        return locked(self, [&] { return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(self.timestamps().data(), self.num_scans())); });
      }, "(S,) scan timestamps, seconds.")
      .def_property_readonly("scan_poses", [](const Rbpf& self) {
        return locked(self, [&] { return self.scan_poses(self.best_index()); });
      }, "(S, 3) every scan's pose along the best particle's path (path(particle) for another's).")
      .def("path", [](const Rbpf& self, py::handle particle) {
        const ParticleChoice k = ParticleChoice::from(particle);
        return locked(self, [&] { return self.scan_poses(k.resolve(self)); });
      }, py::arg("particle") = py::none(),
         "(S, 3) every scan's pose along a particle's path (default: the best particle's).")
      .def("start_from_map",
           start_from_map_method<Rbpf>(),
           py::arg("map"), py::arg("initial_pose") = py::make_tuple(0.0, 0.0, 0.0),
           "Starts the filter on a saved map, before the first scan: the run's frame is the map's; the\n"
           "first scan is placed by correlative matching against the map within the default window\n"
           "(0.3 m, 0.35 rad) around initial_pose (x, y, theta), and every particle's map starts as the\n"
           "saved map with that scan drawn in (tiles shared). ValueError naming map (scans already added,\n"
           "another resolution, no occupied cell) or initial_pose (not finite, outside the map).")
      .def_property_readonly("start_map", [](const Rbpf& self) { return start_map_of(self); },
                             "A copy of the saved map the filter started from (start_from_map), or None.")
      .def("map", [](const Rbpf& self, py::handle particle) {
        const ParticleChoice k = ParticleChoice::from(particle);
        return locked(self, [&] { return self.map(k.resolve(self)); });
      }, py::arg("particle") = py::none(), "A particle's map as a dense OccupancyGrid2D (default: the best particle's).")
      .def_property_readonly("tile_sharing", getter(&Rbpf::tile_sharing),
                             "TileSharing: references (tiles held over all particles), distinct (allocated), bytes.")
      .def_property_readonly("summary", getter(&Rbpf::summary),
                             "GridFastSlamSummary: scans, updates, resamples, matched, fallbacks, effective_sample_size.")
      .def_property_readonly("timings", getter(&Rbpf::timings),
                             "GridFastSlamTimings: processor seconds per stage since construction or loading (not saved).")
      .def("__repr__", [](py::handle self) {
        const Rbpf& s = self.cast<const Rbpf&>();
        return repr_of(self, locked(s, [&] {
          return std::to_string(s.num_particles()) + " particles, " + std::to_string(s.num_scans()) + " scans, best " +
                 std::to_string(s.best_index());
        }));
      });
}

}  // namespace probslam::bindings
