#include "probslam/ekf/ekf_slam.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <optional>
#include <cmath>
#include <stdexcept>
#include <string>
#include <tuple>

#include "probslam/core/angle.hpp"
#include "probslam/core/chi_square.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/filter_limits.hpp"
#include "probslam/core/gaussian.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/spatial_hash_2d.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "probslam/ekf/joint_compatibility.hpp"
#include "gram_kernels.hpp"

namespace probslam {
namespace {

constexpr Eigen::Index kInitialLandmarkCapacity = 16;
// Largest covariance entry (and squared gain row) a call may produce: the square root of the
// double range, so that the products of the next call (G P G^T, H P H^T) still fit.
constexpr double kMaxCovarianceEntry = 1e150;
// Existence log-odds are clamped to this magnitude (a thousand of the largest increments).
constexpr double kMaxExistence = 1e3 * kEkfMaxLogOdds;

void require_motion_noise(const Eigen::MatrixXd& noise, const char* name, bool semi) {
  require((noise.rows() == 3 && noise.cols() == 3) || (noise.rows() == 2 && noise.cols() == 2), name,
          "must be 3x3 (pose space) or 2x2 (control space)");
  require_covariance(noise, name, semi);
}

void require_on_map(const Eigen::Vector3d& pose, const char* name, const char* what) { require(on_map(pose), name, what); }

// Rows of a correction's factor in the dense state: range and bearing (a signature's update is
// its own scalar filter's).
constexpr Eigen::Index kRangeBearing = 2;

}  // namespace

// A call's effect on the state, computed without touching it. With P0 the covariance before the
// call, extended by the staged landmarks as if they had been added first (rows L_a = G_x,a P0's
// robot rows, own block + G_z Q G_z^T), the covariance after the staged corrections is
// P0 - W W^T, W holding one n x m factor per correction (Table 10.1 line 18's K S K^T). A
// landmark added after correction j extends that correction's factor with G_x W_j's robot rows.
// So each correction costs O(n) for the few columns it reads, and commit applies all of them
// in one product: the state is written only once everything has been checked finite. The
// signatures, apart from the dense state, are staged as values (sig, sig_var: one per landmark).
struct EkfSlam::Staged {
  struct Added {
    long id;
    Eigen::Index at;
    Eigen::MatrixXd gx;   // ld x 3
    Eigen::MatrixXd own;  // ld x ld, G_z Q G_z^T
  };
  Eigen::Index n0 = 0, n = 0, c = 0;  // state dimension before / now, factor columns used
  Eigen::VectorXd mean;               // the state mean now (n of its rows used)
  Eigen::MatrixXd robot;              // P0's robot columns, extended (n x 3 used)
  Eigen::MatrixXd w;                  // the factors (n x c used)
  std::vector<double> sig, sig_var;   // the signatures now (with signatures)
  std::vector<Added> added;
  std::unordered_map<long, Eigen::Index> index;  // landmarks added by this call

