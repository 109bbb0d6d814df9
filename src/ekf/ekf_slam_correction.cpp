// EKF SLAM's correction (Table 10.1 lines 6-20): the measurement model and its inverse, one
// measurement's correction staged as a factor of P0 - W W^T, new landmarks, the one O(n^2)
// covariance pass at commit, and update() with known correspondences.
#include "ekf_slam_internal.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <optional>

#include "probslam/core/angle.hpp"
#include "probslam/core/gaussian.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "gram_kernels.hpp"

namespace probslam {
using namespace ekf_detail;

struct EkfSlam::Saved {
  std::shared_ptr<EkfSlamStorage> storage;
  Eigen::VectorXd mean;
  Eigen::MatrixXd cov;
  int n;
  std::vector<long> ids;
  std::unordered_map<long, int> index;
  std::vector<double> existence, signature, signature_var;
  long next_id;
};

void EkfSlam::check_measurements(const Eigen::Ref<const RowMatrixXd>& z) const { require_measurement_rows(z, md_); }

void EkfSlam::measurement_jacobian(const Eigen::Vector3d& x, const Eigen::VectorXd& lm, Eigen::VectorXd& z_hat,
                                   Eigen::MatrixXd& hx, Eigen::MatrixXd& hm) const {
  // Coordinates are within a few kMaxCoordinate, so q cannot overflow.
  const double dx = lm[0] - x[0], dy = lm[1] - x[1], q = dx * dx + dy * dy;
  const double r = std::sqrt(q);
  z_hat.resize(md_);
  z_hat[0] = r;
  z_hat[1] = wrap_angle(std::atan2(dy, dx) - x[2]);
  hx = Eigen::MatrixXd::Zero(md_, 3);
  hm = Eigen::MatrixXd::Zero(md_, md_);  // (x, y[, signature]): a signature's column is its own filter's
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
  const Eigen::VectorXd lm = landmark_at(index);
  const double dx = lm[0] - s_->mean[0], dy = lm[1] - s_->mean[1];
  if (dx * dx + dy * dy < kMinRangeSquared) return false;
  measurement_jacobian(pose(), lm, z_hat, hx, hm);
  innovation(z, z_hat, nu);
  const Eigen::MatrixXd& p = s_->cov;
  pht = p.block(0, 0, n_, 3) * hx.transpose() + p.block(0, index, n_, ld_) * hm.leftCols(ld_).transpose();
  const Eigen::MatrixXd hph = hx * pht.topRows(3) + hm.leftCols(ld_) * pht.middleRows(index, ld_);
  s = 0.5 * (hph + hph.transpose()) + Q_;
  if (md_ == 3) s(2, 2) += signature_var_[static_cast<std::size_t>((index - 3) / ld_)];
  return true;
}

EkfSlam::PairingLikelihood EkfSlam::pairing_likelihood(const Eigen::VectorXd& z, long id) const {
  check_measurements(z.transpose());
  Eigen::VectorXd nu;
  Eigen::MatrixXd s, pht;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!innovation_at(z, index_of(id), nu, s, pht)) return {nan, nan};
  const Eigen::LLT<Eigen::MatrixXd> llt(s);
  const Eigen::VectorXd white = llt.matrixL().solve(nu);
  const PairingLikelihood out{white.squaredNorm(), log_det_2pi(llt)};
  require(llt.info() == Eigen::Success && std::isfinite(out.nis) && std::isfinite(out.log_det), "z",
          "has no finite likelihood against this landmark (innovation covariance degenerate)");
  return out;
}

