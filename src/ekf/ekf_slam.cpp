#include "probslam/ekf/ekf_slam.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <tuple>

#include "probslam/core/angle.hpp"
#include "probslam/core/chi_square.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/gaussian.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/spatial_hash_2d.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "probslam/ekf/joint_compatibility.hpp"

namespace probslam {
namespace {

// Relative asymmetry tolerated in a user's noise matrix (written out by hand, it may carry
// rounding from a conversion); larger asymmetry is a mistake.
constexpr double kSymmetryTolerance = 1e-9;
// Squared range below which a landmark sits on the robot: no bearing, no linearisation.
constexpr double kMinRangeSquared = 1e-18;
constexpr Eigen::Index kInitialLandmarkCapacity = 16;
// Association candidates: within gate_distance plus this many standard deviations of where
// the measurement places its landmark (3 sigma holds 99% of a 2-D Gaussian's mass).
constexpr double kPlacementSigmas = 3.0;

void require_spd(const Eigen::MatrixXd& m, const char* name, bool semi = false) {
  require(m.allFinite(), name, "must contain only finite values");
  const double scale = std::max(1.0, m.cwiseAbs().maxCoeff());
  require((m - m.transpose()).cwiseAbs().maxCoeff() <= kSymmetryTolerance * scale, name, "must be symmetric");
  const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m, Eigen::EigenvaluesOnly).eigenvalues()(0);
  if (semi) require(min_eig >= -kSymmetryTolerance * scale, name, "must be positive semi-definite");
  else require(min_eig > 0.0, name, "must be positive definite");
}

}  // namespace

EkfSlam::EkfSlam(const Eigen::MatrixXd& motion_noise, const Eigen::MatrixXd& measurement_noise, bool use_signatures,
                 const Eigen::Vector3d& initial_pose, const Eigen::Matrix3d& initial_pose_cov) {
  md_ = ld_ = use_signatures ? 3 : 2;
  require((motion_noise.rows() == 3 && motion_noise.cols() == 3) || (motion_noise.rows() == 2 && motion_noise.cols() == 2),
          "motion_noise", "must be 3x3 (pose space) or 2x2 (control space)");
  require_spd(motion_noise, "motion_noise");
  control_noise_ = motion_noise.rows() == 2;
  if (control_noise_) m_control_ = motion_noise;
  else r_pose_ = motion_noise;
  require(measurement_noise.rows() == md_ && measurement_noise.cols() == md_, "measurement_noise",
          use_signatures ? "must be 3x3 (range, bearing, signature)" : "must be 2x2 (range, bearing)");
  require_spd(measurement_noise, "measurement_noise");
  Q_ = measurement_noise;
  require_all_finite(initial_pose, "initial_pose");
  require_spd(initial_pose_cov, "initial_pose_cov", true);
  s_ = std::make_shared<EkfSlamStorage>();
  const Eigen::Index cap = 3 + kInitialLandmarkCapacity * ld_;
  s_->mean = Eigen::VectorXd::Zero(cap);
  s_->cov = Eigen::MatrixXd::Zero(cap, cap);
  s_->mean.head<3>() = initial_pose;
  s_->mean[2] = wrap_angle(initial_pose[2]);
  s_->cov.topLeftCorner<3, 3>() = 0.5 * (initial_pose_cov + initial_pose_cov.transpose());
}

int EkfSlam::index_of(long id) const {
  const auto it = index_.find(id);
  require(it != index_.end(), "id", ("is not a landmark of the map: " + std::to_string(id)).c_str());
  return it->second;
}

Eigen::VectorXd EkfSlam::landmark(long id) const {
  return s_->mean.segment(index_of(id), ld_);
}

Eigen::MatrixXd EkfSlam::landmark_covariance(long id) const {
  const int at = index_of(id);
  return s_->cov.block(at, at, ld_, ld_);
}

double EkfSlam::existence(long id) const {
  return existence_[(index_of(id) - 3) / ld_];
}

EkfSlam EkfSlam::clone() const {
  EkfSlam c = *this;
  c.s_ = std::make_shared<EkfSlamStorage>();
  c.s_->mean = s_->mean.head(n_);
  c.s_->cov = s_->cov.topLeftCorner(n_, n_);
  return c;
}

