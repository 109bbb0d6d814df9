// FastSlam's private parts, shared by its source files (src/fastslam/fast_slam*.cpp): the
// small Gaussian kernels, the scan and association types, FastSlam::Context (what every
// particle's work in one call reads) and the particle-parallel member templates. Not installed.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/filter_limits.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/worker_pool.hpp"
#include "probslam/fastslam/fast_slam.hpp"

namespace probslam {
namespace fastslam_detail {

// Below this many particles per worker the threads' hand-off costs more than it saves.
constexpr int kMinParticlesPerThread = 16;

template <int N>
Eigen::Matrix<double, N, N> symmetric(const Eigen::Matrix<double, N, N>& m) {
  return 0.5 * (m + m.transpose());  // exactly symmetric: a + b == b + a
}

/// L with L L^T = m for a symmetric positive semi-definite m (Cholesky, or the eigenvalue square
/// root with rounding-negative eigenvalues clamped to zero when m is singular).
template <int N>
Eigen::Matrix<double, N, N> psd_factor(const Eigen::Matrix<double, N, N>& m) {
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(m);
  if (llt.info() == Eigen::Success) return llt.matrixL();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(symmetric<N>(m));
  return eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

inline double lambda_max(const Eigen::Matrix2d& s) {
  const double h = 0.5 * (s(0, 0) + s(1, 1)), d = 0.5 * (s(0, 0) - s(1, 1));
  return h + std::sqrt(d * d + s(0, 1) * s(1, 0));
}

/// log N(nu; 0, s) for a 2x2 s; NaN unless s is positive definite.
inline double log_gauss2(const Eigen::Vector2d& nu, const Eigen::Matrix2d& s) {
  const double det = s(0, 0) * s(1, 1) - s(0, 1) * s(1, 0);
  if (!(det > 0.0) || !(s(0, 0) > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  const double m = (s(1, 1) * nu[0] * nu[0] - (s(0, 1) + s(1, 0)) * nu[0] * nu[1] + s(0, 0) * nu[1] * nu[1]) / det;
  return -0.5 * (m + std::log(kTwoPi * kTwoPi * det));
}

inline double log_gauss1(double nu, double var) { return -0.5 * (nu * nu / var + std::log(kTwoPi * var)); }

struct Predicted {
  Eigen::Vector2d z_hat;
  Eigen::Matrix<double, 2, 3> hx;
  Eigen::Matrix2d hm;
};

/// h and its Jacobians at (pose, landmark); false for a landmark on the robot.
inline bool predict_measurement(const Eigen::Vector3d& x, const Eigen::Vector2d& m, Predicted& out) {
  if (!((m - x.head<2>()).squaredNorm() >= kMinRangeSquared)) return false;
  // Poses and landmark means are finite by the filter's checks: the model without its own.
  MeasurementJacobians<2> j;
  range_bearing_unchecked(x, m, out.z_hat, j);
  out.hx = j.pose;
  out.hm = j.landmark;
  return true;
}

inline Eigen::Vector2d innovation(const Eigen::Vector2d& z, const Eigen::Vector2d& z_hat) {
  Eigen::Vector2d nu = z - z_hat;
  nu[1] = wrap_angle(nu[1]);  // bearings live on the circle
  return nu;
}

/// One step of the FastSLAM 2.0 proposal in Kalman form (see fastslam2_proposal); false for a
/// landmark on the pose mean.
bool proposal_step(Eigen::Vector3d& mu, Eigen::Matrix3d& p, const Landmark& lm, const Eigen::Vector2d& z,
                   const Eigen::Matrix2d& q, double& log_likelihood);

struct Scan {
  const Eigen::Ref<const RowMatrixXd>& z;
  bool signatures;
  Eigen::Vector2d rb(Eigen::Index i) const { return {z(i, 0), z(i, 1)}; }
  double sig(Eigen::Index i) const { return z(i, 2); }
};

/// An association candidate of one scan: measurement i and a landmark of the particle's map,
/// with the measurement's log-likelihood under the landmark at the pose prior (its marginal).
struct Pair {
  double ll;
  Eigen::Index i;
  long id;
  const Landmark* lm;
};

/// The joint association's answer: a landmark id per measurement (-1: a new landmark); for
/// version 2 the proposal after the matched measurements and their joint log-likelihood.
struct JointAssignment {
  std::vector<long> ids;
  double match_log_likelihood = 0.0;
  bool any = false;
  Eigen::Vector3d mu = Eigen::Vector3d::Zero();
  Eigen::Matrix3d p = Eigen::Matrix3d::Zero();
};

// The joint association's search stops after this many nodes per particle and scan and keeps
// the best assignment found (its first descent is the per-measurement best, in order of
// confidence): a scan of k measurements with c candidates each has (c + 1)^k assignments, and a
// cluttered scan must not stall the filter. MRCLAM's and Victoria Park's scans stay far below.
constexpr long kJointAssociationMaxNodes = 1L << 14;

}  // namespace fastslam_detail

/// What every particle's work in one call reads.
struct FastSlam::Context {
  const FastSlamOptions& o;
  Eigen::Matrix2d q;   // (range, bearing) noise
  double q_sig;        // signature variance
  double log_p_new;
  double log_outlier;  // log(outlier_density); -inf without the outlier model

  using Scan = fastslam_detail::Scan;
  using Pair = fastslam_detail::Pair;
  using JointAssignment = fastslam_detail::JointAssignment;

  /// Signature log-likelihood of measurement i against lm (0 without signatures).
  double sig_log_likelihood(const Scan& s, Eigen::Index i, const Landmark& lm) const {
    return s.signatures ? fastslam_detail::log_gauss1(s.sig(i) - lm.signature, lm.signature_var + q_sig) : 0.0;
  }

  /// The landmark EKF update (version 1's, and version 2's after sampling) at pose x: returns
  /// log N(z - z_hat; 0, Q_j) (with the signature's factor), NaN for a landmark on the robot.
  double update_landmark(Landmark& lm, const Eigen::Vector3d& x, const Scan& s, Eigen::Index i) const;

  /// Table 13.1's initialisation: the inverse measurement model, Sigma = H^-1 Q H^-T.
  Landmark new_landmark(long id, const Eigen::Vector3d& x, const Scan& s, Eigen::Index i) const;

  /// Moves the path poses of the motions since the last update so that the newest becomes x:
  /// pose i of n shifted by i / n of (x - the newest), the correction spread along the stretch
  /// the proposal conditioned on (a linear bridge) instead of a jump at its end.
  void bridge_path(FastSlamParticle& part, const Eigen::Vector3d& x) const;

  /// An update ends the motion since the last one: version 2's path is bridged to the pose (the
  /// proposal's sample, or the motion sample where no measurement entered the proposal).
  void end_motion(FastSlamParticle& part) const;

  /// Samples the pose from N(mu, p) when a proposal step changed the prior; the update's
  /// end_motion bridges the path to it.
  void take_proposal_sample(FastSlamParticle& part, const Eigen::Vector3d& mu, const Eigen::Matrix3d& p) const;

  /// With a bearing offset model: samples the particle's offset for this scan from its
  /// transition and returns the scan's measurements with their bearings corrected by it (in
  /// `storage`); without, the measurements as given.
  Eigen::Ref<const RowMatrixXd> offset_corrected(FastSlamParticle& part, const Scan& s,
                                                 RowMatrixXd& storage) const;

  void add_log_likelihood(FastSlamParticle& part, double ll) const {
    require(std::isfinite(ll), "z", "has a likelihood that is not finite");
    part.log_weight += ll;
    part.last_log_likelihood = ll;
  }

  // ---- known correspondences ----
  /// log(N + outlier_density) for a Gaussian term log N: the mixture's weight factor.
  double with_outliers(double log_gauss) const {
    return log_outlier == -std::numeric_limits<double>::infinity() ? log_gauss
                                                                   : std::max(log_gauss, log_outlier) +
                                                                         std::log1p(std::exp(-std::abs(log_gauss - log_outlier)));
  }
  /// The outlier density explains the measurement better than its landmark's Gaussian.
  bool is_outlier(double log_gauss) const { return log_gauss < log_outlier; }

  /// Known correspondences: the update of one particle by the scan with landmark ids `ids`.
  void update_known(FastSlamParticle& part, const Scan& given, const std::vector<long>& ids) const;

  // ---- unknown correspondences ----
  /// Per-scan joint maximum-likelihood association (JCBB's search, for one particle): the
  /// assignment of measurements to distinct candidate landmarks or to new ones that maximises
  /// the scan's log-likelihood, each new landmark counted at log p_new. Version 2 scores an
  /// assignment by the proposal's chain rule (measurement j under the pose conditioned on the
  /// matched measurements before it), so sightings that share the pose's error are judged
  /// together; version 1 (the pose known) by the sum of the independent terms. Depth-first,
  /// measurements in order of their best candidate, candidates best first, pruned by a bound:
  /// no measurement's term exceeds max(log p_new, the log density of N(0, Q) at its mean),
  /// since every innovation covariance is Q plus positive semi-definite terms.
  JointAssignment joint_association(const Scan& s, std::vector<Pair>& pairs, const Eigen::Vector3d& mu0,
                                    const Eigen::Matrix3d& p0, bool proposal, double log_p_new_call) const;

  /// Unknown correspondences: the association of one particle's scan (joint_association, or
  /// maximum likelihood pair by pair), then its landmark updates, new landmarks and
  /// negative information; the ids and new flags written to ids_out / new_out.
  void update_unknown(FastSlamParticle& part, const Scan& given, double log_p_new_call, long* ids_out,
                      std::uint8_t* new_out, std::vector<long>& removed) const;

  /// Provisional landmarks (FastSlamOptions::min_sightings): the confirmed leave the list, those
  /// unseen for more than provisional_max_age scans leave the map.
  void expire_provisional(FastSlamParticle& part, long scan, std::vector<long>& removed) const;
};

template <class F>
void FastSlam::for_particles(F&& f) {
  const int m = num_particles();
  const int workers = std::min(o_.threads, std::max(1, m / fastslam_detail::kMinParticlesPerThread));
  if (workers <= 1) {
    for (int k = 0; k < m; ++k) f(k);
    return;
  }
  if (!pool_ || static_cast<int>(pool_->size()) != workers) pool_ = std::make_unique<WorkerPool>(workers);
  pool_->run([&](std::size_t w) {
    const int begin = static_cast<int>(static_cast<long>(m) * static_cast<long>(w) / workers);
    const int end = static_cast<int>(static_cast<long>(m) * static_cast<long>(w + 1) / workers);
    for (int k = begin; k < end; ++k) f(k);
  });
}

template <class F>
void FastSlam::staged(F&& work) {
  // Double buffering: worker k overwrites spare_[k] (a particle no longer used, which it thereby
  // lets go of) with a copy of particles_[k], works on that copy and leaves its log weight in
  // weights_. So one hand-off per call does it all, each particle's memory and reference counts
  // stay with the thread that owns it, and the caller neither allocates, constructs, moves nor
  // reads particles. particles_ changes only when every worker is done.
  const std::size_t m = particles_.size();
  if (spare_.size() != m) spare_.resize(m);
  weights_.resize(m);
  for_particles([&](int k) {
    const auto i = static_cast<std::size_t>(k);
    FastSlamParticle& p = spare_[i];
    p = particles_[i];
    work(k, p);
    weights_[i] = p.log_weight;
  });
  particles_.swap(spare_);
  drop_spare_if_serial();
}

}  // namespace probslam
