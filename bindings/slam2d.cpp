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
  o.validate();
  return o;
}

/// The scan filter's keywords, shared by every laser SLAM class.
struct FilterArgs {
  RealArg max_range, min_range, max_usable_range;
  BoolArg clear_no_return;
  RealArg min_point_spacing;
  ScanFilter get() const {
    return {max_range.get("max_range"), min_range.get("min_range"), max_usable_range.get("max_usable_range"),
            clear_no_return.get("clear_no_return"), min_point_spacing.get("min_point_spacing")};
  }
};

auto filter_keywords(const ScanFilter& d) {
  return std::make_tuple(real_arg("max_range", d.max_range), real_arg("min_range", d.min_range),
                         real_arg("max_usable_range", d.max_usable_range),
                         py::arg_v("clear_no_return", d.clear_no_return), real_arg("min_point_spacing", d.min_point_spacing));
}

/// odometry_noise: the six OdometryNoise coefficients, in their declaration order.
OdometryNoise odometry_noise_arg(py::handle v) {
  const DoubleArray a = vector_arg(v, "odometry_noise", 6);
  return {a.data()[0], a.data()[1], a.data()[2], a.data()[3], a.data()[4], a.data()[5]};
}

py::tuple odometry_noise_default(const OdometryNoise& n) {
  return py::make_tuple(n.trans_per_metre, n.trans_per_radian, n.trans_floor, n.rot_per_radian, n.rot_per_metre,
                        n.rot_floor);
}

/// The frontend's keywords (IncrementalScanMatcher, and SubmapSlam2D's frontend), in signature order.
struct FrontendArgs {
  RealArg resolution;
  FilterArgs filter;
  RealArg sigma, p_rand, linear_window, angular_window;
  BoolArg refine, use_odometry_prior;
  py::handle odometry_noise;
  RealArg min_travel, min_rotation, submap_distance;
  IntArg submap_scans;
  RealArg min_match_quality;
  IntArg warmup_scans;
  RealArg field_refresh_distance, field_refresh_angle;
  BoolArg constant_velocity;
  RealArg match_fraction;

  IncrementalScanMatcherOptions get(IncrementalScanMatcherOptions o) const {
    o.resolution = resolution.get("resolution");
    o.filter = filter.get();
    o.field.sigma = sigma.get("sigma");
    o.field.p_rand = p_rand.get("p_rand");
    o.match.window.linear = linear_window.get("linear_window");
    o.match.window.angular = angular_window.get("angular_window");
    o.match.refine = refine.get("refine");
    o.use_odometry_prior = use_odometry_prior.get("use_odometry_prior");
    o.odometry = odometry_noise_arg(odometry_noise);
    o.min_travel = min_travel.get("min_travel");
    o.min_rotation = min_rotation.get("min_rotation");
    o.submap_distance = submap_distance.get("submap_distance");
    o.submap_scans = submap_scans.get("submap_scans");
    o.min_match_quality = min_match_quality.get("min_match_quality");
    o.warmup_scans = warmup_scans.get("warmup_scans");
    o.field_refresh_distance = field_refresh_distance.get("field_refresh_distance");
    o.field_refresh_angle = field_refresh_angle.get("field_refresh_angle");
    o.constant_velocity = constant_velocity.get("constant_velocity");
    o.match_fraction = match_fraction.get("match_fraction");
    return o;
  }
};