void EkfSlam::reserve(Eigen::Index dim) {
  if (dim <= s_->mean.size()) return;
  auto grown = std::make_shared<EkfSlamStorage>();
  const Eigen::Index cap = std::max(dim, 2 * s_->mean.size());
  grown->mean = Eigen::VectorXd::Zero(cap);
  grown->cov = Eigen::MatrixXd::Zero(cap, cap);
  grown->mean.head(n_) = s_->mean.head(n_);
  grown->cov.topLeftCorner(n_, n_) = s_->cov.topLeftCorner(n_, n_);
  s_ = std::move(grown);  // old views keep the old storage alive
}

// Table 10.1 line 5 exploiting G = I + F_x^T g F_x: only robot rows and columns change.
void EkfSlam::apply_motion(const Eigen::Vector3d& new_pose, const Eigen::Matrix3d& g, const Eigen::Matrix3d& r) {
  Eigen::MatrixXd& p = s_->cov;
  const Eigen::Index m = n_ - 3;
  const Eigen::Matrix3d prr = g * p.topLeftCorner<3, 3>() * g.transpose() + r;
  p.topLeftCorner<3, 3>() = 0.5 * (prr + prr.transpose());
  if (m > 0) {
    const Eigen::MatrixXd prm = g * p.block(0, 3, 3, m);
    p.block(0, 3, 3, m) = prm;
    p.block(3, 0, m, 3) = prm.transpose();
  }
  s_->mean.head<3>() = new_pose;
}

void EkfSlam::predict(double v, double w, double dt) {
  predict(v, w, dt, control_noise_ ? Eigen::MatrixXd(m_control_) : Eigen::MatrixXd(r_pose_));
}

void EkfSlam::predict(double v, double w, double dt, const Eigen::MatrixXd& noise) {
  const Eigen::Vector3d x = pose();
  const Eigen::Matrix3d g = velocity_motion_jacobian(x, v, w, dt);  // validates v, w, dt
  require((noise.rows() == 3 && noise.cols() == 3) || (noise.rows() == 2 && noise.cols() == 2), "noise",
          "must be 3x3 (pose space) or 2x2 (control space)");
  require_spd(noise, "noise", true);
  Eigen::Matrix3d r = noise.rows() == 3 ? Eigen::Matrix3d(noise) : Eigen::Matrix3d::Zero();
  if (noise.rows() == 2) {
    const Eigen::Matrix<double, 3, 2> vj = velocity_motion_control_jacobian(x, v, w, dt);
    r = vj * noise * vj.transpose();
  }
  apply_motion(velocity_motion(x, v, w, dt), g, r);
}

void EkfSlam::predict_odometry(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise) {
  require_all_finite(delta, "delta");
  require_spd(noise, "noise", true);
  const Eigen::Vector3d x = pose();
  const Eigen::Matrix2d rx = rotation_matrix(x[2]);
  const Eigen::Vector2d t = x.head<2>() + rx * delta.head<2>();
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();
  const Eigen::Vector2d turned = rx * delta.head<2>();
  g(0, 2) = -turned.y();
  g(1, 2) = turned.x();
  Eigen::Matrix3d j = Eigen::Matrix3d::Identity();  // d(x (+) delta) / d delta
  j.topLeftCorner<2, 2>() = rx;
  apply_motion({t.x(), t.y(), wrap_angle(x[2] + delta[2])}, g, j * noise * j.transpose());
}

void EkfSlam::check_measurements(const Eigen::Ref<const RowMatrixXd>& z) const {
  require(z.cols() == md_, "z", md_ == 3 ? "must have 3 columns (range, bearing, signature)"
                                         : "must have 2 columns (range, bearing)");
  require(z.allFinite(), "z", "must contain only finite values");
  require((z.col(0).array() >= 0.0).all(), "z", "ranges must be >= 0");
}

