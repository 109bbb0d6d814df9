// Scan matching (slam2d/): thin conversions only. LikelihoodField and CorrelativeScanMatcher
// are immutable once built, so their calls need no object lock; long work releases the GIL.
#include <pybind11/stl.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <string>

#include "kwargs.hpp"
#include "numpy.hpp"
#include "probslam/core/check.hpp"
#include "object_lock.hpp"
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
void scan_filter_options(Kwargs& k, ScanFilter& f) {
  k.get("max_range", f.max_range);
  k.get("min_range", f.min_range);
  k.get("max_usable_range", f.max_usable_range);
  k.get("clear_no_return", f.clear_no_return);
  k.get("min_point_spacing", f.min_point_spacing);
}

/// odometry_noise: the six OdometryNoise coefficients, in their declaration order.
void odometry_noise_option(Kwargs& k, OdometryNoise& n) {
  if (const py::handle v = k.take("odometry_noise"); v && !v.is_none()) {
    const DoubleArray a = vector_arg(v, "odometry_noise", 6);
    n = {a.data()[0], a.data()[1], a.data()[2], a.data()[3], a.data()[4], a.data()[5]};
  }
}

/// The frontend's options (IncrementalScanMatcher, and SubmapSlam2D's frontend) by keyword.
IncrementalScanMatcherOptions frontend_options(Kwargs& k, IncrementalScanMatcherOptions o = {}) {
  k.get("resolution", o.resolution);
  scan_filter_options(k, o.filter);
  k.get("sigma", o.field.sigma);
  k.get("p_rand", o.field.p_rand);
  k.get("linear_window", o.match.window.linear);
  k.get("angular_window", o.match.window.angular);
  k.get("refine", o.match.refine);
  k.get("use_odometry_prior", o.use_odometry_prior);
  odometry_noise_option(k, o.odometry);
  k.get("min_travel", o.min_travel);
  k.get("min_rotation", o.min_rotation);
  k.get("submap_distance", o.submap_distance);
  k.get("submap_scans", o.submap_scans);
  k.get("min_match_quality", o.min_match_quality);
  k.get("warmup_scans", o.warmup_scans);
  k.get("field_refresh_distance", o.field_refresh_distance);
  k.get("field_refresh_angle", o.field_refresh_angle);
  return o;
}

SubmapSlamOptions slam_options(Kwargs& k) {
  SubmapSlamOptions o;
  o.frontend = frontend_options(k, o.frontend);
  LoopClosureOptions& c = o.closures;
  k.get("loop_closures", c.enabled);
  k.get("closure_scans_per_submap", c.scans_per_submap);
  k.get("closure_min_match_quality", c.min_match_quality);
  k.get("closure_window_sigmas", c.window_sigmas);
  k.get("closure_min_linear_window", c.min_linear_window);
  k.get("closure_max_linear_window", c.max_linear_window);
  k.get("closure_min_angular_window", c.min_angular_window);
  k.get("closure_max_angular_window", c.max_angular_window);
  k.get("closure_max_distance", c.max_distance);
  k.get("dissolve_chi2", c.dissolve_chi2);
  double cache_mb = c.field_cache_bytes / (1024.0 * 1024.0);
  k.get("field_cache_mb", cache_mb);
  c.field_cache_bytes = cache_mb * 1024.0 * 1024.0;
  k.get("max_rounds", o.max_rounds);
  return o;
}