void EkfSlam::inverse_measurement(const Eigen::Vector3d& x, const Eigen::VectorXd& z, Eigen::VectorXd& m,
                                  Eigen::MatrixXd& gx, Eigen::MatrixXd& gz) const {
  const MeasurementJacobians<2> j = landmark_from_range_bearing_jacobians(x, z.head<2>());
  m.resize(md_);
  m.head<2>() = landmark_from_range_bearing(x, z.head<2>());
  gx = Eigen::MatrixXd::Zero(md_, 3);
  gz = Eigen::MatrixXd::Zero(md_, md_);
  gx.topRows<2>() = j.pose;
  gz.topLeftCorner<2, 2>() = j.landmark;
  if (md_ == 3) {
    m[2] = z[2];
    gz(2, 2) = 1.0;
  }
}

// Table 10.1 lines 12-20 for one measurement, with H's non-zero columns (robot and landmark):
// P H^T is read from the staged covariance P0 - W W^T without forming it.
double EkfSlam::stage_correct(Staged& st, const Eigen::VectorXd& z, Eigen::Index index, double gate,
                              bool& used) const {
  used = false;
  const Eigen::Index n = st.n;
  const std::size_t slot = static_cast<std::size_t>((index - 3) / ld_);
  Eigen::VectorXd lm(md_);
  lm.head<2>() = st.mean.segment<2>(index);
  if (md_ == 3) lm[2] = st.sig[slot];
  const Eigen::Vector3d x = st.mean.head<3>();
  const double dx = lm[0] - x[0], dy = lm[1] - x[1];
  if (!(dx * dx + dy * dy >= kMinRangeSquared)) return std::numeric_limits<double>::quiet_NaN();
  Eigen::VectorXd z_hat, nu;
  Eigen::MatrixXd hx, hm;
  measurement_jacobian(x, lm, z_hat, hx, hm);
  innovation(z, z_hat, nu);
  // P0's robot and landmark columns (n x (3 + ld)), then minus the staged factors.
  Eigen::MatrixXd cols(n, 3 + ld_);
  cols.leftCols<3>() = st.robot.topRows(n);
  if (index < st.n0) {
    cols.rightCols(ld_).topRows(st.n0) = s_->cov.block(0, index, st.n0, ld_);
    for (const Staged::Added& a : st.added)
      cols.block(a.at, 3, ld_, ld_) = a.gx * s_->cov.block(0, index, 3, ld_);
  } else {
    const auto it = std::find_if(st.added.begin(), st.added.end(), [&](const Staged::Added& a) { return a.at == index; });
    cols.rightCols(ld_) = st.robot.topRows(n) * it->gx.transpose();
    cols.block(index, 3, ld_, ld_) += it->own;
  }
  if (st.c > 0) cols.noalias() -= st.w.topLeftCorner(n, st.c) * st.factor_rows(index, ld_).transpose();
  // H's dense part: range and bearing rows (a signature row reads only the signature).
  const Eigen::MatrixXd hm_dense = hm.topLeftCorner(kRangeBearing, ld_);
  const Eigen::MatrixXd pht = cols.leftCols<3>() * hx.topRows(kRangeBearing).transpose() +
                              cols.rightCols(ld_) * hm_dense.transpose();  // n x 2
  const Eigen::MatrixXd hph = hx.topRows(kRangeBearing) * pht.topRows(3) + hm_dense * pht.middleRows(index, ld_);
  const Eigen::Matrix2d s = 0.5 * (hph + hph.transpose()) + Q_.topLeftCorner<2, 2>();
  const Eigen::LLT<Eigen::Matrix2d> llt(s);
  const Eigen::Vector2d white = llt.matrixL().solve(nu.head<2>());  // L^-1 nu
  // The signature's scalar filter: S = its variance + Q's, the same NIS term as the full state's.
  const double sig_s = md_ == 3 ? st.sig_var[slot] + Q_(2, 2) : 1.0;
  const double sig_white = md_ == 3 ? nu[2] / std::sqrt(sig_s) : 0.0;
  const double nis = white.squaredNorm() + sig_white * sig_white;
  require(llt.info() == Eigen::Success && std::isfinite(nis) && sig_s > 0.0, "z",
          "cannot be applied: its innovation covariance is not finite positive definite");
  if (!(nis <= gate)) return nis;
  // K = P H^T S^-1 = W L^-1 with W = P H^T L^-T; then P -= W W^T.
  const Eigen::MatrixXd wj = llt.matrixL().solve(pht.transpose()).transpose();
  Eigen::VectorXd moved = st.mean.head(n);
  moved.noalias() += wj * white;
  moved[2] = wrap_angle(moved[2]);
  const double sig_w = md_ == 3 ? st.sig_var[slot] / std::sqrt(sig_s) : 0.0;  // the signature's W
  const double sig = md_ == 3 ? st.sig[slot] + sig_w * sig_white : 0.0;
  require(wj.allFinite() && moved.allFinite() && wj.cwiseAbs2().rowwise().sum().maxCoeff() <= kMaxCovarianceEntry &&
              std::isfinite(sig) && sig_w * sig_w <= kMaxCovarianceEntry,
          "z", "cannot be applied: the update would not be finite");
  st.mean.head(n) = moved;
  st.w.block(0, st.c, n, kRangeBearing) = wj;
  st.c += kRangeBearing;
  if (md_ == 3) {
    st.sig[slot] = sig;
    st.sig_var[slot] -= sig_w * sig_w;
  }
  used = true;
  return nis;
}

