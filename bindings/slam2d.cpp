// Scan matching (slam2d/): thin conversions only. LikelihoodField and CorrelativeScanMatcher
// are immutable once built, so their calls need no object lock; long work releases the GIL.
#include <pybind11/stl.h>

#include <limits>
#include <string>

#include "numpy.hpp"
#include "object_lock.hpp"
#include "probslam/slam2d/correlative_scan_matcher.hpp"
#include "probslam/slam2d/likelihood_field.hpp"
#include "probslam/slam2d/range_scan.hpp"

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
                           double min_translation_std, double min_rotation_std) {
  MatchOptions o;
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
             double min_translation_std, double min_rotation_std) {
            const Points2 p = points_arg(points);
            const Eigen::Vector3d x0 = pose_arg(prior, "prior");
            const MatchOptions o = match_options(linear_window, angular_window, angular_step, prior_covariance,
                                                 refine, brute_force, min_translation_std, min_rotation_std);
            py::gil_scoped_release release;
            return self.match(p, x0, o);
          },
          py::arg("points"), py::arg("prior"), py::arg("linear_window") = 0.3, py::arg("angular_window") = 0.35,
          py::arg("angular_step") = 0.0, py::arg("prior_covariance") = py::none(), py::arg("refine") = true,
          py::arg("brute_force") = false, py::arg("min_translation_std") = 0.0, py::arg("min_rotation_std") = 0.0)
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
}

}  // namespace probslam::bindings