void EkfSlam::measurement_jacobian(const Eigen::VectorXd& lm, Eigen::VectorXd& z_hat, Eigen::MatrixXd& hx,
                                   Eigen::MatrixXd& hm) const {
  const Eigen::Vector3d x = s_->mean.head<3>();
  const double dx = lm[0] - x[0], dy = lm[1] - x[1], q = dx * dx + dy * dy;
  const double r = std::sqrt(q);
  z_hat.resize(md_);
  z_hat[0] = r;
  z_hat[1] = wrap_angle(std::atan2(dy, dx) - x[2]);
  hx = Eigen::MatrixXd::Zero(md_, 3);
  hm = Eigen::MatrixXd::Zero(md_, ld_);
  // Table 10.1 line 16, signs corrected.
  hx(0, 0) = -dx / r, hx(0, 1) = -dy / r;
  hx(1, 0) = dy / q, hx(1, 1) = -dx / q, hx(1, 2) = -1.0;
  hm(0, 0) = dx / r, hm(0, 1) = dy / r;
  hm(1, 0) = -dy / q, hm(1, 1) = dx / q;
  if (md_ == 3) {
    z_hat[2] = lm[2];
    hm(2, 2) = 1.0;
  }
}

void EkfSlam::innovation(const Eigen::VectorXd& z, const Eigen::VectorXd& z_hat, Eigen::VectorXd& nu) const {
  nu = z - z_hat;
  nu[1] = wrap_angle(nu[1]);  // bearing innovations live on the circle
}

bool EkfSlam::innovation_at(const Eigen::VectorXd& z, int index, Eigen::VectorXd& nu, Eigen::MatrixXd& s,
                            Eigen::MatrixXd& pht) const {
  Eigen::VectorXd z_hat;
  Eigen::MatrixXd hx, hm;
  const Eigen::VectorXd lm = s_->mean.segment(index, ld_);
  const double dx = lm[0] - s_->mean[0], dy = lm[1] - s_->mean[1];
  if (dx * dx + dy * dy < kMinRangeSquared) return false;
  measurement_jacobian(lm, z_hat, hx, hm);
  innovation(z, z_hat, nu);
  const Eigen::MatrixXd& p = s_->cov;
  pht = p.block(0, 0, n_, 3) * hx.transpose() + p.block(0, index, n_, ld_) * hm.transpose();
  const Eigen::MatrixXd hph = hx * pht.topRows(3) + hm * pht.middleRows(index, ld_);
  s = 0.5 * (hph + hph.transpose()) + Q_;
  return true;
}

// Table 10.1 lines 12-20 for one measurement, with H's six non-zero columns.
double EkfSlam::correct(const Eigen::VectorXd& z, int index, double gate, bool& used) {
  used = false;
  Eigen::VectorXd nu;
  Eigen::MatrixXd s, pht;
  if (!innovation_at(z, index, nu, s, pht)) return std::numeric_limits<double>::quiet_NaN();
  const Eigen::LLT<Eigen::MatrixXd> llt(s);
  const Eigen::VectorXd white = llt.matrixL().solve(nu);  // L^-1 nu
  const double nis = white.squaredNorm();
  if (!(nis <= gate)) return nis;
  // K = P H^T S^-1 = W L^-1 with W = P H^T L^-T; then P -= W W^T (symmetric by construction).
  const Eigen::MatrixXd w = llt.matrixL().solve(pht.transpose()).transpose();
  s_->mean.head(n_).noalias() += w * white;
  s_->mean[2] = wrap_angle(s_->mean[2]);
  s_->cov.topLeftCorner(n_, n_).noalias() -= w * w.transpose();
  used = true;
  return nis;
}

EkfSlam::PairingLikelihood EkfSlam::pairing_likelihood(const Eigen::VectorXd& z, long id) const {
  check_measurements(z.transpose());
  Eigen::VectorXd nu;
  Eigen::MatrixXd s, pht;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!innovation_at(z, index_of(id), nu, s, pht)) return {nan, nan};
  const Eigen::LLT<Eigen::MatrixXd> llt(s);
  const Eigen::VectorXd white = llt.matrixL().solve(nu);
  return {white.squaredNorm(), log_det_2pi(llt)};
}