auto frontend_keywords(const IncrementalScanMatcherOptions& d) {
  return std::tuple_cat(
      std::make_tuple(real_arg("resolution", d.resolution)), filter_keywords(d.filter),
      std::make_tuple(real_arg("sigma", d.field.sigma), real_arg("p_rand", d.field.p_rand),
                      real_arg("linear_window", d.match.window.linear), real_arg("angular_window", d.match.window.angular),
                      py::arg_v("refine", d.match.refine), py::arg_v("use_odometry_prior", d.use_odometry_prior),
                      py::arg_v("odometry_noise", odometry_noise_default(d.odometry)),
                      real_arg("min_travel", d.min_travel), real_arg("min_rotation", d.min_rotation),
                      real_arg("submap_distance", d.submap_distance), py::arg_v("submap_scans", d.submap_scans),
                      real_arg("min_match_quality", d.min_match_quality), py::arg_v("warmup_scans", d.warmup_scans),
                      real_arg("field_refresh_distance", d.field_refresh_distance),
                      real_arg("field_refresh_angle", d.field_refresh_angle),
                      py::arg_v("constant_velocity", d.constant_velocity),
                      real_arg("match_fraction", d.match_fraction)));
}

constexpr double kBytesPerMiB = 1024.0 * 1024.0;

/// The loop closures' keywords of SubmapSlam2D (field_cache_mb in MiB; the C++ option is bytes).
struct ClosureArgs {
  BoolArg loop_closures;
  IntArg closure_scans_per_submap;
  RealArg closure_min_match_quality, closure_window_sigmas, closure_min_linear_window, closure_max_linear_window,
      closure_min_angular_window, closure_max_angular_window, closure_max_distance, dissolve_chi2, field_cache_mb;
  IntArg max_rounds;

  void get(SubmapSlamOptions& o) const {
    LoopClosureOptions& c = o.closures;
    c.enabled = loop_closures.get("loop_closures");
    c.scans_per_submap = closure_scans_per_submap.get("closure_scans_per_submap");
    c.min_match_quality = closure_min_match_quality.get("closure_min_match_quality");
    c.window_sigmas = closure_window_sigmas.get("closure_window_sigmas");
    c.min_linear_window = closure_min_linear_window.get("closure_min_linear_window");
    c.max_linear_window = closure_max_linear_window.get("closure_max_linear_window");
    c.min_angular_window = closure_min_angular_window.get("closure_min_angular_window");
    c.max_angular_window = closure_max_angular_window.get("closure_max_angular_window");
    c.max_distance = closure_max_distance.get("closure_max_distance");
    c.dissolve_chi2 = dissolve_chi2.get("dissolve_chi2");
    c.field_cache_bytes = field_cache_mb.get("field_cache_mb") * kBytesPerMiB;
    o.max_rounds = max_rounds.get("max_rounds");
  }
};

auto closure_keywords(const SubmapSlamOptions& d) {
  const LoopClosureOptions& c = d.closures;
  return std::make_tuple(
      py::arg_v("loop_closures", c.enabled), py::arg_v("closure_scans_per_submap", c.scans_per_submap),
      real_arg("closure_min_match_quality", c.min_match_quality), real_arg("closure_window_sigmas", c.window_sigmas),
      real_arg("closure_min_linear_window", c.min_linear_window),
      real_arg("closure_max_linear_window", c.max_linear_window),
      real_arg("closure_min_angular_window", c.min_angular_window),
      real_arg("closure_max_angular_window", c.max_angular_window), real_arg("closure_max_distance", c.max_distance),
      real_arg("dissolve_chi2", c.dissolve_chi2), real_arg("field_cache_mb", c.field_cache_bytes / kBytesPerMiB),
      py::arg_v("max_rounds", d.max_rounds));
}

GridProposal proposal_arg(const StrArg& v) {
  const std::string name = v.get("proposal");
  if (name == "motion") return GridProposal::kMotion;
  if (name == "scan-matching") return GridProposal::kScanMatching;
  if (name == "improved-odometry") return GridProposal::kImprovedOdometry;
  throw py::value_error("proposal must be 'motion', 'scan-matching' or 'improved-odometry', got '" + name + "'");
}

const char* proposal_name(GridProposal p) {
  switch (p) {
    case GridProposal::kMotion: return "motion";
    case GridProposal::kImprovedOdometry: return "improved-odometry";
    default: return "scan-matching";
  }
}

