#pragma once
// Private to src/ekf: EkfSlam's parts shared by its source files (src/ekf/ekf_slam*.cpp): the
// limits every step checks against, the argument checks, and EkfSlam::Staged (a call's effect
// on the state, staged before commit). Not installed.

#include <Eigen/Core>
#include <unordered_map>
#include <vector>

#include "probslam/core/check.hpp"
#include "probslam/core/filter_limits.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/ekf/ekf_slam.hpp"

namespace probslam {
namespace ekf_detail {

// Largest covariance entry (and squared gain row) a call may produce: the square root of the
// double range, so that the products of the next call (G P G^T, H P H^T) still fit.
constexpr double kMaxCovarianceEntry = 1e150;
// Existence log-odds are clamped to this magnitude (a thousand of the largest increments).
constexpr double kMaxExistence = 1e3 * kEkfMaxLogOdds;

inline void require_motion_noise(const Eigen::MatrixXd& noise, const char* name, bool semi) {
  require((noise.rows() == 3 && noise.cols() == 3) || (noise.rows() == 2 && noise.cols() == 2), name,
          "must be 3x3 (pose space) or 2x2 (control space)");
  require_covariance(noise, name, semi);
}

inline void require_on_map(const Eigen::Vector3d& pose, const char* name, const char* what) {
  require(on_map(pose), name, what);
}

// Rows of a correction's factor in the dense state: range and bearing (a signature's update is
// its own scalar filter's).
constexpr Eigen::Index kRangeBearing = 2;

}  // namespace ekf_detail

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

  // max_corrections: the call's corrections at most (each adds ekf_detail::kRangeBearing factor columns).
  Staged(const EkfSlam& f, Eigen::Index final_dim, Eigen::Index max_corrections)
      : n0(f.n_), n(f.n_), mean(final_dim), robot(final_dim, 3), w(final_dim, ekf_detail::kRangeBearing * max_corrections),
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

}  // namespace probslam
