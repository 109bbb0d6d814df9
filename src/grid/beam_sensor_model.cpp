#include "probslam/grid/beam_sensor_model.hpp"

#include <cmath>

#include "probslam/core/check.hpp"

namespace probslam {
namespace {

void check_beams(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& beam_angles) {
  require_all_finite(pose, "pose");
  require_all_finite(beam_angles, "beam_angles");
}

}  // namespace

void require_valid_ranges(const Eigen::Ref<const Eigen::VectorXd>& ranges, const char* name) {
  for (Eigen::Index k = 0; k < ranges.size(); ++k)
    require(ranges[k] >= 0.0, name, "must contain only readings >= 0 (no NaN)");  // NaN compares false
}

BeamSensorModel::BeamSensorModel(const BeamMixture& mixture, BeamShape shape, double beta)
    : mixture_(mixture), geometry_{shape, mixture.max_range, shape == BeamShape::kSonar ? beta : 0.0} {
  mixture_.validate();
  geometry_.validate();
}

Eigen::VectorXd BeamSensorModel::expected_ranges(const Eigen::Vector3d& pose,
                                                 const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                                 const BinaryMap2D& map) const {
  check_beams(pose, beam_angles);
  double visits = 0.0;
  for (Eigen::Index k = 0; k < beam_angles.size(); ++k)
    visits += beam_footprint_visits(map.lattice(), map.width(), map.height(), pose, beam_angles[k], geometry_);
  require_footprint_budget(visits, "beam_angles");
  Eigen::VectorXd out(beam_angles.size());
  for (Eigen::Index k = 0; k < beam_angles.size(); ++k) out[k] = expected_range(map, pose, beam_angles[k], geometry_);
  return out;
}

// Table 6.1: p = prod_k p(z_k | x, m) (eq. 6.2), kept per beam.
Eigen::VectorXd BeamSensorModel::log_likelihoods(const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                                 const Eigen::Vector3d& pose,
                                                 const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                                 const BinaryMap2D& map) const {
  require(ranges.size() == beam_angles.size(), "ranges", "must have one reading per beam angle");
  require_valid_ranges(ranges, "ranges");
  const Eigen::VectorXd expected = expected_ranges(pose, beam_angles, map);
  Eigen::VectorXd out(ranges.size());
  for (Eigen::Index k = 0; k < ranges.size(); ++k) out[k] = mixture_.log_probability(ranges[k], expected[k]);
  return out;
}

Eigen::VectorXd BeamSensorModel::sample(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                        const BinaryMap2D& map, std::mt19937_64& rng) const {
  const Eigen::VectorXd expected = expected_ranges(pose, beam_angles, map);
  Eigen::VectorXd out(expected.size());
  for (Eigen::Index k = 0; k < expected.size(); ++k) out[k] = mixture_.sample(expected[k], rng);
  return out;
}

}  // namespace probslam