double EkfSlam::placement_radius(const Eigen::Vector3d& x, const Eigen::VectorXd& z) const {
  // The radius widened by three sigma of the placement, so a drifted pose still finds the
  // landmark it sees.
  const MeasurementJacobians<2> place = landmark_from_range_bearing_jacobians(x, z.head<2>());
  const Eigen::Matrix2d spread = place.pose * s_->cov.topLeftCorner<3, 3>() * place.pose.transpose() +
                                 place.landmark * Q_.topLeftCorner<2, 2>() * place.landmark.transpose();
  return gate_distance_ +
         kPlacementSigmas *
             std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(spread, Eigen::EigenvaluesOnly)
                                         .eigenvalues()(1)));
}

std::vector<long> EkfSlam::nearby_landmarks(const Eigen::VectorXd& z) const {
  check_measurements(z.transpose());
  const Eigen::Vector3d x = pose();
  const Eigen::Vector2d placed = landmark_from_range_bearing(x, z.head<2>());
  const double radius = placement_radius(x, z);
  std::vector<long> out;
  for (std::size_t j = 0; j < ids_.size(); ++j)
    if ((s_->mean.segment<2>(3 + static_cast<Eigen::Index>(j) * ld_) - placed).norm() <= radius) out.push_back(ids_[j]);
  return out;
}

void EkfSlam::inverse_measurement(const Eigen::VectorXd& z, Eigen::VectorXd& m, Eigen::MatrixXd& gx,
                                  Eigen::MatrixXd& gz) const {
  const Eigen::Vector3d x = s_->mean.head<3>();
  const MeasurementJacobians<2> j = landmark_from_range_bearing_jacobians(x, z.head<2>());
  m.resize(ld_);
  m.head<2>() = landmark_from_range_bearing(x, z.head<2>());
  gx = Eigen::MatrixXd::Zero(ld_, 3);
  gz = Eigen::MatrixXd::Zero(ld_, md_);
  gx.topRows<2>() = j.pose;
  gz.topLeftCorner<2, 2>() = j.landmark;
  if (ld_ == 3) {
    m[2] = z[2];
    gz(2, 2) = 1.0;
  }
}

// Table 10.1 line 10, with the covariance of that inverse measurement: the exact limit of an
// infinite prior updated with this first sighting, so the rest of the state does not move.
void EkfSlam::augment(const Eigen::VectorXd& z, long id) {
  Eigen::VectorXd m;
  Eigen::MatrixXd gx, gz;
  inverse_measurement(z, m, gx, gz);
  reserve(n_ + ld_);
  Eigen::MatrixXd& p = s_->cov;
  const Eigen::MatrixXd cross = gx * p.block(0, 0, 3, n_);  // ld x n
  Eigen::MatrixXd own = gx * p.topLeftCorner<3, 3>() * gx.transpose() + gz * Q_ * gz.transpose();
  s_->mean.segment(n_, ld_) = m;
  p.block(n_, 0, ld_, n_) = cross;
  p.block(0, n_, n_, ld_) = cross.transpose();
  p.block(n_, n_, ld_, ld_) = 0.5 * (own + own.transpose());
  ids_.push_back(id);
  index_[id] = n_;
  existence_.push_back(mm_.existence_hit);
  n_ += ld_;
  next_id_ = std::max(next_id_, id + 1);
}

UpdateReport EkfSlam::update(const Eigen::Ref<const RowMatrixXd>& z, const std::vector<long>& ids, double gate) {
  check_measurements(z);
  require(static_cast<Eigen::Index>(ids.size()) == z.rows(), "ids", "must have one id per measurement");
  require(!std::isnan(gate) && gate > 0.0, "gate", "must be > 0");
  UpdateReport report{Eigen::VectorXd::Constant(z.rows(), std::numeric_limits<double>::quiet_NaN()),
                      std::vector<std::uint8_t>(z.rows(), 1)};
  for (Eigen::Index i = 0; i < z.rows(); ++i) {
    const Eigen::VectorXd zi = z.row(i).transpose();
    const auto it = index_.find(ids[i]);
    if (it == index_.end()) {
      augment(zi, ids[i]);
      continue;
    }
    bool used = false;
    report.nis[i] = correct(zi, it->second, gate, used);
    report.used[i] = used;
  }
  return report;
}

