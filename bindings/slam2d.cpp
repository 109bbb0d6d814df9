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
  // The corrector sees the scans as the filter does.
  o.corrector.resolution = o.resolution;
  o.corrector.filter = o.filter;
  o.corrector.odometry = o.odometry;
  return o;
}

/// add_scans of IncrementalScanMatcher and SubmapSlam2D: every row is checked before the first
/// scan is added, so a bad batch changes nothing.
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
  if (!O.allFinite()) throw py::value_error("odometry must contain only finite values");
  if (!as_vector(a).allFinite()) throw py::value_error("beam_angles must contain only finite values");
  if (T.hasNaN()) throw py::value_error("timestamps must not contain NaN");
  locked(self, [&] {
    for (py::ssize_t k = 0; k < S; ++k) {
      const Eigen::Map<const Eigen::VectorXd> ang(a.data() + (per_scan ? k * B : 0), B);
      self.add_scan(R.row(k).transpose(), ang, O.row(k).transpose(), T[k]);
    }
  });
}

/// The keyword constructor (options parsed by `parse`, unknown keywords a TypeError) and
/// add_scans of a laser SLAM class.
template <typename Mapper, typename Parse>
py::class_<Mapper> mapper_class(py::module_& m, const char* name, Parse parse) {
  py::class_<Mapper> c(m, name);
  c.def(py::init([parse](const py::kwargs& kw) {
     Kwargs k(kw);
     const auto o = parse(k);
     k.finish();
     return std::make_unique<Mapper>(o);
   }))
      .def("add_scans", &add_scans<Mapper>, py::arg("ranges"), py::arg("beam_angles"), py::arg("odometry"),
           py::arg("timestamps"));
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
      py::arg("max_usable_range") = 30.0, py::arg("min_point_spacing") = 0.0);
  m.def(
      "ranges_for_insertion",
      [](py::handle ranges, double max_range, double min_range, double max_usable_range, bool clear_no_return) {
        const DoubleArray r = vector_arg(ranges, "ranges");
        const ScanFilter f = filter_args(max_range, min_range, max_usable_range, clear_no_return, 0.0);
        return py::make_tuple(ranges_for_insertion(as_vector(r), f), f.usable_range());
      },
      py::arg("ranges"), py::arg("max_range") = inf, py::arg("min_range") = 0.0, py::arg("max_usable_range") = 30.0,
      py::arg("clear_no_return") = true);

  py::class_<LikelihoodField>(m, "LikelihoodField")
      .def(py::init([](const OccupancyGrid2D& grid, double sigma, double p_rand, double occupied_probability,
                       double max_distance, py::handle region) {
             const LikelihoodFieldOptions o{sigma, p_rand, occupied_probability, max_distance};
             if (region.is_none())
               return locked(grid, [&] { return LikelihoodField::from_grid(grid, o); });
             const Eigen::Vector4d box = fixed_vector<4>(region, "region");
             return locked(grid, [&] { return LikelihoodField::from_grid(grid, box, o); });
           }),
           py::arg("grid"), py::arg("sigma") = 0.05, py::arg("p_rand") = 0.05, py::arg("occupied_probability") = 0.5,
           py::arg("max_distance") = 0.0, py::arg("region") = py::none())
      .def_property_readonly("resolution", &LikelihoodField::resolution)
      .def_property_readonly("origin", &LikelihoodField::origin)
      .def_property_readonly("shape", [](const LikelihoodField& f) { return py::make_tuple(f.height(), f.width()); })
      .def_property_readonly("num_occupied", &LikelihoodField::num_occupied)
      .def_property_readonly("floor_value", &LikelihoodField::floor_value)
      .def_property_readonly("sigma", [](const LikelihoodField& f) { return f.options().sigma; })
      .def_property_readonly("p_rand", [](const LikelihoodField& f) { return f.options().p_rand; })
      .def_property_readonly("truncation", [](const LikelihoodField& f) { return f.options().truncation(); })
      .def_property_readonly("distance", [](const LikelihoodField& f) { return FloatImage(f.distance()); })
      .def_property_readonly("log_likelihood", [](const LikelihoodField& f) { return FloatImage(f.log_likelihood()); })
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
          py::arg("points"));

  py::class_<MatchResult>(m, "MatchResult")
      .def_readonly("found", &MatchResult::found)
      .def_readonly("pose", &MatchResult::pose)
      .def_readonly("search_pose", &MatchResult::search_pose)
      .def_readonly("covariance", &MatchResult::covariance)
      .def_readonly("score", &MatchResult::score)
      .def_readonly("search_score", &MatchResult::search_score)
      .def_readonly("match_quality", &MatchResult::match_quality)
      .def_readonly("num_points", &MatchResult::num_points)
      .def_readonly("candidates_scored", &MatchResult::candidates_scored)
      .def_readonly("angular_steps", &MatchResult::angular_steps)
      .def_readonly("angular_step", &MatchResult::angular_step)
      .def("__repr__", [](const MatchResult& r) {
        return "MatchResult(pose=(" + std::to_string(r.pose.x()) + ", " + std::to_string(r.pose.y()) + ", " +
               std::to_string(r.pose.z()) + "), score=" + std::to_string(r.score) +
               ", match_quality=" + std::to_string(r.match_quality) + ")";
      });

  py::class_<CorrelativeScanMatcher>(m, "CorrelativeScanMatcher")
      .def(py::init([](const LikelihoodField& field, int max_level) {
             py::gil_scoped_release release;
             return CorrelativeScanMatcher(field, max_level);
           }),
           py::arg("field"), py::arg("max_level") = 6)
      .def_property_readonly("max_level", &CorrelativeScanMatcher::max_level)
      .def_property_readonly("field", &CorrelativeScanMatcher::field)
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
          py::arg("min_score") = -std::numeric_limits<double>::infinity())
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
          py::arg("points"), py::arg("pose"), py::arg("prior") = py::none(), py::arg("prior_covariance") = py::none());

  using ISM = IncrementalScanMatcher;
  mapper_class<ISM>(m, "IncrementalScanMatcher", [](Kwargs& k) { return frontend_options(k); })
      .def_property_readonly("num_scans", getter(&ISM::num_scans))
      .def_property_readonly("poses", [](const ISM& self) { return locked(self, [&] { return estimate_poses(self); }); })
      .def_property_readonly("timestamps", [](const ISM& self) { return locked(self, [&] { return timestamps_of(self); }); })
      .def_property_readonly("scan_info", [](const ISM& self) { return locked(self, [&] { return scan_info(self); }); })
      .def_property_readonly("num_submaps", [](const ISM& self) { return locked(self, [&] { return self.submaps().size(); }); })
      .def("submap_grid", [](const ISM& self, int k) {
        return locked(self, [&] {
          require(k >= 0 && k < static_cast<int>(self.submaps().size()), "index", "is not a submap index");
          return self.submaps()[k].grid;
        });
      }, py::arg("index"));

  using Slam = SubmapSlam2D;
  mapper_class<Slam>(m, "SubmapSlam2D", slam_options)
      .def("finish", [](Slam& self) { locked(self, [&] { self.finish(); }); })
      .def_property_readonly("num_scans", getter(&Slam::num_scans))
      .def_property_readonly("num_submaps", getter(&Slam::num_submaps))
      .def_property_readonly("scan_poses", [](const Slam& self) { return locked(self, [&] { return rows_of(self.scan_poses()); }); })
      .def_property_readonly("frontend_poses",
                             [](const Slam& self) { return locked(self, [&] { return estimate_poses(self.frontend()); }); })
      .def_property_readonly("submap_poses", [](const Slam& self) { return locked(self, [&] { return rows_of(self.submap_poses()); }); })
      .def_property_readonly("timestamps", [](const Slam& self) { return locked(self, [&] { return timestamps_of(self.frontend()); }); })
      .def_property_readonly("scan_info", [](const Slam& self) { return locked(self, [&] { return scan_info(self.frontend()); }); })
      .def("graph", [](const Slam& self) { return locked(self, [&] { return self.graph(); }); })
      .def("map", [](const Slam& self, double resolution) { return locked(self, [&] { return self.map(resolution); }); },
           py::arg("resolution") = 0.0)
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
      })
      .def_property_readonly("summary", [](const Slam& self) {
        const SubmapSlamSummary s = locked(self, [&] { return self.summary(); });
        py::dict d;
        d["scans"] = s.scans, d["submaps"] = s.submaps, d["matched_scans"] = s.matched_scans;
        d["closures_searched"] = s.closures_searched, d["closures_accepted"] = s.closures_accepted;
        d["closures_rejected"] = s.closures_rejected, d["closures_dissolved"] = s.closures_dissolved;
        d["rounds"] = s.rounds, d["optimizations"] = s.optimizations, d["final_chi2"] = s.final_chi2;
        return d;
      });

  using Rbpf = GridFastSlam;
  // The particle argument is read with the GIL held; resolved (None: the best) under the lock.
  auto particle_arg = [](py::handle k) -> long long {
    if (k.is_none()) return -1;
    if (py::isinstance<py::bool_>(k) || !PyIndex_Check(k.ptr())) throw py::type_error("particle must be an int");
    const long long i = k.cast<long long>();
    if (i < 0) throw py::value_error("particle must be in [0, num_particles)");
    return i;
  };
  auto resolve = [](const Rbpf& self, long long k) {
    if (k < 0) return self.best_index();
    require(k < self.num_particles(), "particle", "must be in [0, num_particles)");
    return static_cast<int>(k);
  };
  mapper_class<Rbpf>(m, "GridFastSlam", rbpf_options)
      .def_property_readonly("num_scans", getter(&Rbpf::num_scans))
      .def_property_readonly("num_particles", getter(&Rbpf::num_particles))
      .def_property_readonly("poses", [](const Rbpf& self) { return locked(self, [&] { return self.poses(); }); })
      .def_property_readonly("log_weights", [](const Rbpf& self) { return locked(self, [&] { return self.log_weights(); }); })
      .def_property_readonly("best_index", getter(&Rbpf::best_index))
      .def_property_readonly("timestamps", [](const Rbpf& self) {
        return locked(self, [&] { return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(self.timestamps().data(), self.num_scans())); });
      })
      .def("scan_poses", [particle_arg, resolve](const Rbpf& self, py::handle particle) {
        const long long k = particle_arg(particle);
        return locked(self, [&] { return self.scan_poses(resolve(self, k)); });
      }, py::arg("particle") = py::none())
      .def("map", [particle_arg, resolve](const Rbpf& self, py::handle particle) {
        const long long k = particle_arg(particle);
        return locked(self, [&] { return self.map(resolve(self, k)); });
      }, py::arg("particle") = py::none())
      .def_property_readonly("tile_sharing", [](const Rbpf& self) {
        const TileSharing t = locked(self, [&] { return self.tile_sharing(); });
        py::dict d;
        d["references"] = t.references, d["distinct"] = t.distinct, d["bytes"] = t.bytes;
        return d;
      })
      .def_property_readonly("summary", [](const Rbpf& self) {
        const GridFastSlamSummary s = locked(self, [&] { return self.summary(); });
        py::dict d;
        d["scans"] = s.scans, d["updates"] = s.updates, d["resamples"] = s.resamples, d["matched"] = s.matched;
        d["fallbacks"] = s.fallbacks, d["effective_sample_size"] = s.effective_sample_size;
        return d;
      });
}

}  // namespace probslam::bindings
