#pragma once
// The beam-based forward model p(z | x, m) of range finders on a binary grid map
// (Probabilistic Robotics ch. 6.3, Table 6.1): the mixture of beam_mixture.hpp around the
// expected range of range_footprint.hpp, for a laser ray or a sonar cone.
#include <Eigen/Core>
#include <random>

#include "probslam/grid/beam_mixture.hpp"
#include "probslam/grid/binary_map_2d.hpp"
#include "probslam/grid/range_footprint.hpp"

namespace probslam {

class BeamSensorModel {
 public:
  /// mixture.max_range is the beam's reach; beta (rad) is the sonar cone's full opening angle
  /// (ignored for a laser). Throws std::invalid_argument naming a bad parameter.
  BeamSensorModel(const BeamMixture& mixture, BeamShape shape, double beta = 0.0);

  const BeamMixture& mixture() const { return mixture_; }
  const BeamGeometry& geometry() const { return geometry_; }

  /// z* of each beam (metres): pose (x, y, theta), beam_angles (rad, relative to theta).
  Eigen::VectorXd expected_ranges(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                  const BinaryMap2D& map) const;
  /// log p(z_k | x, m) of each beam (Table 6.1 line 5, logged); -inf where it is 0. Ranges must
  /// be >= 0 and not NaN (+inf and readings >= max_range are max readings).
  Eigen::VectorXd log_likelihoods(const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Vector3d& pose,
                                  const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const BinaryMap2D& map) const;
  /// One reading per beam drawn from p(z_k | x, m).
  Eigen::VectorXd sample(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                         const BinaryMap2D& map, std::mt19937_64& rng) const;

 private:
  BeamMixture mixture_;
  BeamGeometry geometry_;
};

/// std::invalid_argument naming `name` unless every reading is >= 0 and not NaN.
void require_valid_ranges(const Eigen::Ref<const Eigen::VectorXd>& ranges, const char* name);

}  // namespace probslam