/// Defines a constructor whose keywords are the tuple `keywords` (py::arg_v each), after py::kw_only().
template <typename Class, typename Init, typename Keywords>
void keyword_init(Class& c, Init&& init, const Keywords& keywords, const char* doc) {
  std::apply([&](const auto&... k) { c.def(std::forward<Init>(init), py::kw_only(), k..., doc); }, keywords);
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
      .def_readonly("updates", &G::updates, "Filter updates (scans after update_distance / update_angle of travel).")
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
      .def(py::init([](ClassArg<OccupancyGrid2D> grid_arg, double sigma, double p_rand, double occupied_probability,
                       double max_distance, py::handle region) {
             const OccupancyGrid2D& grid = grid_arg.get("grid");
             const LikelihoodFieldOptions o{sigma, p_rand, occupied_probability, max_distance};
             if (region.is_none())
               return locked(grid, [&] { return LikelihoodField::from_grid(grid, o); });
             const Eigen::Vector4d box = fixed_vector<4>(region, "region");
             return locked(grid, [&] { return LikelihoodField::from_grid(grid, box, o); });
           }),
           py::arg("grid"), py::arg("sigma") = 0.05, py::arg("p_rand") = 0.05, py::arg("occupied_probability") = 0.5,
           py::arg("max_distance") = 0.0, py::arg("region") = py::none(),
           "From grid's cells with p > occupied_probability; sigma m; max_distance m (0: 6 sigma), the\n"
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
          "Score (sum of log p over points (N, 2) m, plus the prior term) at pose (3,) on the bilinear field.");

  define_laser_results(m);

  using ISM = IncrementalScanMatcher;
  const IncrementalScanMatcherOptions ism_defaults;
  auto ism = mapper_class<ISM>(
      m, "IncrementalScanMatcher",
      "Each scan matched against the map built so far (incremental scan matching into local submaps).\n"
      "\n"
      "IncrementalScanMatcher(*, options), every option a keyword (defaults in the signature):\n"
      "    resolution: cell side of the local maps, m.\n"
      "    max_range: the sensor's maximum, m (readings at or beyond it are no-returns).\n"
      "    min_range: closer readings (the robot's own body) are dropped, m.\n"
      "    max_usable_range: farther hits are not used; they clear free space up to it, m.\n"
      "    clear_no_return: no-return beams clear free space up to the usable range.\n"
      "    min_point_spacing: hits closer than this to the last kept one are dropped, m (0: keep all).\n"
      "    sigma: standard deviation of a hit around the nearest obstacle in the likelihood field, m.\n"
      "    p_rand: weight of the field's uniform part.\n"
      "    linear_window: half-width of the search window, m; angular_window: rad.\n"
      "    refine: Gauss-Newton on the interpolated field after the search.\n"
      "    use_odometry_prior: the odometry motion model enters the score.\n"
      "    odometry_noise: (6,) trans_per_metre (m/m), trans_per_radian (m/rad), trans_floor (m),\n"
      "        rot_per_radian (rad/rad), rot_per_metre (rad/m), rot_floor (rad) of the odometry model.\n"
      "    min_travel: m; min_rotation: rad; a scan is matched once the odometry moved or turned this\n"
      "        much since the last matched scan.\n"
      "    submap_distance: a new submap starts after this much travel, m (0: one map);\n"
      "        submap_scans: ... or this many matched scans (0: no limit).\n"
      "    min_match_quality: matches below this mean hit likelihood (0 .. 1) fall back to odometry.\n"
      "    warmup_scans: scans inserted into a new local map before matching starts against it.\n"
      "    field_refresh_distance: m; field_refresh_angle: rad; the local map's likelihood field is\n"
      "        rebuilt once the robot moved or turned this much since it was built (0: every scan).\n"
      "    constant_velocity: predict each scan's motion as the last matched one (a log without\n"
      "        odometry), not the odometry's.\n"
      "    match_fraction: hits beyond this fraction of the usable range are inserted, not matched\n"
      "        (the map's edge pulls them back), 0 < f <= 1.\n"
      "A failed call (add_scans included) changes nothing.");
  keyword_init(
      ism,
      py::init([](RealArg resolution, RealArg max_range, RealArg min_range, RealArg max_usable_range,
                  BoolArg clear_no_return, RealArg min_point_spacing, RealArg sigma, RealArg p_rand,
                  RealArg linear_window, RealArg angular_window, BoolArg refine, BoolArg use_odometry_prior,
                  py::handle odometry_noise, RealArg min_travel, RealArg min_rotation, RealArg submap_distance,
                  IntArg submap_scans, RealArg min_match_quality, IntArg warmup_scans, RealArg field_refresh_distance,
                  RealArg field_refresh_angle, BoolArg constant_velocity, RealArg match_fraction) {
        const FrontendArgs a{resolution, {max_range, min_range, max_usable_range, clear_no_return, min_point_spacing},
                             sigma, p_rand, linear_window, angular_window, refine, use_odometry_prior,
                             odometry_noise, min_travel, min_rotation, submap_distance, submap_scans,
                             min_match_quality, warmup_scans, field_refresh_distance, field_refresh_angle,
                             constant_velocity, match_fraction};
        const IncrementalScanMatcherOptions o = a.get(IncrementalScanMatcherOptions{});
        return std::make_unique<ISM>(o);
      }),
      frontend_keywords(ism_defaults), "Keyword options only: see the class docstring.");
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
  const SubmapSlamOptions slam_defaults;
  auto slam = mapper_class<Slam>(
      m, "SubmapSlam2D",
      "GraphSLAM over scan-matched submaps with correlative loop closures (ch. 11.7).\n"
      "probslam.slam.run_slam drives it from a log.\n"
      "\n"
      "SubmapSlam2D(*, options), every option a keyword (defaults in the signature): the\n"
      "IncrementalScanMatcher's (the frontend; submap_distance 10 m here) and the loop closures':\n"
      "    loop_closures: search for loop closures at all.\n"
      "    closure_scans_per_submap: scans of each finished submap matched against the older ones.\n"
      "    closure_min_match_quality: a closure needs this mean hit likelihood (0 .. 1).\n"
      "    closure_window_sigmas: the search window is this many standard deviations of the\n"
      "        predicted relative pose, within closure_min_linear_window .. closure_max_linear_window\n"
      "        (m) and closure_min_angular_window .. closure_max_angular_window (rad).\n"
      "    closure_max_distance: submaps predicted farther apart are not searched, m.\n"
      "    dissolve_chi2: a closure whose error in the optimised graph exceeds this chi2 (3 dof) is\n"
      "        dissolved.\n"
      "    field_cache_mb: MiB of submap likelihood fields kept for the search (least recently used\n"
      "        rebuilt).\n"
      "    max_rounds: rounds of search, optimisation and dissolution in finish().\n"
      "A failed call (add_scans included) changes nothing.");
  keyword_init(
      slam,
      py::init([](RealArg resolution, RealArg max_range, RealArg min_range, RealArg max_usable_range,
                  BoolArg clear_no_return, RealArg min_point_spacing, RealArg sigma, RealArg p_rand,
                  RealArg linear_window, RealArg angular_window, BoolArg refine, BoolArg use_odometry_prior,
                  py::handle odometry_noise, RealArg min_travel, RealArg min_rotation, RealArg submap_distance,
                  IntArg submap_scans, RealArg min_match_quality, IntArg warmup_scans, RealArg field_refresh_distance,
                  RealArg field_refresh_angle, BoolArg constant_velocity, RealArg match_fraction, BoolArg loop_closures, IntArg closure_scans_per_submap,
                  RealArg closure_min_match_quality, RealArg closure_window_sigmas, RealArg closure_min_linear_window,
                  RealArg closure_max_linear_window, RealArg closure_min_angular_window,
                  RealArg closure_max_angular_window, RealArg closure_max_distance, RealArg dissolve_chi2,
                  RealArg field_cache_mb, IntArg max_rounds) {
        const FrontendArgs a{resolution, {max_range, min_range, max_usable_range, clear_no_return, min_point_spacing},
                             sigma, p_rand, linear_window, angular_window, refine, use_odometry_prior,
                             odometry_noise, min_travel, min_rotation, submap_distance, submap_scans,
                             min_match_quality, warmup_scans, field_refresh_distance, field_refresh_angle,
                             constant_velocity, match_fraction};
        const ClosureArgs c{loop_closures, closure_scans_per_submap, closure_min_match_quality,
                            closure_window_sigmas, closure_min_linear_window, closure_max_linear_window,
                            closure_min_angular_window, closure_max_angular_window, closure_max_distance,
                            dissolve_chi2, field_cache_mb, max_rounds};
        SubmapSlamOptions o;
        o.frontend = a.get(o.frontend);
        c.get(o);
        return std::make_unique<Slam>(o);
      }),
      std::tuple_cat(frontend_keywords(slam_defaults.frontend), closure_keywords(slam_defaults)),
      "Keyword options only: see the class docstring.");
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
  const GridFastSlamOptions rbpf_defaults;
  auto rbpf = mapper_class<Rbpf>(
      m, "GridFastSlam",
      "Grid-based FastSLAM from a raw laser log: particles with a pose, a log weight and their own\n"
      "occupancy grid (32 x 32-cell tiles shared copy-on-write).\n"
      "\n"
      "GridFastSlam(*, options), every option a keyword (defaults in the signature):\n"
      "    num_particles: M.\n"
      "    proposal: \"scan-matching\" (Grisetti et al. 2007), \"motion\" (the odometry motion model) or\n"
      "        \"improved-odometry\" (Haehnel et al. 2003).\n"
      "    resolution: cell side of the particles' maps, m.\n"
      "    max_range, min_range, max_usable_range (m), clear_no_return, min_point_spacing (m): the scan\n"
      "        filter, as IncrementalScanMatcher's.\n"
      "    odometry_noise: (6,) the odometry model's coefficients, as IncrementalScanMatcher's.\n"
      "    sigma: standard deviation of a hit around the nearest obstacle, m; p_rand: weight of the\n"
      "        uniform part; search_radius: obstacles farther than this count as none, m.\n"
      "    linear_step (m), angular_step (rad): the proposal's first hill-climbing steps; refinements:\n"
      "        step halvings; sample_linear (m), sample_angular (rad): spacing of its evaluation poses.\n"
      "    min_match_quality: a match below this mean hit likelihood (0 .. 1) falls back to the motion\n"
      "        model.\n"
      "    corrected_start: the climb starts from the odometry corrected by incremental scan matching.\n"
      "    resample_threshold: resample when N_eff < resample_threshold * M, in [0, 1].\n"
      "    weight_scale: each update's log weight increment is multiplied by this, in (0, 1] (tempered\n"
      "        weights: a scan's beams are not independent).\n"
      "    update_distance (m), update_angle (rad): the filter updates once the odometry moved or\n"
      "        turned this much since the last update.\n"
      "    corrector_submap_distance: submap length of the odometry corrector, m.\n"
      "    seed: int in [0, 2^64); threads: worker threads (results identical for any count).\n"
      "    max_map_bytes: bytes; the particles' maps with the worst case of the next update; a\n"
      "        num_particles or an update that could exceed it raises ValueError.\n"
      "A failed call (add_scans included) changes nothing.");
  keyword_init(
      rbpf,
      py::init([](IntArg num_particles, StrArg proposal, RealArg resolution, RealArg max_range, RealArg min_range,
                  RealArg max_usable_range, BoolArg clear_no_return, RealArg min_point_spacing,
                  py::handle odometry_noise, RealArg sigma, RealArg p_rand, RealArg search_radius, RealArg linear_step,
                  RealArg angular_step, IntArg refinements, RealArg sample_linear, RealArg sample_angular,
                  RealArg min_match_quality, BoolArg corrected_start, RealArg resample_threshold, RealArg weight_scale,
                  RealArg update_distance, RealArg update_angle, RealArg corrector_submap_distance, UInt64Arg seed,
                  IntArg threads, RealArg max_map_bytes) {
        GridFastSlamOptions o;
        o.num_particles = num_particles.get("num_particles");
        o.proposal = proposal_arg(proposal);
        o.resolution = resolution.get("resolution");
        o.filter = FilterArgs{max_range, min_range, max_usable_range, clear_no_return, min_point_spacing}.get();
        o.odometry = odometry_noise_arg(odometry_noise);
        o.likelihood.sigma = sigma.get("sigma");
        o.likelihood.p_rand = p_rand.get("p_rand");
        o.likelihood.search_radius = search_radius.get("search_radius");
        o.matching.linear_step = linear_step.get("linear_step");
        o.matching.angular_step = angular_step.get("angular_step");
        o.matching.refinements = refinements.get("refinements");
        o.matching.sample_linear = sample_linear.get("sample_linear");
        o.matching.sample_angular = sample_angular.get("sample_angular");
        o.matching.min_quality = min_match_quality.get("min_match_quality");
        o.corrected_start = corrected_start.get("corrected_start");
        o.resample_threshold = resample_threshold.get("resample_threshold");
        o.weight_scale = weight_scale.get("weight_scale");
        o.update_distance = update_distance.get("update_distance");
        o.update_angle = update_angle.get("update_angle");
        o.corrector.submap_distance = corrector_submap_distance.get("corrector_submap_distance");
        o.seed = seed.get("seed");
        o.threads = threads.get("threads");
        o.max_map_bytes = max_map_bytes.get("max_map_bytes");
        // The corrector sees the scans as the filter does.
        o.corrector.resolution = o.resolution;
        o.corrector.filter = o.filter;
        o.corrector.odometry = o.odometry;
        return std::make_unique<Rbpf>(o);
      }),
      std::make_tuple(
          py::arg_v("num_particles", rbpf_defaults.num_particles),
          py::arg_v("proposal", std::string(proposal_name(rbpf_defaults.proposal))),
          real_arg("resolution", rbpf_defaults.resolution), real_arg("max_range", rbpf_defaults.filter.max_range),
          real_arg("min_range", rbpf_defaults.filter.min_range),
          real_arg("max_usable_range", rbpf_defaults.filter.max_usable_range),
          py::arg_v("clear_no_return", rbpf_defaults.filter.clear_no_return),
          real_arg("min_point_spacing", rbpf_defaults.filter.min_point_spacing),
          py::arg_v("odometry_noise", odometry_noise_default(rbpf_defaults.odometry)),
          real_arg("sigma", rbpf_defaults.likelihood.sigma), real_arg("p_rand", rbpf_defaults.likelihood.p_rand),
          real_arg("search_radius", rbpf_defaults.likelihood.search_radius),
          real_arg("linear_step", rbpf_defaults.matching.linear_step),
          real_arg("angular_step", rbpf_defaults.matching.angular_step),
          py::arg_v("refinements", rbpf_defaults.matching.refinements),
          real_arg("sample_linear", rbpf_defaults.matching.sample_linear),
          real_arg("sample_angular", rbpf_defaults.matching.sample_angular),
          real_arg("min_match_quality", rbpf_defaults.matching.min_quality),
          py::arg_v("corrected_start", rbpf_defaults.corrected_start),
          real_arg("resample_threshold", rbpf_defaults.resample_threshold),
          real_arg("weight_scale", rbpf_defaults.weight_scale),
          real_arg("update_distance", rbpf_defaults.update_distance),
          real_arg("update_angle", rbpf_defaults.update_angle),
          real_arg("corrector_submap_distance", rbpf_defaults.corrector.submap_distance),
          py::arg_v("seed", rbpf_defaults.seed), py::arg_v("threads", rbpf_defaults.threads),
          real_arg("max_map_bytes", rbpf_defaults.max_map_bytes)),
      "Keyword options only: see the class docstring.");
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