EkfSlam::Candidate EkfSlam::candidate(const Eigen::VectorXd& lm, const Eigen::MatrixXd* own_cov, int index) const {
  Candidate c;
  measurement_jacobian(lm, c.z_hat, c.hx, c.hm);
  const Eigen::MatrixXd& hx = c.hx;
  const Eigen::MatrixXd& hm = c.hm;
  const Eigen::MatrixXd& p = s_->cov;
  Eigen::MatrixXd psi = hx * p.topLeftCorner<3, 3>() * hx.transpose() + Q_;
  if (own_cov == nullptr) {  // a map landmark: correlated with the robot
    const Eigen::MatrixXd pxm = p.block(0, index, 3, ld_);
    psi += hx * pxm * hm.transpose() + hm * pxm.transpose() * hx.transpose() +
           hm * p.block(index, index, ld_, ld_) * hm.transpose();
  } else {  // a provisional landmark: kept apart from the state
    psi += hm * (*own_cov) * hm.transpose();
  }
  c.psi_inv = psi.llt().solve(Eigen::MatrixXd::Identity(md_, md_));
  return c;
}

bool EkfSlam::update_provisional(Provisional& p, const Eigen::VectorXd& z) const {
  Eigen::VectorXd z_hat, nu;
  Eigen::MatrixXd hx, hm;
  measurement_jacobian(p.mean, z_hat, hx, hm);
  innovation(z, z_hat, nu);
  const Eigen::MatrixXd s = hm * p.cov * hm.transpose() + hx * s_->cov.topLeftCorner<3, 3>() * hx.transpose() + Q_;
  const Eigen::MatrixXd k = p.cov * hm.transpose() * s.llt().solve(Eigen::MatrixXd::Identity(md_, md_));
  p.mean += k * nu;
  const Eigen::MatrixXd c = (Eigen::MatrixXd::Identity(ld_, ld_) - k * hm) * p.cov;
  p.cov = 0.5 * (c + c.transpose());
  ++p.seen;
  p.age = 0;
  const double largest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(p.cov.topLeftCorner<2, 2>()).eigenvalues()(1);
  return p.seen >= mm_.min_observations && std::sqrt(largest) < mm_.provisional_max_std;
}

