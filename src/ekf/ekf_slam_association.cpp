// EKF SLAM with unknown correspondences (Table 10.2): candidates gated through a spatial
// index, maximum-likelihood or joint-compatibility (JCBB) association, then the scan staged
// and committed as one.
#include "ekf_slam_internal.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <tuple>

#include "probslam/core/chi_square.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/spatial_hash_2d.hpp"
#include "probslam/ekf/joint_compatibility.hpp"

namespace probslam {
using namespace ekf_detail;

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

EkfSlam::Candidate EkfSlam::candidate(const Eigen::VectorXd& lm, const Eigen::MatrixXd* own_cov, int index) const {
  Candidate c;
  measurement_jacobian(pose(), lm, c.z_hat, c.hx, c.hm);
  const Eigen::MatrixXd& hx = c.hx;
  const Eigen::MatrixXd& hm = c.hm;
  const Eigen::MatrixXd& p = s_->cov;
  Eigen::MatrixXd psi = hx * p.topLeftCorner<3, 3>() * hx.transpose() + Q_;
  if (own_cov == nullptr) {  // a map landmark: correlated with the robot (its position)
    const Eigen::MatrixXd pxm = p.block(0, index, 3, ld_);
    const Eigen::MatrixXd hp = hm.leftCols(ld_);
    psi += hx * pxm * hp.transpose() + hp * pxm.transpose() * hx.transpose() +
           hp * p.block(index, index, ld_, ld_) * hp.transpose();
    if (md_ == 3) psi(2, 2) += signature_var_[static_cast<std::size_t>((index - 3) / ld_)];
  } else {  // a provisional landmark: kept apart from the state
    psi += hm * (*own_cov) * hm.transpose();
  }
  c.psi_inv = psi.llt().solve(Eigen::MatrixXd::Identity(md_, md_));
  require(c.psi_inv.allFinite(), "z", "cannot be associated: an innovation covariance is not finite");
  return c;
}

// Table 10.2, with candidates gated through a spatial index and per-landmark quantities
// (z-hat, Psi^-1) computed once per scan from the predicted belief. Every decision is taken on
// that belief first; the corrections and new landmarks are then staged and applied together.
AssociationReport EkfSlam::update_unknown(const Eigen::Ref<const RowMatrixXd>& z, double alpha, double alpha_new,
                                          Association association) {
  check_measurements(z);
  require(std::isfinite(alpha) && alpha > 0.0, "alpha", "must be finite and > 0");
  require(!std::isnan(alpha_new) && alpha_new >= alpha, "alpha_new", "must be >= alpha");
  require(association == Association::kMaximumLikelihood || association == Association::kJointCompatibility,
          "association", "must be maximum likelihood or joint compatibility");
  const Eigen::Index k = z.rows();
  require_state_room(k);  // at most one landmark per measurement
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
        const Eigen::VectorXd lm = prov ? provisional_[j - n_map].mean : landmark_at(3 + j * ld_);
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

  // Stage the scan: nothing below changes the filter until commit.
  Staged st(*this, n_ + k * ld_, std::min<Eigen::Index>(k, n_map));
  std::vector<Provisional> prov = provisional_;
  std::vector<std::uint8_t> observed(n_map, 0);
  std::vector<int> promoted;
  long next_id = next_id_;
  for (Eigen::Index i = 0; i < k; ++i) {
    const Eigen::VectorXd zi = z.row(i).transpose();
    const int j = target[i];
    if (j >= 0 && j < n_map) {  // line 22 and the update of lines 24-25, one at a time
      bool used = false;
      stage_correct(st, zi, 3 + j * ld_, std::numeric_limits<double>::infinity(), used);
      observed[j] = 1;
      report.ids[i] = ids_[j];
      report.outcome[i] = AssociationReport::kAssociated;
    } else if (j >= n_map) {
      if (update_provisional(prov[j - n_map], st.mean.head<3>(), st.robot_cov(), zi)) {
        stage_augment(st, zi, next_id);
        promoted.push_back(j - n_map);
        report.ids[i] = next_id++;
        report.outcome[i] = AssociationReport::kNewLandmark;
      } else {
        report.outcome[i] = AssociationReport::kProvisional;
      }
    } else if (free_pi[i] > alpha_new) {  // line 19: a new landmark
      if (mm_.provisional) {
        Provisional p;
        Eigen::MatrixXd gx, gz;
        inverse_measurement(st.mean.head<3>(), zi, p.mean, gx, gz);
        p.cov = gx * st.robot_cov() * gx.transpose() + gz * Q_ * gz.transpose();
        require(p.mean.allFinite() && p.cov.allFinite(), "z", "places a landmark whose covariance would not be finite");
        prov.push_back(std::move(p));
        report.outcome[i] = AssociationReport::kProvisional;
      } else {
        stage_augment(st, zi, next_id);
        report.ids[i] = next_id++;
        report.outcome[i] = AssociationReport::kNewLandmark;
      }
    }
  }
  // Provisional bookkeeping: drop the promoted, age the unseen, forget the stale.
  std::vector<std::uint8_t> seen_now(prov.size(), 0);
  for (Eigen::Index i = 0; i < k; ++i)
    if (target[i] >= n_map) seen_now[target[i] - n_map] = 1;
  std::vector<Provisional> kept;
  for (std::size_t p = 0; p < prov.size(); ++p) {
    if (std::find(promoted.begin(), promoted.end(), static_cast<int>(p)) != promoted.end()) continue;
    if (p < static_cast<std::size_t>(n_prov) && !seen_now[p] && ++prov[p].age > mm_.provisional_max_age) continue;
    kept.push_back(std::move(prov[p]));
  }
  commit(st);
  provisional_ = std::move(kept);
  if (mm_.existence) update_existence(observed, x, report);
  return report;
}

namespace {
// JCBB's joint gates for up to k pairs (entry n: n pairs; entry 0 unused): the chi-square
// quantile, with n times one measurement's dof, at the probability alpha has for one. Every scan
// of a run asks for the same ones, so the last alpha's are kept (per thread: a filter's const
// calls may run on several); a quantile costs a root search over the incomplete gamma function.
const std::vector<double>& joint_gates(double alpha, int dof, int k) {
  struct Gates {
    double alpha = std::numeric_limits<double>::quiet_NaN();
    int dof = 0;
    std::vector<double> gates;
  };
  thread_local Gates cached;
  if (!(cached.alpha == alpha && cached.dof == dof)) cached = Gates{alpha, dof, {}};
  std::vector<double>& gates = cached.gates;
  if (static_cast<int>(gates.size()) <= k) {
    const double probability = chi_square_cdf(alpha, dof);
    const int from = std::max(1, static_cast<int>(gates.size()));
    gates.resize(static_cast<std::size_t>(k) + 1, std::numeric_limits<double>::infinity());
    if (probability < 1.0)
      for (int n = from; n <= k; ++n) gates[static_cast<std::size_t>(n)] = chi_square_quantile(probability, n * dof);
  }
  return gates;
}
}  // namespace

// JCBB over the scan's individually compatible pairs, gated by joint_gates.
std::vector<int> EkfSlam::joint_target(const Eigen::Ref<const RowMatrixXd>& z,
                                       const std::vector<std::tuple<double, int, int>>& pairs,
                                       const std::unordered_map<int, Candidate>& cache, int n_map, double alpha) const {
  const int k = static_cast<int>(z.rows());
  const std::vector<double>& gates = joint_gates(alpha, md_, k);
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
      p.jacobian << c.hx, c.hm.leftCols(ld_);
      p.columns = {0, 1, 2};
      for (int d = 0; d < ld_; ++d) p.columns.push_back(at + d);
      // The signature's own variance: no other pairing's landmark is correlated with it.
      p.noise = Q_;
      if (md_ == 3) p.noise(2, 2) += signature_var_[static_cast<std::size_t>(j)];
    } else {  // a provisional landmark: outside the state, uncorrelated with it
      p.jacobian = c.hx;
      p.columns = {0, 1, 2};
      p.noise = Q_ + c.hm * provisional_[j - n_map].cov * c.hm.transpose();
    }
    pairings.push_back(std::move(p));
  }
  return joint_compatibility(k, pairings, s_->cov.topLeftCorner(n_, n_), gates).target;
}

void EkfSlam::set_gate_distance(double metres) {
  require(std::isfinite(metres) && metres >= kMinHashCellSize && metres <= kMaxCoordinate, "gate_distance",
          "must be in [1e-6, 1e9] m");
  gate_distance_ = metres;
}

}  // namespace probslam
