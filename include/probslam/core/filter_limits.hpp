#pragma once
// The limits and checks every landmark filter applies to its input (EkfSlam, FastSlam, and the
// laser filters' coordinates): one definition, so the same bad input gets the same answer from
// each. Beyond the limits input is refused by name (std::invalid_argument), so that a filter's
// products (r^2 times a variance, G P G^T, K S K^T) stay far inside the double range.
#include <Eigen/Core>

#include "probslam/core/types.hpp"

namespace probslam {

/// Metres: robot coordinates, measured ranges and signatures, one motion's length. Larger than
/// any planar map (the Earth's circumference is 4e7 m).
inline constexpr double kMaxCoordinate = 1e9;
/// Entries of a noise or initial covariance: a standard deviation of kMaxCoordinate metres,
/// beyond which a measurement or motion carries no information at all.
inline constexpr double kMaxVariance = 1e18;
/// Landmark ids are in [0, kMaxLandmarkId]: negative ids mark "no landmark" in the reports, and
/// new ids (largest + 1) never overflow.
inline constexpr long kMaxLandmarkId = 1L << 62;
/// Smallest cell of a spatial hash over landmarks (m): the cell indices of coordinates within a
/// few kMaxCoordinate then stay far inside int64.
inline constexpr double kMinHashCellSize = 1e-6;
/// Relative asymmetry tolerated in a user's covariance: one written out by hand may carry
/// rounding from a conversion; larger asymmetry is a mistake.
inline constexpr double kCovarianceSymmetry = 1e-9;
/// Squared range below which a landmark sits on the robot: no bearing, no linearisation (as
/// core/range_bearing_model.cpp, which refuses it).
inline constexpr double kMinRangeSquared = 1e-18;
/// Association candidates lie within the gate plus this many standard deviations of where a
/// measurement places its landmark (3 sigma holds 99% of a 2-D Gaussian's mass).
inline constexpr double kPlacementSigmas = 3.0;

/// Refused with `name` unless non-empty, finite, with entries within kMaxVariance, symmetric to
/// kCovarianceSymmetry and positive definite (positive semi-definite when `semi_definite`).
void require_covariance(const Eigen::MatrixXd& m, const char* name, bool semi_definite);

/// Finite, with |x|, |y| <= kMaxCoordinate (the heading is any finite angle).
bool on_map(const Eigen::Vector3d& pose);

/// One odometry step of a filter's predict_odometry: refused with `delta_name` unless delta is
/// finite and its translation at most kMaxCoordinate, with `noise_name` unless
/// require_covariance(noise, semi-definite) holds.
void require_odometry_step(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise, const char* delta_name,
                           const char* noise_name);

/// A batch of odometry steps (predict_odometry_batch): refused with "deltas" / "noises" unless
/// deltas is (K, 3) and noises (K, 9), a row-major 3x3 covariance a row.
void require_odometry_batch(const Eigen::Ref<const RowMatrixXd>& deltas, const Eigen::Ref<const RowMatrixXd>& noises);
/// Row k of a batch's noises as the 3x3 covariance it holds.
Eigen::Matrix3d odometry_batch_noise(const Eigen::Ref<const RowMatrixXd>& noises, Eigen::Index k);

/// Range-bearing measurement rows (N x columns: range, bearing[, signature]): refused with "z"
/// unless they have `columns` columns, are finite, ranges >= 0 and entries within kMaxCoordinate.
void require_measurement_rows(const Eigen::Ref<const RowMatrixXd>& z, int columns);

}  // namespace probslam
