// SubmapSlamOptions: its checks and the defaults it takes from the frontend and the optimiser.
#include <cmath>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/slam2d/submap_slam.hpp"

namespace probslam {

void LoopClosureOptions::validate() const {
  require(scans_per_submap >= 1, "scans_per_submap", "must be >= 1");
  require(std::isfinite(min_match_quality) && min_match_quality >= 0.0 && min_match_quality <= 1.0,
          "min_match_quality", "must be in [0, 1]");
  require_positive(window_sigmas, "window_sigmas");
  require(std::isfinite(min_linear_window) && min_linear_window >= 0.0, "min_linear_window", "must be finite and >= 0");
  require(std::isfinite(max_linear_window) && max_linear_window >= min_linear_window, "max_linear_window",
          "must be finite and >= min_linear_window");
  require(std::isfinite(min_angular_window) && min_angular_window >= 0.0, "min_angular_window",
          "must be finite and >= 0");
  require(max_angular_window >= min_angular_window && max_angular_window <= kPi, "max_angular_window",
          "must lie in [min_angular_window, pi]");
  require_positive(max_distance, "max_distance");
  require_positive(dissolve_chi2, "dissolve_chi2");
  require(std::isfinite(field_cache_bytes) && field_cache_bytes >= 0.0, "field_cache_bytes", "must be finite and >= 0");
}

OptimizerOptions SubmapSlamOptions::default_optimizer() {
  OptimizerOptions o;
  o.algorithm = OptimizerAlgorithm::kLevenbergMarquardt;
  o.kernel = RobustKernel::kHuber;
  o.kernel_width = std::sqrt(7.81);  // the 95% quantile of chi2 with 3 dof
  o.max_iterations = 50;
  o.relative_tolerance = 1e-9;
  return o;
}

IncrementalScanMatcherOptions SubmapSlamOptions::default_frontend() {
  IncrementalScanMatcherOptions o;
  o.submap_distance = 10.0;
  return o;
}

void SubmapSlamOptions::validate() const {
  validate_group(frontend, "frontend");
  validate_group(closures, "closures");
  validate_group(optimizer, "optimizer");
  require(max_rounds >= 1, "max_rounds", "must be >= 1");
}

}  // namespace probslam