// Table 10.1 line 10, with the covariance of that inverse measurement: the exact limit of an
// infinite prior updated with this first sighting, so the rest of the state does not move.
void EkfSlam::stage_augment(Staged& st, const Eigen::VectorXd& z, long id) const {
  Eigen::VectorXd m;
  Eigen::MatrixXd gx, gz;
  inverse_measurement(st.mean.head<3>(), z, m, gx, gz);
  // The position's rows (a signature starts as its measurement: z[2] with variance Q(2, 2)).
  const Eigen::MatrixXd gx_pos = gx.topRows(ld_), gz_pos = gz.topLeftCorner(ld_, kRangeBearing);
  Staged::Added a{id, st.n, gx_pos, gz_pos * Q_.topLeftCorner<2, 2>() * gz_pos.transpose()};
  const Eigen::MatrixXd robot_rows = gx_pos * s_->cov.topLeftCorner<3, 3>();
  require(m.allFinite() && a.own.allFinite() && robot_rows.allFinite() &&
              std::max(a.own.cwiseAbs().maxCoeff(), robot_rows.cwiseAbs().maxCoeff()) <= kMaxCovarianceEntry,
          "z", "places a landmark whose covariance would be too large to stay finite");
  st.mean.segment(st.n, ld_) = m.head(ld_);
  if (md_ == 3) {
    st.sig.push_back(m[2]);
    st.sig_var.push_back(Q_(2, 2));
  }
  st.robot.middleRows(st.n, ld_) = robot_rows;
  if (st.c > 0) st.w.block(st.n, 0, ld_, st.c) = gx_pos * st.w.block(0, 0, 3, st.c);
  st.index[id] = st.n;
  st.added.push_back(std::move(a));
  st.n += ld_;
}

void EkfSlam::commit(Staged& st) {
  const Eigen::Index n = st.n;
  reserve(n);
  Eigen::MatrixXd& p = s_->cov;
  for (const Staged::Added& a : st.added) {  // P0's rows and columns of the new landmarks
    Eigen::MatrixXd col = st.robot.topRows(n) * a.gx.transpose();
    col.middleRows(a.at, ld_) += a.own;
    const Eigen::MatrixXd block = col.middleRows(a.at, ld_);
    col.middleRows(a.at, ld_) = 0.5 * (block + block.transpose());
    p.block(0, a.at, n, ld_) = col;
    p.block(a.at, 0, ld_, n) = col.transpose();
  }
  // P -= W W^T over the whole state: the call's one O(n^2) step (gram_kernels.hpp).
  static const ekf_detail::SubtractGram subtract_gram = ekf_detail::subtract_gram_kernel();
  if (st.c > 0) subtract_gram(p.data(), n, p.outerStride(), st.w.data(), st.w.outerStride(), st.c);
  s_->mean.head(n) = st.mean.head(n);
  signature_ = std::move(st.sig);
  signature_var_ = std::move(st.sig_var);
  for (const Staged::Added& a : st.added) {
    ids_.push_back(a.id);
    index_[a.id] = static_cast<int>(a.at);
    existence_.push_back(mm_.existence_hit);
    next_id_ = std::max(next_id_, a.id + 1);
  }
  n_ = static_cast<int>(n);
}