// Table 10.2, with candidates gated through a spatial index and per-landmark quantities
// (z-hat, Psi^-1) computed once per scan from the predicted belief.
AssociationReport EkfSlam::update_unknown(const Eigen::Ref<const RowMatrixXd>& z, double alpha, double alpha_new,
                                          Association association) {
  check_measurements(z);
  require(std::isfinite(alpha) && alpha > 0.0, "alpha", "must be finite and > 0");
  require(!std::isnan(alpha_new) && alpha_new >= alpha, "alpha_new", "must be >= alpha");
  require(association == Association::kMaximumLikelihood || association == Association::kJointCompatibility,
          "association", "must be maximum likelihood or joint compatibility");
  const Eigen::Index k = z.rows();
  const int n_map = num_landmarks();
  const int n_prov = static_cast<int>(provisional_.size());
  const Eigen::Vector3d x = pose();

  // Targets 0..n_map-1 are map landmarks, then the provisional ones.
  Points2 where(n_map + n_prov, 2);
  for (int j = 0; j < n_map; ++j) where.row(j) = s_->mean.segment<2>(3 + j * ld_).transpose();
  for (int j = 0; j < n_prov; ++j) where.row(n_map + j) = provisional_[j].mean.head<2>().transpose();
  SpatialHash2D hash(gate_distance_);
  for (int j = 0; j < where.rows(); ++j) hash.insert(j, where(j, 0), where(j, 1));

  std::unordered_map<int, Candidate> cache;
  std::vector<std::tuple<double, int, int>> pairs;  // (pi, measurement, target), pi <= alpha
  std::vector<std::tuple<double, int, int>> near_pairs;  // every candidate looked at
  AssociationReport report;
  report.ids.assign(k, -1);
  report.outcome.assign(k, AssociationReport::kDiscarded);
  report.mahalanobis = Eigen::VectorXd::Constant(k, std::numeric_limits<double>::infinity());
  std::vector<int> near;
  for (Eigen::Index i = 0; i < k; ++i) {
    const Eigen::VectorXd zi = z.row(i).transpose();
    // Candidates near where the measurement places its landmark.
    const Eigen::Vector2d placed = landmark_from_range_bearing(x, zi.head<2>());
    const double radius = placement_radius(x, zi);
    near.clear();
    hash.query(placed.x(), placed.y(), radius, where, near);
    for (int j : near) {
      auto it = cache.find(j);
      if (it == cache.end()) {
        const bool prov = j >= n_map;
        const Eigen::VectorXd lm = prov ? provisional_[j - n_map].mean : Eigen::VectorXd(s_->mean.segment(3 + j * ld_, ld_));
        const double dx = lm[0] - x[0], dy = lm[1] - x[1];
        if (dx * dx + dy * dy < kMinRangeSquared) continue;
        it = cache.emplace(j, candidate(lm, prov ? &provisional_[j - n_map].cov : nullptr, 3 + j * ld_)).first;
      }
      Eigen::VectorXd nu;
      innovation(zi, it->second.z_hat, nu);
      const double pi = nu.dot(it->second.psi_inv * nu);  // Table 10.2 line 17
      report.mahalanobis[i] = std::min(report.mahalanobis[i], pi);
      near_pairs.emplace_back(pi, static_cast<int>(i), j);
      if (pi <= alpha) pairs.emplace_back(pi, static_cast<int>(i), j);
    }
  }
  std::vector<int> target(k, -1);
  std::vector<std::uint8_t> taken(where.rows(), 0);
  if (association == Association::kMaximumLikelihood) {
    // Lines 19-20, globally: the best pairs first, one landmark per measurement and vice versa.
    std::sort(pairs.begin(), pairs.end());
    for (const auto& [pi, i, j] : pairs) {
      if (target[i] >= 0 || taken[j]) continue;
      target[i] = j;
      taken[j] = 1;
    }
  } else {
    target = joint_target(z, pairs, cache, n_map, alpha);
    for (const int j : target)
      if (j >= 0) taken[j] = 1;
  }
  // A landmark paired with another measurement of this scan cannot explain this one too, so only
  // the others decide whether an unpaired measurement is a new landmark.
  std::vector<double> free_pi(k, std::numeric_limits<double>::infinity());
  for (const auto& [pi, i, j] : near_pairs)
    if (!taken[j]) free_pi[i] = std::min(free_pi[i], pi);

  std::vector<std::uint8_t> observed(n_map, 0);
  std::vector<long> map_ids(ids_.begin(), ids_.end());  // ids before this scan changes the map
  std::vector<int> promoted;
  for (Eigen::Index i = 0; i < k; ++i) {
    const Eigen::VectorXd zi = z.row(i).transpose();
    const int j = target[i];
    if (j >= 0 && j < n_map) {  // line 22 and the update of lines 24-25, one at a time
      bool used = false;
      correct(zi, index_.at(map_ids[j]), std::numeric_limits<double>::infinity(), used);
      observed[j] = 1;
      report.ids[i] = map_ids[j];
      report.outcome[i] = AssociationReport::kAssociated;
    } else if (j >= n_map) {
      if (update_provisional(provisional_[j - n_map], zi)) {
        const long id = next_id_;
        augment(zi, id);
        promoted.push_back(j - n_map);
        report.ids[i] = id;
        report.outcome[i] = AssociationReport::kNewLandmark;
      } else {
        report.outcome[i] = AssociationReport::kProvisional;
      }
    } else if (free_pi[i] > alpha_new) {  // line 19: a new landmark
      if (mm_.provisional) {
        Provisional p;
        Eigen::MatrixXd gx, gz;
        inverse_measurement(zi, p.mean, gx, gz);
        p.cov = gx * s_->cov.topLeftCorner<3, 3>() * gx.transpose() + gz * Q_ * gz.transpose();
        provisional_.push_back(std::move(p));
        report.outcome[i] = AssociationReport::kProvisional;
      } else {
        const long id = next_id_;
        augment(zi, id);
        report.ids[i] = id;
        report.outcome[i] = AssociationReport::kNewLandmark;
      }
    }
  }
  // Provisional bookkeeping: drop the promoted, age the unseen, forget the stale.
  std::vector<std::uint8_t> seen_now(provisional_.size(), 0);
  for (Eigen::Index i = 0; i < k; ++i)
    if (target[i] >= n_map) seen_now[target[i] - n_map] = 1;
  std::vector<Provisional> kept;
  for (std::size_t p = 0; p < provisional_.size(); ++p) {
    if (std::find(promoted.begin(), promoted.end(), static_cast<int>(p)) != promoted.end()) continue;
    if (p < static_cast<std::size_t>(n_prov) && !seen_now[p] && ++provisional_[p].age > mm_.provisional_max_age) continue;
    kept.push_back(std::move(provisional_[p]));
  }
  provisional_ = std::move(kept);
  if (mm_.existence) update_existence(observed, x, report);
  return report;
}