  // max_corrections: the call's corrections at most (each adds kRangeBearing factor columns).
  Staged(const EkfSlam& f, Eigen::Index final_dim, Eigen::Index max_corrections)
      : n0(f.n_), n(f.n_), mean(final_dim), robot(final_dim, 3), w(final_dim, kRangeBearing * max_corrections),
        sig(f.signature_), sig_var(f.signature_var_) {
    mean.head(n0) = f.s_->mean.head(n0);
    robot.topRows(n0) = f.s_->cov.block(0, 0, n0, 3);
  }
  // The rows of the factors that robot and landmark `at` columns need: P[:, cols] = P0 - W W[cols]^T.
  Eigen::MatrixXd factor_rows(Eigen::Index at, Eigen::Index ld) const {
    Eigen::MatrixXd rows(3 + ld, c);
    rows << w.block(0, 0, 3, c), w.block(at, 0, ld, c);
    return rows;
  }
  Eigen::Matrix3d robot_cov() const {
    return robot.topRows<3>() - w.block(0, 0, 3, c) * w.block(0, 0, 3, c).transpose();
  }
};

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

EkfSlam::EkfSlam(const Eigen::MatrixXd& motion_noise, const Eigen::MatrixXd& measurement_noise, bool use_signatures,
                 const Eigen::Vector3d& initial_pose, const Eigen::Matrix3d& initial_pose_cov) {
  md_ = use_signatures ? 3 : 2;
  require_motion_noise(motion_noise, "motion_noise", false);
  control_noise_ = motion_noise.rows() == 2;
  if (control_noise_) m_control_ = motion_noise;
  else r_pose_ = motion_noise;
  require(measurement_noise.rows() == md_ && measurement_noise.cols() == md_, "measurement_noise",
          use_signatures ? "must be 3x3 (range, bearing, signature)" : "must be 2x2 (range, bearing)");
  require_covariance(measurement_noise, "measurement_noise", false);
  require(!use_signatures || (measurement_noise(0, 2) == 0.0 && measurement_noise(1, 2) == 0.0), "measurement_noise",
          "must leave the signature uncorrelated with range and bearing (zero (0, 2) and (1, 2) entries): the "
          "filter keeps signatures apart from the dense state");
  Q_ = measurement_noise;
  require_on_map(initial_pose, "initial_pose", "must be finite with |x|, |y| <= 1e9 m (kMaxCoordinate)");
  require_covariance(initial_pose_cov, "initial_pose_cov", true);
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

Eigen::VectorXd EkfSlam::landmark_at(Eigen::Index index) const {
  Eigen::VectorXd lm(md_);
  lm.head<2>() = s_->mean.segment<2>(index);
  if (md_ == 3) lm[2] = signature_[static_cast<std::size_t>((index - 3) / ld_)];
  return lm;
}

Eigen::VectorXd EkfSlam::landmark(long id) const { return landmark_at(index_of(id)); }

Eigen::MatrixXd EkfSlam::landmark_covariance(long id) const {
  const int at = index_of(id);
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(md_, md_);
  c.topLeftCorner<2, 2>() = s_->cov.block<2, 2>(at, at);
  if (md_ == 3) c(2, 2) = signature_var_[static_cast<std::size_t>((at - 3) / ld_)];
  return c;
}

double EkfSlam::existence(long id) const {
  return existence_[(index_of(id) - 3) / ld_];
}

namespace {
// The used part of a filter's storage, copied: no spare capacity (it grows again on demand).
std::shared_ptr<EkfSlamStorage> trimmed_copy(const EkfSlamStorage& s, Eigen::Index n) {
  auto c = std::make_shared<EkfSlamStorage>();
  c->mean = s.mean.head(n);
  c->cov = s.cov.topLeftCorner(n, n);
  return c;
}
}  // namespace

// Every member as the default copy would, but the storage: a new one (EkfSlamTest.CopiesAreDeep
// compares every observable field, so a member added later and forgotten here shows).
EkfSlam::EkfSlam(const EkfSlam& o)
    : r_pose_(o.r_pose_), m_control_(o.m_control_), control_noise_(o.control_noise_), Q_(o.Q_), md_(o.md_),
      s_(trimmed_copy(*o.s_, o.n_)), n_(o.n_), ids_(o.ids_), index_(o.index_), signature_(o.signature_),
      signature_var_(o.signature_var_), existence_(o.existence_),
      provisional_(o.provisional_), next_id_(o.next_id_), gate_distance_(o.gate_distance_), mm_(o.mm_) {}

EkfSlam& EkfSlam::operator=(const EkfSlam& o) {
  if (this != &o) *this = EkfSlam(o);
  return *this;
}

void EkfSlam::require_state_room(Eigen::Index added_landmarks) const {
  require(added_landmarks <= (kEkfMaxStateDimension - n_) / ld_, "z",
          "would grow the state beyond 16384 dimensions (kEkfMaxStateDimension)");
}

void EkfSlam::reserve(Eigen::Index dim) {
  if (dim <= s_->mean.size()) return;
  auto grown = std::make_shared<EkfSlamStorage>();
  const Eigen::Index cap = std::min<Eigen::Index>(std::max(dim, 2 * s_->mean.size()), kEkfMaxStateDimension);
  grown->mean = Eigen::VectorXd::Zero(cap);
  grown->cov = Eigen::MatrixXd::Zero(cap, cap);
  grown->mean.head(n_) = s_->mean.head(n_);
  grown->cov.topLeftCorner(n_, n_) = s_->cov.topLeftCorner(n_, n_);
  s_ = std::move(grown);  // old views keep the old storage alive
}

// Table 10.1 line 5 exploiting G = I + F_x^T g F_x: only robot rows and columns change. Both
// are computed first and written only when finite.
EkfSlam::Motion EkfSlam::plan_motion(const Eigen::Vector3d& new_pose, const Eigen::Matrix3d& g,
                                     const Eigen::Matrix3d& r) const {
  const Eigen::MatrixXd& p = s_->cov;
  const Eigen::Matrix3d prr = g * p.topLeftCorner<3, 3>() * g.transpose() + r;
  Motion m{new_pose, 0.5 * (prr + prr.transpose()), g * p.block(0, 3, 3, n_ - 3), g};
  require(m.prr.allFinite() && m.prm.allFinite() && m.prr.cwiseAbs().maxCoeff() <= kMaxCovarianceEntry, "noise",
          "and the motion would make the covariance too large to stay finite");
  return m;
}

void EkfSlam::apply(const Motion& motion) {
  Eigen::MatrixXd& p = s_->cov;
  const Eigen::Index m = n_ - 3;
  p.topLeftCorner<3, 3>() = motion.prr;
  p.block(0, 3, 3, m) = motion.prm;
  p.block(3, 0, m, 3) = motion.prm.transpose();
  s_->mean.head<3>() = motion.pose;
}

void EkfSlam::predict(double v, double w, double dt) {
  predict(v, w, dt, control_noise_ ? Eigen::MatrixXd(m_control_) : Eigen::MatrixXd(r_pose_));
}

void EkfSlam::predict(double v, double w, double dt, const Eigen::MatrixXd& noise) {
  apply(plan_predict(v, w, dt, noise));
}

EkfSlam::Motion EkfSlam::plan_predict(double v, double w, double dt, const Eigen::MatrixXd& noise) const {
  const Eigen::Vector3d x = pose();
  const Eigen::Matrix3d g = velocity_motion_jacobian(x, v, w, dt);  // validates v, w, dt
  require(std::fabs(v * dt) <= kMaxCoordinate, "v", "* dt must be <= 1e9 m (kMaxCoordinate)");
  require_motion_noise(noise, "noise", true);
  Eigen::Matrix3d r = noise.rows() == 3 ? Eigen::Matrix3d(noise) : Eigen::Matrix3d::Zero();
  if (noise.rows() == 2) {
    const Eigen::Matrix<double, 3, 2> vj = velocity_motion_control_jacobian(x, v, w, dt);
    r = vj * noise * vj.transpose();
  }
  const Eigen::Vector3d next = velocity_motion(x, v, w, dt);
  require_on_map(next, "v", "moves the robot beyond 1e9 m (kMaxCoordinate)");
  return plan_motion(next, g, r);
}

namespace {
// One odometry step from pose x: the new pose, the motion's Jacobian G and the noise's J N J^T;
// predict_odometry's checks, naming `delta_name` / `noise_name`.
struct OdometryStep {
  Eigen::Vector3d next;
  Eigen::Matrix3d g, r;
};
OdometryStep odometry_step(const Eigen::Vector3d& x, const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise,
                           const char* delta_name, const char* noise_name) {
  require_odometry_step(delta, noise, delta_name, noise_name);
  const Eigen::Matrix2d rx = rotation_matrix(x[2]);
  const Eigen::Vector2d turned = rx * delta.head<2>();
  OdometryStep s;
  s.g = Eigen::Matrix3d::Identity();
  s.g(0, 2) = -turned.y();
  s.g(1, 2) = turned.x();
  Eigen::Matrix3d j = Eigen::Matrix3d::Identity();  // d(x (+) delta) / d delta
  j.topLeftCorner<2, 2>() = rx;
  s.r = j * noise * j.transpose();
  s.next = Eigen::Vector3d(x[0] + turned.x(), x[1] + turned.y(), wrap_angle(x[2] + delta[2]));
  require_on_map(s.next, delta_name, "moves the robot beyond 1e9 m (kMaxCoordinate)");
  return s;
}
}  // namespace

void EkfSlam::predict_odometry(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise) {
  const OdometryStep s = odometry_step(pose(), delta, noise, "delta", "noise");
  apply(plan_motion(s.next, s.g, s.r));
}

Poses2 EkfSlam::predict_odometry_batch(const Eigen::Ref<const RowMatrixXd>& deltas,
                                       const Eigen::Ref<const RowMatrixXd>& noises) {
  require_odometry_batch(deltas, noises);
  const Eigen::Index n = deltas.rows();
  Poses2 poses(n, 3);
  if (n == 0) return poses;
  Eigen::Vector3d x = pose();
  Eigen::Matrix3d prr = s_->cov.topLeftCorner<3, 3>();
  Eigen::Matrix3d g = Eigen::Matrix3d::Identity();  // the steps' Jacobians, composed
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Matrix3d noise = odometry_batch_noise(noises, k);
    const std::string dn = "deltas[" + std::to_string(k) + "]", nn = "noises[" + std::to_string(k) + "]";
    const OdometryStep s = odometry_step(x, deltas.row(k).transpose(), noise, dn.c_str(), nn.c_str());
    const Eigen::Matrix3d next = s.g * prr * s.g.transpose() + s.r;  // plan_motion's, step by step
    prr = 0.5 * (next + next.transpose());
    require(prr.allFinite() && prr.cwiseAbs().maxCoeff() <= kMaxCovarianceEntry, nn.c_str(),
            "and the motion would make the covariance too large to stay finite");
    g = s.g * g;
    x = s.next;
    poses.row(k) = x.transpose();
  }
  Motion m{x, prr, g * s_->cov.block(0, 3, 3, n_ - 3), g};
  require(m.prm.allFinite(), "noises", "and the motion would make the covariance too large to stay finite");
  apply(m);
  return poses;
}

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

void EkfSlam::set_gate_distance(double metres) {
  require(std::isfinite(metres) && metres >= kMinHashCellSize && metres <= kMaxCoordinate, "gate_distance",
          "must be in [1e-6, 1e9] m");
  gate_distance_ = metres;
}

}  // namespace probslam
