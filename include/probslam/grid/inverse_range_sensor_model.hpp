#pragma once
// Table 9.2: the inverse range sensor model of a cone-shaped beam.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "probslam/grid/beam_index.hpp"

namespace probslam {

/// Parameters of Table 9.2: z_max (m), obstacle thickness alpha (m), beam width beta (rad),
/// and the log-odds l0 (prior), l_occ and l_free it returns.
struct ConeModel {
  double z_max = 0.0;
  double alpha = 0.0;
  double beta = 0.0;
  double l0 = 0.0;
  double l_occ = 0.0;
  double l_free = 0.0;

  /// Throws std::invalid_argument naming the first bad parameter.
  void validate() const;
};

/// One scan prepared for Table 9.2 queries. Readings that are NaN, infinite or negative are
/// left out, as if their beam did not exist.
class ConeScan {
 public:
  /// pose (x, y, theta); ranges and beam_angles (radians, relative to theta) of equal length.
  ConeScan(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
           const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const ConeModel& model);

  /// Table 9.2 for the cell whose centre of mass is (cx, cy); line 8 tests the measured range.
  double operator()(double cx, double cy) const;
  /// No cell farther than this from the sensor can be in the perceptual field (metres).
  double reach() const { return reach_; }
  const ConeModel& model() const { return model_; }
  const Eigen::Vector3d& pose() const { return pose_; }

 private:
  Eigen::Vector3d pose_;
  Eigen::VectorXd ranges_;
  Eigen::VectorXd angles_;
  ConeModel model_;
  BeamIndex beams_;
  double reach_ = 0.0;
  // The blind wedge: directions (world frame) farther than beta/2 from every beam, shrunk by a
  // margin; cells inside it return l0 without the cost of atan2.
  bool has_blind_wedge_ = false;
  bool blind_wedge_reflex_ = false;  // wider than pi
  double wedge_from_[2] = {0, 0}, wedge_to_[2] = {0, 0};
  bool in_blind_wedge(double dx, double dy) const;
};

/// Table 9.2 for each row of cells (n x 2 centres, metres).
Eigen::VectorXd inverse_range_sensor_model(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& cells,
    const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
    const Eigen::Ref<const Eigen::VectorXd>& beam_angles, const ConeModel& model);

/// Which readings count: finite and >= 0.
std::vector<std::uint8_t> valid_readings(const Eigen::Ref<const Eigen::VectorXd>& ranges);

}  // namespace probslam