/// GridFastSlam's options by keyword (particles, proposal as a string, the rest as named).
GridFastSlamOptions rbpf_options(Kwargs& k) {
  GridFastSlamOptions o;
  k.get("num_particles", o.num_particles);
  if (const py::handle v = k.take("proposal"); v && !v.is_none()) {
    if (!py::isinstance<py::str>(v)) throw py::type_error("proposal must be a str");
    const std::string name = v.cast<std::string>();
    if (name == "motion") o.proposal = GridProposal::kMotion;
    else if (name == "scan-matching") o.proposal = GridProposal::kScanMatching;
    else if (name == "improved-odometry") o.proposal = GridProposal::kImprovedOdometry;
    else throw py::value_error("proposal must be 'motion', 'scan-matching' or 'improved-odometry', got '" + name + "'");
  }
  k.get("resolution", o.resolution);
  scan_filter_options(k, o.filter);
  odometry_noise_option(k, o.odometry);
  k.get("sigma", o.likelihood.sigma);
  k.get("p_rand", o.likelihood.p_rand);
  k.get("search_radius", o.likelihood.search_radius);
  k.get("linear_step", o.matching.linear_step);
  k.get("angular_step", o.matching.angular_step);
  k.get("refinements", o.matching.refinements);
  k.get("sample_linear", o.matching.sample_linear);
  k.get("sample_angular", o.matching.sample_angular);
  k.get("min_match_quality", o.matching.min_quality);
  k.get("corrected_start", o.corrected_start);
  k.get("resample_threshold", o.resample_threshold);
  k.get("weight_scale", o.weight_scale);
  k.get("update_distance", o.update_distance);
  k.get("update_angle", o.update_angle);
  k.get("corrector_submap_distance", o.corrector.submap_distance);
  k.get("seed", o.seed);
  k.get("threads", o.threads);
  k.get("max_map_bytes", o.max_map_bytes);
  // The corrector sees the scans as the filter does.
  o.corrector.resolution = o.resolution;
  o.corrector.filter = o.filter;
  o.corrector.odometry = o.odometry;
  return o;
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

/// The keyword constructor (options parsed by `parse`, unknown keywords a TypeError) and
/// add_scans of a laser SLAM class.
template <typename Mapper, typename Parse>
py::class_<Mapper> mapper_class(py::module_& m, const char* name, const char* doc, Parse parse) {
  py::class_<Mapper> c(m, name, doc);
  c.def(py::init([parse](const py::kwargs& kw) {
     Kwargs k(kw);
     const auto o = parse(k);
     k.finish();
     return std::make_unique<Mapper>(o);
   }), "Keyword options only: see the class docstring.")
      .def("add_scans", &add_scans<Mapper>, py::arg("ranges"), py::arg("beam_angles"), py::arg("odometry"),
           py::arg("timestamps"),
           "Adds scans in order: ranges (S, B) m, beam_angles (B,) or (S, B) rad relative to the sensor's\n"
           "heading, odometry (S, 3) sensor poses (m, m, rad), timestamps (S,) s. Every row is checked\n"
           "before the first is used.");
  return c;
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
      .def(py::init([](const OccupancyGrid2D& grid, double sigma, double p_rand, double occupied_probability,
                       double max_distance, py::handle region) {
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
      .def(py::init([](const LikelihoodField& field, IntArg max_level_arg) {
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

  using ISM = IncrementalScanMatcher;
  mapper_class<ISM>(m, "IncrementalScanMatcher",
                    "Each scan matched against the map built so far (incremental scan matching into local\n"
                    "submaps). Keyword options: resolution (m), max_range, min_range, max_usable_range (m),\n"
                    "clear_no_return, min_point_spacing (m), sigma (m), p_rand, linear_window (m), angular_window\n"
                    "(rad), refine, use_odometry_prior, odometry_noise (6,), min_travel (m), min_rotation (rad),\n"
                    "submap_distance (m), submap_scans, min_match_quality, warmup_scans, field_refresh_distance (m),\n"
                    "field_refresh_angle (rad).",
                    [](Kwargs& k) { return frontend_options(k); })
      .def_property_readonly("num_scans", getter(&ISM::num_scans), "Scans added.")
      .def_property_readonly("poses", [](const ISM& self) { return locked(self, [&] { return estimate_poses(self); }); },
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
  mapper_class<Slam>(m, "SubmapSlam2D",
                     "GraphSLAM over scan-matched submaps with correlative loop closures (ch. 11.7): the\n"
                     "IncrementalScanMatcher's keyword options (submap_distance default 10 m) and loop_closures,\n"
                     "closure_scans_per_submap, closure_min_match_quality, closure_window_sigmas,\n"
                     "closure_{min,max}_{linear,angular}_window (m, rad), closure_max_distance (m), dissolve_chi2,\n"
                     "max_rounds, field_cache_mb. probslam.slam.run_slam drives it from a log.",
                     slam_options)
      .def("finish", [](Slam& self) { locked(self, [&] { self.finish(); }); },
           "Closes the last submap, searches its loop closures and optimises the graph.")
      .def_property_readonly("num_scans", getter(&Slam::num_scans), "Scans added.")
      .def_property_readonly("num_submaps", getter(&Slam::num_submaps), "Submaps so far.")
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
      .def("map", [](const Slam& self, double resolution) { return locked(self, [&] { return self.map(resolution); }); },
           py::arg("resolution") = 0.0,
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
        const std::vector<SubmapConstraint> cs = locked(self, [&] { return self.constraints(); });
        const auto n = static_cast<py::ssize_t>(cs.size());
        py::array_t<int> from(n), to(n), scan(n);
        py::array_t<bool> loop(n), active(n);
        py::array_t<double> z({n, py::ssize_t(3)}), cov({n, py::ssize_t(3), py::ssize_t(3)}), quality(n);
        for (py::ssize_t k = 0; k < n; ++k) {
          const SubmapConstraint& c = cs[static_cast<std::size_t>(k)];
          from.mutable_at(k) = c.from, to.mutable_at(k) = c.to, scan.mutable_at(k) = c.scan;
          loop.mutable_at(k) = c.loop, active.mutable_at(k) = c.active, quality.mutable_at(k) = c.match_quality;
          for (int i = 0; i < 3; ++i) {
            z.mutable_at(k, i) = c.measurement[i];
            for (int j = 0; j < 3; ++j) cov.mutable_at(k, i, j) = c.covariance(i, j);
          }
        }
        py::dict d;
        d["from"] = from, d["to"] = to, d["measurement"] = z, d["covariance"] = cov, d["loop"] = loop;
        d["scan"] = scan, d["match_quality"] = quality, d["active"] = active;
        return d;
      },
      "Dict of (C,) arrays over the constraints between submaps: from, to, measurement (C, 3),\n"
      "covariance (C, 3, 3), loop, scan, match_quality, active.")
      .def_property_readonly("summary", [](const Slam& self) {
        const SubmapSlamSummary s = locked(self, [&] { return self.summary(); });
        py::dict d;
        d["scans"] = s.scans, d["submaps"] = s.submaps, d["matched_scans"] = s.matched_scans;
        d["closures_searched"] = s.closures_searched, d["closures_accepted"] = s.closures_accepted;
        d["closures_rejected"] = s.closures_rejected, d["closures_dissolved"] = s.closures_dissolved;
        d["rounds"] = s.rounds, d["optimizations"] = s.optimizations, d["final_chi2"] = s.final_chi2;
        return d;
      },
      "Dict: scans, submaps, matched_scans, closures_searched / accepted / rejected / dissolved, rounds,\n"
      "optimizations, final_chi2.");

  using Rbpf = GridFastSlam;
  // The particle argument is read with the GIL held; resolved (None: the best) under the lock.
  auto particle_arg = [](py::handle k) -> long long {
    if (k.is_none()) return -1;
    const long long i = index_value(k, "particle");
    if (i < 0) throw py::value_error("particle must be in [0, num_particles)");
    return i;
  };
  auto resolve = [](const Rbpf& self, long long k) {
    if (k < 0) return self.best_index();
    require(k < self.num_particles(), "particle", "must be in [0, num_particles)");
    return static_cast<int>(k);
  };
  mapper_class<Rbpf>(m, "GridFastSlam",
                     "Grid-based FastSLAM from a raw laser log: particles with a pose, a log weight and their own\n"
                     "occupancy grid (32 x 32-cell tiles shared copy-on-write). Keyword options: num_particles (30),\n"
                     "proposal (\"scan-matching\" (default), \"motion\", \"improved-odometry\"), resolution (m, 0.05),\n"
                     "max_range, min_range, max_usable_range (m), clear_no_return, min_point_spacing (m),\n"
                     "odometry_noise (6,), sigma (m, 0.05), p_rand (0.05), search_radius (m, 0.3), linear_step (m),\n"
                     "angular_step (rad), refinements, sample_linear (m), sample_angular (rad), min_match_quality\n"
                     "(0.3), weight_scale (0.03: tempered weights), resample_threshold (0.5), update_distance (m,\n"
                     "0.25), update_angle (rad, 0.25), corrector_submap_distance (m, 5), corrected_start (True), seed\n"
                     "(int >= 0), threads, max_map_bytes (bytes, 8 GiB: the particles' maps with the worst case of the\n"
                     "next update; a num_particles or an update that could exceed it raises ValueError). Results are\n"
                     "identical for any thread count. A failed call (add_scans included) changes nothing.",
                     rbpf_options)
      .def_property_readonly("num_scans", getter(&Rbpf::num_scans), "Scans added.")
      .def_property_readonly("num_particles", getter(&Rbpf::num_particles), "M, the number of particles.")
      .def_property_readonly("poses", [](const Rbpf& self) { return locked(self, [&] { return self.poses(); }); },
                             "(M, 3) particle poses (m, m, rad).")
      .def_property_readonly("log_weights", [](const Rbpf& self) { return locked(self, [&] { return self.log_weights(); }); },
                             "(M,) normalised log weights.")
      .def_property_readonly("best_index", getter(&Rbpf::best_index), "Index of the particle of highest weight.")
      .def_property_readonly("timestamps", [](const Rbpf& self) {
        return locked(self, [&] { return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(self.timestamps().data(), self.num_scans())); });
      }, "(S,) scan timestamps, seconds.")
      .def("scan_poses", [particle_arg, resolve](const Rbpf& self, py::handle particle) {
        const long long k = particle_arg(particle);
        return locked(self, [&] { return self.scan_poses(resolve(self, k)); });
      }, py::arg("particle") = py::none(),
         "(S, 3) every scan's pose along a particle's path (default: the heaviest).")
      .def("map", [particle_arg, resolve](const Rbpf& self, py::handle particle) {
        const long long k = particle_arg(particle);
        return locked(self, [&] { return self.map(resolve(self, k)); });
      }, py::arg("particle") = py::none(), "A particle's map as a dense OccupancyGrid2D (default: the heaviest).")
      .def_property_readonly("tile_sharing", [](const Rbpf& self) {
        const TileSharing t = locked(self, [&] { return self.tile_sharing(); });
        py::dict d;
        d["references"] = t.references, d["distinct"] = t.distinct, d["bytes"] = t.bytes;
        return d;
      }, "Dict: references (tiles held over all particles), distinct (allocated), bytes (of the distinct).")
      .def_property_readonly("summary", [](const Rbpf& self) {
        const GridFastSlamSummary s = locked(self, [&] { return self.summary(); });
        py::dict d;
        d["scans"] = s.scans, d["updates"] = s.updates, d["resamples"] = s.resamples, d["matched"] = s.matched;
        d["fallbacks"] = s.fallbacks, d["effective_sample_size"] = s.effective_sample_size;
        return d;
      }, "Dict: scans, updates, resamples, matched, fallbacks, effective_sample_size.")
      .def("__repr__", [](py::handle self) {
        const Rbpf& s = self.cast<const Rbpf&>();
        return repr_of(self, locked(s, [&] {
          return std::to_string(s.num_particles()) + " particles, " + std::to_string(s.num_scans()) + " scans, best " +
                 std::to_string(s.best_index());
        }));
      });
}

}  // namespace probslam::bindings
