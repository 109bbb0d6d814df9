// EKF SLAM's map management (ch. 10.3.3): provisional landmarks, existence log-odds and the
// removal of a landmark from the state, with their options.
#include "ekf_slam_internal.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "probslam/core/angle.hpp"

namespace probslam {
using namespace ekf_detail;

// Updates a copy of provisional landmark p; the robot pose and its covariance are the scan's
// current (staged) ones.
bool EkfSlam::update_provisional(Provisional& p, const Eigen::Vector3d& x, const Eigen::Matrix3d& pose_cov,
                                 const Eigen::VectorXd& z) const {
  Eigen::VectorXd z_hat, nu;
  Eigen::MatrixXd hx, hm;
  measurement_jacobian(x, p.mean, z_hat, hx, hm);
  innovation(z, z_hat, nu);
  const Eigen::MatrixXd s = hm * p.cov * hm.transpose() + hx * pose_cov * hx.transpose() + Q_;
  const Eigen::MatrixXd k = p.cov * hm.transpose() * s.llt().solve(Eigen::MatrixXd::Identity(md_, md_));
  p.mean += k * nu;
  const Eigen::MatrixXd c = (Eigen::MatrixXd::Identity(md_, md_) - k * hm) * p.cov;
  p.cov = 0.5 * (c + c.transpose());
  require(p.mean.allFinite() && p.cov.allFinite(), "z", "cannot be applied: a provisional landmark would not be finite");
  p.seen = std::min(p.seen + 1, kEkfMaxCount);
  p.age = 0;
  const double largest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(p.cov.topLeftCorner<2, 2>()).eigenvalues()(1);
  return p.seen >= mm_.min_observations && std::sqrt(largest) < mm_.provisional_max_std;
}

// Ch. 10.3.3: o_j rises when j is observed, falls when j should have been seen but was not.
// The increments are bounded (kEkfMaxLogOdds) and o_j is clamped to a multiple of that bound:
// it can neither overflow nor take longer to fall than it took to rise.
void EkfSlam::update_existence(const std::vector<std::uint8_t>& observed, const Eigen::Vector3d& x,
                               AssociationReport& report) {
  std::vector<long> doomed;
  for (std::size_t j = 0; j < observed.size(); ++j) {
    const long id = ids_[j];
    double& o = existence_[j];
    if (observed[j]) {
      o = std::min(o + mm_.existence_hit, kMaxExistence);
      continue;
    }
    const Eigen::Vector2d d = s_->mean.segment<2>(3 + j * ld_) - x.head<2>();
    const double bearing = wrap_angle(std::atan2(d.y(), d.x()) - x[2]);
    if (d.norm() <= mm_.sensor_range && std::fabs(bearing) <= mm_.sensor_fov / 2.0)
      o = std::max(o - mm_.existence_miss, -kMaxExistence);
    if (o < mm_.existence_threshold) doomed.push_back(id);
  }
  for (long id : doomed) remove_landmark(id);
  report.removed = std::move(doomed);
}

void EkfSlam::remove_landmark(long id) {
  const int at = index_of(id), tail = n_ - at - ld_;
  Eigen::MatrixXd& p = s_->cov;
  if (tail > 0) {
    s_->mean.segment(at, tail) = s_->mean.segment(at + ld_, tail).eval();
    for (int c = at; c < at + tail; ++c) p.col(c).head(n_) = p.col(c + ld_).head(n_);
    for (int c = 0; c < n_ - ld_; ++c) p.col(c).segment(at, tail) = p.col(c).segment(at + ld_, tail).eval();
  }
  const int slot = (at - 3) / ld_;
  ids_.erase(ids_.begin() + slot);
  existence_.erase(existence_.begin() + slot);
  if (md_ == 3) {
    signature_.erase(signature_.begin() + slot);
    signature_var_.erase(signature_var_.begin() + slot);
  }
  index_.erase(id);
  n_ -= ld_;
  for (auto& [other, index] : index_)
    if (index > at) index -= ld_;
}

void MapManagement::validate() const {
  const MapManagement& m = *this;
  require(m.min_observations >= 1 && m.min_observations <= kEkfMaxCount, "min_observations", "must be in [1, 1e6]");
  require_positive(m.provisional_max_std, "provisional_max_std");
  require(m.provisional_max_age >= 0 && m.provisional_max_age <= kEkfMaxCount, "provisional_max_age",
          "must be in [0, 1e6]");
  const auto log_odds = [](double v, const char* name) {
    require(std::isfinite(v) && std::fabs(v) <= kEkfMaxLogOdds, name, "must be finite with magnitude <= 1e6 (kEkfMaxLogOdds)");
  };
  log_odds(m.existence_hit, "existence_hit");
  log_odds(m.existence_miss, "existence_miss");
  log_odds(m.existence_threshold, "existence_threshold");
  require(!std::isnan(m.sensor_range) && m.sensor_range > 0.0, "sensor_range", "must be > 0");
  require(std::isfinite(m.sensor_fov) && m.sensor_fov > 0.0, "sensor_fov", "must be finite and > 0");
}

void EkfSlam::set_map_management(const MapManagement& m) {
  m.validate();
  mm_ = m;
}

}  // namespace probslam