// JCBB over the scan's individually compatible pairs. The joint gate for n pairs is the chi-square
// quantile, with n times one measurement's dof, at the probability alpha has for one.
std::vector<int> EkfSlam::joint_target(const Eigen::Ref<const RowMatrixXd>& z,
                                       const std::vector<std::tuple<double, int, int>>& pairs,
                                       const std::unordered_map<int, Candidate>& cache, int n_map, double alpha) const {
  const int k = static_cast<int>(z.rows());
  const double probability = chi_square_cdf(alpha, md_);
  std::vector<double> gates(k + 1, std::numeric_limits<double>::infinity());
  if (probability < 1.0)
    for (int n = 1; n <= k; ++n) gates[n] = chi_square_quantile(probability, n * md_);
  std::vector<Pairing> pairings;
  pairings.reserve(pairs.size());
  for (const auto& [pi, i, j] : pairs) {
    const Candidate& c = cache.at(j);
    Pairing p;
    p.measurement = i;
    p.target = j;
    innovation(z.row(i).transpose(), c.z_hat, p.innovation);
    if (j < n_map) {  // robot and landmark columns of the state
      const int at = 3 + j * ld_;
      p.jacobian.resize(md_, 3 + ld_);
      p.jacobian << c.hx, c.hm;
      p.columns = {0, 1, 2};
      for (int d = 0; d < ld_; ++d) p.columns.push_back(at + d);
      p.noise = Q_;
    } else {  // a provisional landmark: outside the state, uncorrelated with it
      p.jacobian = c.hx;
      p.columns = {0, 1, 2};
      p.noise = Q_ + c.hm * provisional_[j - n_map].cov * c.hm.transpose();
    }
    pairings.push_back(std::move(p));
  }
  return joint_compatibility(k, pairings, s_->cov.topLeftCorner(n_, n_), gates).target;
}

// Ch. 10.3.3: o_j rises when j is observed, falls when j should have been seen but was not.
void EkfSlam::update_existence(const std::vector<std::uint8_t>& observed, const Eigen::Vector3d& x,
                               AssociationReport& report) {
  std::vector<long> doomed;
  for (std::size_t j = 0; j < observed.size(); ++j) {
    const long id = ids_[j];
    double& o = existence_[j];
    if (observed[j]) {
      o += mm_.existence_hit;
      continue;
    }
    const Eigen::Vector2d d = s_->mean.segment<2>(3 + j * ld_) - x.head<2>();
    const double bearing = wrap_angle(std::atan2(d.y(), d.x()) - x[2]);
    if (d.norm() <= mm_.sensor_range && std::fabs(bearing) <= mm_.sensor_fov / 2.0) o -= mm_.existence_miss;
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
  index_.erase(id);
  n_ -= ld_;
  for (auto& [other, index] : index_)
    if (index > at) index -= ld_;
}

void EkfSlam::set_map_management(const MapManagement& m) {
  require(m.min_observations >= 1, "min_observations", "must be >= 1");
  require_positive(m.provisional_max_std, "provisional_max_std");
  require(m.provisional_max_age >= 0, "provisional_max_age", "must be >= 0");
  require_finite(m.existence_hit, "existence_hit");
  require_finite(m.existence_miss, "existence_miss");
  require_finite(m.existence_threshold, "existence_threshold");
  require(!std::isnan(m.sensor_range) && m.sensor_range > 0.0, "sensor_range", "must be > 0");
  require(std::isfinite(m.sensor_fov) && m.sensor_fov > 0.0, "sensor_fov", "must be finite and > 0");
  mm_ = m;
}

void EkfSlam::set_gate_distance(double metres) {
  require_positive(metres, "gate_distance");
  gate_distance_ = metres;
}

}  // namespace probslam