EkfSlam::Saved EkfSlam::save() const {
  return {s_, s_->mean.head(n_), s_->cov.topLeftCorner(n_, n_), n_, ids_, index_, existence_, signature_,
          signature_var_, next_id_};
}

void EkfSlam::restore(Saved& saved) {
  s_ = saved.storage;
  n_ = saved.n;
  s_->mean.head(n_) = saved.mean;
  s_->cov.topLeftCorner(n_, n_) = saved.cov;
  ids_ = std::move(saved.ids);
  index_ = std::move(saved.index);
  existence_ = std::move(saved.existence);
  signature_ = std::move(saved.signature);
  signature_var_ = std::move(saved.signature_var);
  next_id_ = saved.next_id;
}

UpdateReport EkfSlam::update(const Eigen::Ref<const RowMatrixXd>& z, const std::vector<long>& ids, double gate) {
  check_measurements(z);
  require(static_cast<Eigen::Index>(ids.size()) == z.rows(), "ids", "must have one id per measurement");
  for (const long id : ids) require(id >= 0 && id <= kMaxLandmarkId, "ids", "must be in [0, 2^62]");
  require(!std::isnan(gate) && gate > 0.0, "gate", "must be > 0");
  // Which measurements correct a landmark (the others are first sightings).
  std::unordered_map<long, int> fresh;
  std::vector<std::uint8_t> corrects(ids.size(), 1);
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (!index_.count(ids[i]) && fresh.emplace(ids[i], 0).second) corrects[i] = 0;
  require_state_room(static_cast<Eigen::Index>(fresh.size()));
  const Eigen::Index k = z.rows(), final_dim = n_ + static_cast<Eigen::Index>(fresh.size()) * ld_;
  // Staging reads O(n) per factor column: up to n columns it costs no more than the update it
  // replaces. Longer calls (the same landmarks many times) run in chunks on a saved state.
  const Eigen::Index max_corrections = std::max<Eigen::Index>(1, final_dim / md_);
  std::vector<Eigen::Index> ends;  // chunk ends
  Eigen::Index count = 0;
  for (Eigen::Index i = 0; i < k; ++i) {
    if (corrects[i] && count == max_corrections) {
      ends.push_back(i);
      count = 0;
    }
    count += corrects[i];
  }
  ends.push_back(k);
  UpdateReport report{Eigen::VectorXd::Constant(k, std::numeric_limits<double>::quiet_NaN()),
                      std::vector<std::uint8_t>(k, 1)};
  std::optional<Saved> saved;
  if (ends.size() > 1) saved = save();
  try {
    Eigen::Index from = 0;
    for (const Eigen::Index to : ends) {
      Staged st(*this, final_dim, std::count(corrects.begin() + from, corrects.begin() + to, 1));
      for (Eigen::Index i = from; i < to; ++i) {
        const Eigen::VectorXd zi = z.row(i).transpose();
        const auto it = index_.find(ids[i]);
        const auto staged = st.index.find(ids[i]);
        if (it == index_.end() && staged == st.index.end()) {
          stage_augment(st, zi, ids[i]);
          continue;
        }
        bool used = false;
        report.nis[i] = stage_correct(st, zi, it != index_.end() ? it->second : staged->second, gate, used);
        report.used[i] = used;
      }
      commit(st);
      from = to;
    }
  } catch (...) {
    if (saved) restore(*saved);
    throw;
  }
  return report;
}

}  // namespace probslam
