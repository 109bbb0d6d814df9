#include "probslam/core/filter_limits.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>

#include "probslam/core/check.hpp"

namespace probslam {

void require_covariance(const Eigen::MatrixXd& m, const char* name, bool semi_definite) {
  require(m.size() > 0, name, "must not be empty");
  require(m.allFinite(), name, "must contain only finite values");
  require(m.cwiseAbs().maxCoeff() <= kMaxVariance, name, "entries must be <= 1e18 (kMaxVariance) in magnitude");
  const double scale = std::max(1.0, m.cwiseAbs().maxCoeff());
  require((m - m.transpose()).cwiseAbs().maxCoeff() <= kCovarianceSymmetry * scale, name, "must be symmetric");
  const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m, Eigen::EigenvaluesOnly).eigenvalues()(0);
  if (semi_definite) require(min_eig >= -kCovarianceSymmetry * scale, name, "must be positive semi-definite");
  else require(min_eig > 0.0, name, "must be positive definite");
}

bool on_map(const Eigen::Vector3d& pose) {
  return pose.allFinite() && pose.head<2>().cwiseAbs().maxCoeff() <= kMaxCoordinate;
}

void require_measurement_rows(const Eigen::Ref<const RowMatrixXd>& z, int columns) {
  require(z.cols() == columns, "z", columns == 3 ? "must have 3 columns (range, bearing, signature)"
                                                 : "must have 2 columns (range, bearing)");
  require(z.allFinite(), "z", "must contain only finite values");
  require((z.col(0).array() >= 0.0).all(), "z", "ranges must be >= 0");
  require(z.size() == 0 || z.cwiseAbs().maxCoeff() <= kMaxCoordinate, "z",
          "entries must be <= 1e9 (kMaxCoordinate) in magnitude");
}

void require_odometry_step(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise, const char* delta_name,
                           const char* noise_name) {
  require_all_finite(delta, delta_name);
  require(delta.head<2>().norm() <= kMaxCoordinate, delta_name, "must be a step of at most 1e9 m (kMaxCoordinate)");
  require_covariance(noise, noise_name, true);
}

void require_odometry_batch(const Eigen::Ref<const RowMatrixXd>& deltas, const Eigen::Ref<const RowMatrixXd>& noises) {
  require(deltas.cols() == 3, "deltas", "must be (K, 3)");
  require(noises.cols() == 9 && noises.rows() == deltas.rows(), "noises", "must be (K, 3, 3), one per row of deltas");
}

Eigen::Matrix3d odometry_batch_noise(const Eigen::Ref<const RowMatrixXd>& noises, Eigen::Index k) {
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(noises.row(k).data());
}

}  // namespace probslam
