#include "probslam/fastslam/fast_slam.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <iterator>
#include <string>
#include <unordered_set>
#include <utility>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/filter_limits.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "probslam/core/worker_pool.hpp"

namespace probslam {
namespace {

// Below this many particles per worker the threads' hand-off costs more than it saves.
constexpr int kMinParticlesPerThread = 16;
// The filter's own random stream (resampling offsets): a stream number no particle reaches.
constexpr std::uint64_t kFilterStream = ~std::uint64_t{0};

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

double lambda_max(const Eigen::Matrix2d& s) {
  const double h = 0.5 * (s(0, 0) + s(1, 1)), d = 0.5 * (s(0, 0) - s(1, 1));
  return h + std::sqrt(d * d + s(0, 1) * s(1, 0));
}

/// log N(nu; 0, s) for a 2x2 s; NaN unless s is positive definite.
double log_gauss2(const Eigen::Vector2d& nu, const Eigen::Matrix2d& s) {
  const double det = s(0, 0) * s(1, 1) - s(0, 1) * s(1, 0);
  if (!(det > 0.0) || !(s(0, 0) > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  const double m = (s(1, 1) * nu[0] * nu[0] - (s(0, 1) + s(1, 0)) * nu[0] * nu[1] + s(0, 0) * nu[1] * nu[1]) / det;
  return -0.5 * (m + std::log(kTwoPi * kTwoPi * det));
}

double log_gauss1(double nu, double var) { return -0.5 * (nu * nu / var + std::log(kTwoPi * var)); }

struct Predicted {
  Eigen::Vector2d z_hat;
  Eigen::Matrix<double, 2, 3> hx;
  Eigen::Matrix2d hm;
};

/// h and its Jacobians at (pose, landmark); false for a landmark on the robot.
bool predict_measurement(const Eigen::Vector3d& x, const Eigen::Vector2d& m, Predicted& out) {
  if (!((m - x.head<2>()).squaredNorm() >= kMinRangeSquared)) return false;
  // Poses and landmark means are finite by the filter's checks: the model without its own.
  MeasurementJacobians<2> j;
  range_bearing_unchecked(x, m, out.z_hat, j);
  out.hx = j.pose;
  out.hm = j.landmark;
  return true;
}

Eigen::Vector2d innovation(const Eigen::Vector2d& z, const Eigen::Vector2d& z_hat) {
  Eigen::Vector2d nu = z - z_hat;
  nu[1] = wrap_angle(nu[1]);  // bearings live on the circle
  return nu;
}

/// One step of the FastSLAM 2.0 proposal in Kalman form (see fastslam2_proposal); false for a
/// landmark on the pose mean.
bool proposal_step(Eigen::Vector3d& mu, Eigen::Matrix3d& p, const Landmark& lm, const Eigen::Vector2d& z,
                   const Eigen::Matrix2d& q, double& log_likelihood) {
  Predicted pr;
  if (!predict_measurement(mu, lm.mean, pr)) return false;
  const Eigen::Vector2d nu = innovation(z, pr.z_hat);
  const Eigen::Matrix2d qj = symmetric<2>(pr.hm * lm.cov * pr.hm.transpose()) + q;
  const Eigen::Matrix2d s = symmetric<2>(pr.hx * p * pr.hx.transpose()) + qj;
  const Eigen::Matrix<double, 3, 2> k = p * pr.hx.transpose() * s.inverse();
  mu += k * nu;
  mu[2] = wrap_angle(mu[2]);
  p = symmetric<3>(p - k * s * k.transpose());
  log_likelihood = log_gauss2(nu, s);
  return true;
}

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

}  // namespace

// ---- free functions ----

PoseProposal fastslam2_proposal(const Eigen::Vector3d& pose_mean, const Eigen::Matrix3d& pose_cov,
                                const Eigen::Vector2d& landmark_mean, const Eigen::Matrix2d& landmark_cov,
                                const Eigen::Vector2d& z, const Eigen::Matrix2d& measurement_noise) {
  require(on_map(pose_mean), "pose_mean", "must be finite with |x|, |y| <= 1e9 m (kMaxCoordinate)");
  require_covariance(pose_cov, "pose_cov", true);
  require(landmark_mean.allFinite() && landmark_mean.cwiseAbs().maxCoeff() <= kMaxCoordinate,
          "landmark_mean", "must be finite with |x|, |y| <= 1e9 m (kMaxCoordinate)");
  require_covariance(landmark_cov, "landmark_cov", true);
  require(z.allFinite() && z[0] >= 0.0 && z.cwiseAbs().maxCoeff() <= kMaxCoordinate, "z",
          "must be finite with a range in [0, 1e9]");
  require_covariance(measurement_noise, "measurement_noise", false);
  Landmark lm;
  lm.mean = landmark_mean;
  lm.cov = symmetric<2>(landmark_cov);
  PoseProposal out{pose_mean, symmetric<3>(pose_cov), 0.0};
  out.mean[2] = wrap_angle(out.mean[2]);
  require(proposal_step(out.mean, out.cov, lm, z, measurement_noise, out.log_likelihood), "landmark_mean",
          "coincides with the pose (no bearing)");
  require(out.mean.allFinite() && out.cov.allFinite() && std::isfinite(out.log_likelihood), "z",
          "gives a proposal that is not finite");
  return out;
}

// ---- the filter ----

/// What every particle's work in one call reads.
struct FastSlam::Context {
  const FastSlamOptions& o;
  Eigen::Matrix2d q;   // (range, bearing) noise
  double q_sig;        // signature variance
  double log_p_new;
  double log_outlier;  // log(outlier_density); -inf without the outlier model

  /// Signature log-likelihood of measurement i against lm (0 without signatures).
  double sig_log_likelihood(const Scan& s, Eigen::Index i, const Landmark& lm) const {
    return s.signatures ? log_gauss1(s.sig(i) - lm.signature, lm.signature_var + q_sig) : 0.0;
  }

  /// The landmark EKF update (version 1's, and version 2's after sampling) at pose x: returns
  /// log N(z - z_hat; 0, Q_j) (with the signature's factor), NaN for a landmark on the robot.
  double update_landmark(Landmark& lm, const Eigen::Vector3d& x, const Scan& s, Eigen::Index i) const {
    Predicted pr;
    if (!predict_measurement(x, lm.mean, pr)) return std::numeric_limits<double>::quiet_NaN();
    const Eigen::Vector2d nu = innovation(s.rb(i), pr.z_hat);
    const Eigen::Matrix2d qj = symmetric<2>(pr.hm * lm.cov * pr.hm.transpose()) + q;
    const Eigen::Matrix2d k = lm.cov * pr.hm.transpose() * qj.inverse();
    double ll = log_gauss2(nu, qj) + sig_log_likelihood(s, i, lm);
    lm.mean += k * nu;
    lm.cov = symmetric<2>(lm.cov - k * qj * k.transpose());
    if (s.signatures) {
      const double gain = lm.signature_var / (lm.signature_var + q_sig);
      lm.signature += gain * (s.sig(i) - lm.signature);
      lm.signature_var = (1.0 - gain) * lm.signature_var;
    }
    lm.existence += o.existence_hit;
    require(lm.mean.allFinite() && lm.cov.allFinite() && std::isfinite(ll) &&
                lm.mean.cwiseAbs().maxCoeff() <= 4.0 * kMaxCoordinate,
            "z", "cannot be applied: the landmark update would not be finite");
    return ll;
  }

  /// Table 13.1's initialisation: the inverse measurement model, Sigma = H^-1 Q H^-T.
  Landmark new_landmark(long id, const Eigen::Vector3d& x, const Scan& s, Eigen::Index i) const {
    Landmark lm;
    lm.id = id;
    MeasurementJacobians<2> j;
    landmark_from_range_bearing_unchecked(x, s.rb(i), lm.mean, j);
    const Eigen::Matrix2d& gz = j.landmark;  // = H^-1
    lm.cov = symmetric<2>(gz * q * gz.transpose());
    lm.existence = o.existence_hit;
    if (s.signatures) {
      lm.signature = s.sig(i);
      lm.signature_var = q_sig;
    }
    require(lm.cov.allFinite(), "z", "places a landmark whose covariance is not finite");
    return lm;
  }

  /// Moves the path poses of the motions since the last update so that the newest becomes x:
  /// pose i of n shifted by i / n of (x - the newest), the correction spread along the stretch
  /// the proposal conditioned on (a linear bridge) instead of a jump at its end.
  void bridge_path(FastSlamParticle& part, const Eigen::Vector3d& x) const {
    const std::size_t n = static_cast<std::size_t>(std::max(1, part.moves_since_update));
    const std::vector<Eigen::Vector3d> moved = part.path.newest(n);
    if (moved.empty() || moved.back() == x) return;  // a noise-free motion: nothing to move
    Eigen::Vector3d shift = x - moved.back();
    shift[2] = wrap_angle(shift[2]);
    for (std::size_t i = 0; i < moved.size(); ++i) part.path.pop();
    for (std::size_t i = 0; i + 1 < moved.size(); ++i) {
      Eigen::Vector3d y = moved[i] + shift * (static_cast<double>(i + 1) / static_cast<double>(moved.size()));
      y[2] = wrap_angle(y[2]);
      part.path.push(y);
    }
    part.path.push(x);
  }

  /// An update ends the motion since the last one: version 2's path is bridged to the pose (the
  /// proposal's sample, or the motion sample where no measurement entered the proposal).
  void end_motion(FastSlamParticle& part) const {
    if (o.version == 2 && part.has_prior && o.record_path) bridge_path(part, part.pose);
    part.has_prior = false;
    part.moves_since_update = 0;
  }

  /// Samples the pose from N(mu, p) when a proposal step changed the prior; the update's
  /// end_motion bridges the path to it.
  void take_proposal_sample(FastSlamParticle& part, const Eigen::Vector3d& mu, const Eigen::Matrix3d& p) const {
    const Eigen::Matrix3d l = psd_factor<3>(p);
    const Eigen::Vector3d n(part.rng.normal(), part.rng.normal(), part.rng.normal());
    Eigen::Vector3d x = mu + l * n;
    x[2] = wrap_angle(x[2]);
    require(on_map(x), "z", "moves the pose beyond 1e9 m (kMaxCoordinate)");
    part.pose = x;
  }

  /// With a bearing offset model: samples the particle's offset for this scan from its
  /// transition and returns the scan's measurements with their bearings corrected by it (in
  /// `storage`); without, the measurements as given.
  Eigen::Ref<const RowMatrixXd> offset_corrected(FastSlamParticle& part, const Scan& s, RowMatrixXd& storage) const {
    if (o.bearing_offset_sigma == 0.0 || s.z.rows() == 0) return s.z;
    const double rho = o.bearing_offset_correlation;
    part.bearing_offset = rho * part.bearing_offset + std::sqrt(1.0 - rho * rho) * o.bearing_offset_sigma * part.rng.normal();
    storage = s.z;
    for (Eigen::Index i = 0; i < storage.rows(); ++i) storage(i, 1) = wrap_angle(storage(i, 1) - part.bearing_offset);
    return storage;
  }

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

  void update_known(FastSlamParticle& part, const Scan& given, const std::vector<long>& ids) const {
    RowMatrixXd storage;
    const Eigen::Ref<const RowMatrixXd> z = offset_corrected(part, given, storage);
    const Scan s{z, given.signatures};
    const Eigen::Index k = s.z.rows();
    if (k == 0) {
      part.last_log_likelihood = 0.0;
      return;
    }
    double ll = 0.0;
    // Per measurement: 1 when it entered the proposal (weighted there), 2 when the outlier
    // density claimed it (weighted, its landmark left as it was).
    std::vector<std::uint8_t> handled(static_cast<std::size_t>(k), 0);
    constexpr std::uint8_t kInProposal = 1, kOutlier = 2;
    if (o.version == 2 && part.has_prior) {
      // The proposal, measurement by measurement: each step's posterior is the next one's prior.
      Eigen::Vector3d mu = part.prior_mean;
      Eigen::Matrix3d p = part.prior_cov;
      std::unordered_set<long> used;
      bool any = false;
      for (Eigen::Index i = 0; i < k; ++i) {
        const Landmark* lm = part.map.find(ids[static_cast<std::size_t>(i)]);
        if (!lm || !used.insert(lm->id).second) continue;
        Eigen::Vector3d mu_next = mu;
        Eigen::Matrix3d p_next = p;
        double step = 0.0;
        if (!proposal_step(mu_next, p_next, *lm, s.rb(i), q, step)) continue;
        step += sig_log_likelihood(s, i, *lm);
        ll += with_outliers(step);
        // An outlier under the marginal likelihood must not pull the proposal either.
        if (is_outlier(step)) {
          handled[static_cast<std::size_t>(i)] = kOutlier;
          continue;
        }
        mu = mu_next;
        p = p_next;
        handled[static_cast<std::size_t>(i)] = kInProposal;
        any = true;
      }
      if (any) take_proposal_sample(part, mu, p);
    }
    for (Eigen::Index i = 0; i < k; ++i) {
      const long id = ids[static_cast<std::size_t>(i)];
      const std::uint8_t how = handled[static_cast<std::size_t>(i)];
      if (how == kOutlier) continue;
      if (const Landmark* found = part.map.find(id)) {
        Landmark lm = *found;
        const double step = update_landmark(lm, part.pose, s, i);
        if (std::isnan(step)) continue;  // on the robot: no bearing, skipped
        if (how != kInProposal) {
          ll += with_outliers(step);
          if (is_outlier(step)) continue;  // lm is a copy: the map keeps the landmark as it was
        }
        part.map.put(lm);
      } else {
        part.map.put(new_landmark(id, part.pose, s, i));
        ll += log_p_new;
      }
    }
    end_motion(part);
    add_log_likelihood(part, ll);
  }

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
                                    const Eigen::Matrix3d& p0, bool proposal, double log_p_new_call) const {
    const Eigen::Index k = s.z.rows();
    // Measurement i's candidates, best first: pairs[first[i] .. first[i + 1]) after the sort.
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
      if (a.i != b.i) return a.i < b.i;
      return a.ll != b.ll ? a.ll > b.ll : a.id < b.id;
    });
    std::vector<std::size_t> first(static_cast<std::size_t>(k) + 1, 0);
    for (const Pair& pr : pairs) ++first[static_cast<std::size_t>(pr.i) + 1];
    for (std::size_t i = 0; i < static_cast<std::size_t>(k); ++i) first[i + 1] += first[i];
    struct Candidates {
      const Pair* b;
      const Pair* e;
      const Pair* begin() const { return b; }
      const Pair* end() const { return e; }
      bool empty() const { return b == e; }
      const Pair* front() const { return b; }
    };
    std::vector<Candidates> cands(static_cast<std::size_t>(k));
    for (std::size_t i = 0; i < cands.size(); ++i) cands[i] = {pairs.data() + first[i], pairs.data() + first[i + 1]};
    JointAssignment best;
    if (!proposal) {
      // The pose known, the terms are independent: when no two measurements' best candidates
      // coincide, each taking its best is the optimum (the common case, at no search).
      best.ids.assign(static_cast<std::size_t>(k), -1);
      std::unordered_set<long> firsts;
      bool distinct = true;
      for (Eigen::Index i = 0; i < k && distinct; ++i) {
        const auto& c = cands[static_cast<std::size_t>(i)];
        if (c.empty()) continue;
        distinct = firsts.insert(c.front()->id).second;
        best.ids[static_cast<std::size_t>(i)] = c.front()->id;
      }
      if (distinct) return best;
    }
    std::vector<Eigen::Index> order(static_cast<std::size_t>(k));
    for (Eigen::Index i = 0; i < k; ++i) order[static_cast<std::size_t>(i)] = i;
    const auto best_ll = [&](Eigen::Index i) {
      const auto& c = cands[static_cast<std::size_t>(i)];
      return c.empty() ? log_p_new_call : c.front()->ll;
    };
    std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) { return best_ll(a) > best_ll(b); });
    const double sig_peak = s.signatures ? -0.5 * std::log(kTwoPi * q_sig) : 0.0;
    const double peak = std::max(log_p_new_call, -0.5 * std::log(kTwoPi * kTwoPi * q.determinant()) + sig_peak);
    // bound[d]: the most the measurements order[d..] can add.
    std::vector<double> bound(static_cast<std::size_t>(k) + 1, 0.0);
    for (Eigen::Index d = k - 1; d >= 0; --d) {
      const bool matchable = !cands[static_cast<std::size_t>(order[static_cast<std::size_t>(d)])].empty();
      bound[static_cast<std::size_t>(d)] = bound[static_cast<std::size_t>(d) + 1] + (matchable ? peak : log_p_new_call);
    }
    double best_score = -std::numeric_limits<double>::infinity();
    std::vector<long> current(static_cast<std::size_t>(k), -1);
    long nodes = 0;
    // score: the total so far; match: its matched part.
    const auto search = [&](const auto& self, std::size_t d, const Eigen::Vector3d& mu, const Eigen::Matrix3d& p,
                            double score, double match, bool any) -> void {
      if (++nodes > kJointAssociationMaxNodes && best_score > -std::numeric_limits<double>::infinity()) return;
      if (!(score + bound[d] > best_score)) return;
      if (d == static_cast<std::size_t>(k)) {
        best_score = score;
        best.ids = current;
        best.match_log_likelihood = match;
        best.any = any;
        best.mu = mu;
        best.p = p;
        return;
      }
      const Eigen::Index i = order[d];
      for (const Pair& cand : cands[static_cast<std::size_t>(i)]) {
        const Pair* c = &cand;
        if (std::find(current.begin(), current.end(), c->id) != current.end()) continue;
        Eigen::Vector3d mu_next = mu;
        Eigen::Matrix3d p_next = p;
        double step = c->ll;
        if (proposal) {
          if (!proposal_step(mu_next, p_next, *c->lm, s.rb(i), q, step)) continue;
          step += sig_log_likelihood(s, i, *c->lm);
          if (!std::isfinite(step)) continue;
        }
        current[static_cast<std::size_t>(i)] = c->id;
        self(self, d + 1, mu_next, p_next, score + step, match + step, true);
        current[static_cast<std::size_t>(i)] = -1;
      }
      self(self, d + 1, mu, p, score + log_p_new_call, match, any);
    };
    search(search, 0, mu0, p0, 0.0, 0.0, false);
    return best;
  }

  void update_unknown(FastSlamParticle& part, const Scan& given, double log_p_new_call, long* ids_out,
                      std::uint8_t* new_out, std::vector<long>& removed) const {
    RowMatrixXd storage;
    const Eigen::Ref<const RowMatrixXd> z = offset_corrected(part, given, storage);
    const Scan s{z, given.signatures};
    const Eigen::Index k = s.z.rows();
    const bool proposal = o.version == 2 && part.has_prior;
    Eigen::Vector3d mu = proposal ? part.prior_mean : part.pose;
    Eigen::Matrix3d p = proposal ? part.prior_cov : Eigen::Matrix3d::Zero();
    // Candidate pairs whose likelihood exceeds p_new, from the landmarks near where each
    // measurement places its landmark (version 2: the marginal likelihood at the prior mean),
    // found in one walk of the map for the whole scan (their order does not matter: the
    // association sorts them).
    std::vector<LandmarkMap::Disc> discs(static_cast<std::size_t>(k));
    for (Eigen::Index i = 0; i < k; ++i) {
      MeasurementJacobians<2> j;
      LandmarkMap::Disc& d = discs[static_cast<std::size_t>(i)];
      landmark_from_range_bearing_unchecked(mu, s.rb(i), d.center, j);
      const Eigen::Matrix2d spread =
          j.landmark * q * j.landmark.transpose() + j.pose * p * j.pose.transpose();
      d.radius = o.association_radius + kPlacementSigmas * std::sqrt(std::max(0.0, lambda_max(spread)));
    }
    std::vector<Pair> pairs;
    part.map.for_each_within_any(discs, [&](const Landmark& lm, std::size_t at) {
      const auto i = static_cast<Eigen::Index>(at);
      Predicted pr;
      if (!predict_measurement(mu, lm.mean, pr)) return;
      const Eigen::Matrix2d sm = symmetric<2>(pr.hm * lm.cov * pr.hm.transpose()) + q +
                                 symmetric<2>(pr.hx * p * pr.hx.transpose());
      const double ll = log_gauss2(innovation(s.rb(i), pr.z_hat), sm) + sig_log_likelihood(s, i, lm);
      if (ll > log_p_new_call) pairs.push_back({ll, i, lm.id, &lm});
    });
    std::vector<long> assigned(static_cast<std::size_t>(k), -1);
    double ll = 0.0;
    std::vector<std::uint8_t> in_proposal(static_cast<std::size_t>(k), 0);
    if (o.joint_association) {
      const JointAssignment best = joint_association(s, pairs, mu, p, proposal, log_p_new_call);
      assigned = best.ids;
      if (proposal && best.any) {
        for (Eigen::Index i = 0; i < k; ++i) in_proposal[static_cast<std::size_t>(i)] = assigned[static_cast<std::size_t>(i)] >= 0;
        ll += best.match_log_likelihood;
        take_proposal_sample(part, best.mu, best.p);
      }
    } else {
      // Maximum likelihood, best pairs first, one measurement per landmark and scan.
      std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
        if (a.ll != b.ll) return a.ll > b.ll;
        if (a.i != b.i) return a.i < b.i;
        return a.id < b.id;
      });
      std::unordered_set<long> taken;
      for (const Pair& pr : pairs) {
        long& a = assigned[static_cast<std::size_t>(pr.i)];
        if (a < 0 && taken.insert(pr.id).second) a = pr.id;
      }
      if (proposal) {
        bool any = false;
        for (Eigen::Index i = 0; i < k; ++i) {
          if (assigned[static_cast<std::size_t>(i)] < 0) continue;
          const Landmark& lm = *part.map.find(assigned[static_cast<std::size_t>(i)]);
          double step = 0.0;
          if (!proposal_step(mu, p, lm, s.rb(i), q, step)) continue;
          ll += step + sig_log_likelihood(s, i, lm);
          in_proposal[static_cast<std::size_t>(i)] = 1;
          any = true;
        }
        if (any) take_proposal_sample(part, mu, p);
      }
    }
    std::unordered_set<long> seen;  // for negative information only
    const long scan = ++part.scans;
    for (Eigen::Index i = 0; i < k; ++i) {
      const long id = assigned[static_cast<std::size_t>(i)];
      bool created = id < 0;
      if (!created) {
        Landmark lm = *part.map.find(id);
        const double step = update_landmark(lm, part.pose, s, i);
        if (std::isnan(step)) {
          created = true;  // on the robot now: cannot be this landmark
        } else {
          if (!in_proposal[static_cast<std::size_t>(i)]) ll += step;
          lm.sightings = std::min(lm.sightings + 1, kFastSlamMaxCount);
          lm.last_seen = scan;
          part.map.put(lm);
          ids_out[i] = id;
          new_out[i] = 0;
          if (o.negative_information) seen.insert(id);
        }
      }
      if (created) {
        const long nid = part.next_id++;
        Landmark lm = new_landmark(nid, part.pose, s, i);
        lm.last_seen = scan;
        part.map.put(lm);
        if (o.min_sightings > 1) part.provisional.push_back(nid);
        ll += log_p_new_call;
        ids_out[i] = nid;
        new_out[i] = 1;
        if (o.negative_information) seen.insert(nid);
      }
    }
    if (o.negative_information) {
      // Landmarks in the perceptual field that this scan did not see lose existence.
      std::vector<Landmark> missed;
      const Eigen::Vector3d x = part.pose;
      part.map.for_each_within(x.head<2>(), o.sensor_range, [&](const Landmark& lm) {
        if (!seen.count(lm.id) && in_sensor_field(x, lm.mean, o.sensor_range, o.sensor_fov)) missed.push_back(lm);
      });
      for (Landmark& lm : missed) {
        lm.existence -= o.existence_miss;
        if (lm.existence < 0.0) {
          part.map.erase(lm.id);
          removed.push_back(lm.id);
        } else {
          part.map.put(lm);
        }
      }
    }
    expire_provisional(part, scan, removed);
    if (k > 0) end_motion(part);
    add_log_likelihood(part, ll);
  }

  /// Provisional landmarks (FastSlamOptions::min_sightings): the confirmed leave the list, those
  /// unseen for more than provisional_max_age scans leave the map.
  void expire_provisional(FastSlamParticle& part, long scan, std::vector<long>& removed) const {
    std::size_t kept = 0;
    for (const long id : part.provisional) {
      const Landmark* lm = part.map.find(id);
      if (lm == nullptr || lm->sightings >= o.min_sightings) continue;  // gone, or confirmed
      if (scan - lm->last_seen > o.provisional_max_age) {
        part.map.erase(id);
        removed.push_back(id);
        continue;
      }
      part.provisional[kept++] = id;
    }
    part.provisional.resize(kept);
  }
};

void FastSlamOptions::validate() const {
  require(num_particles >= 1 && num_particles <= kFastSlamMaxParticles, "num_particles",
          "must be in [1, 2^20] (kFastSlamMaxParticles)");
  require(version == 1 || version == 2, "version", "must be 1 or 2");
  require(threads >= 1 && threads <= kFastSlamMaxThreads, "threads", "must be in [1, 256] (kFastSlamMaxThreads)");
  require(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0,
          "resample_threshold", "must be in [0, 1]");
  require(std::isfinite(p_new) && p_new > 0.0 && std::isfinite(std::log(p_new)), "p_new", "must be finite and > 0");
  require(std::isfinite(outlier_density) && outlier_density >= 0.0, "outlier_density",
          "must be finite and >= 0 (0: no outlier model)");
  require(std::isfinite(association_radius) && association_radius >= 0.0 && association_radius <= kMaxCoordinate,
          "association_radius", "must be in [0, 1e9] m");
  require(std::isfinite(cell_size) && cell_size >= kMinHashCellSize && cell_size <= kMaxCoordinate, "cell_size",
          "must be in [1e-6, 1e9] m (kMinHashCellSize)");
  require(std::isfinite(existence_hit) && existence_hit >= 0.0 && existence_hit <= kMaxCoordinate, "existence_hit",
          "must be in [0, 1e9]");
  require(std::isfinite(existence_miss) && existence_miss >= 0.0 && existence_miss <= kMaxCoordinate,
          "existence_miss", "must be in [0, 1e9]");
  require(min_sightings >= 1 && min_sightings <= kFastSlamMaxCount, "min_sightings", "must be in [1, 1e6]");
  require(provisional_max_age >= 0 && provisional_max_age <= kFastSlamMaxCount, "provisional_max_age",
          "must be in [0, 1e6]");
  require(sensor_range > 0.0 && (std::isinf(sensor_range) || sensor_range <= kMaxCoordinate), "sensor_range",
          "must be > 0 m (and at most 1e9 m, or infinite)");
  require(!negative_information || std::isfinite(sensor_range), "sensor_range",
          "must be finite with negative_information");
  require(std::isfinite(sensor_fov) && sensor_fov > 0.0 && sensor_fov <= kTwoPi, "sensor_fov",
          "must be in (0, 2 pi] rad");
  require(std::isfinite(bearing_offset_sigma) && bearing_offset_sigma >= 0.0 && bearing_offset_sigma <= kPi,
          "bearing_offset_sigma", "must be in [0, pi] rad");
  require(std::isfinite(bearing_offset_correlation) && bearing_offset_correlation >= 0.0 &&
              bearing_offset_correlation < 1.0,
          "bearing_offset_correlation", "must be in [0, 1)");
}

FastSlam::FastSlam(const Eigen::MatrixXd& motion_noise, const Eigen::MatrixXd& measurement_noise,
                   const FastSlamOptions& options, const Eigen::Vector3d& initial_pose)
    : o_(options) {
  o_.validate();
  require((motion_noise.rows() == 3 && motion_noise.cols() == 3) || (motion_noise.rows() == 2 && motion_noise.cols() == 2),
          "motion_noise", "must be 3x3 (pose space) or 2x2 (control space)");
  require_covariance(motion_noise, "motion_noise", true);
  const int md = o_.use_signatures ? 3 : 2;
  require(measurement_noise.rows() == md && measurement_noise.cols() == md, "measurement_noise",
          o_.use_signatures ? "must be 3x3 (range, bearing, signature)" : "must be 2x2 (range, bearing)");
  require_covariance(measurement_noise, "measurement_noise", false);
  if (o_.use_signatures)
    require(measurement_noise(0, 2) == 0.0 && measurement_noise(1, 2) == 0.0 && measurement_noise(2, 0) == 0.0 &&
                measurement_noise(2, 1) == 0.0,
            "measurement_noise", "the signature must be uncorrelated with range and bearing (zero off-diagonal entries)");
  require(on_map(initial_pose), "initial_pose", "must be finite with |x|, |y| <= 1e9 m (kMaxCoordinate)");

  motion_noise_ = symmetric<Eigen::Dynamic>(motion_noise);
  control_noise_ = motion_noise_.rows() == 2;
  if (control_noise_) control_factor_ = psd_factor<2>(Eigen::Matrix2d(motion_noise_));
  else motion_factor_ = psd_factor<3>(Eigen::Matrix3d(motion_noise_));
  measurement_noise_ = symmetric<Eigen::Dynamic>(measurement_noise);
  q2_ = measurement_noise_.topLeftCorner<2, 2>();
  if (o_.use_signatures) q_signature_ = measurement_noise_(2, 2);
  initial_pose_ = initial_pose;
  initial_pose_[2] = wrap_angle(initial_pose_[2]);

  const int m = o_.num_particles;
  particles_.resize(static_cast<std::size_t>(m));
  for (int k = 0; k < m; ++k) {
    FastSlamParticle& p = particles_[static_cast<std::size_t>(k)];
    p.pose = initial_pose_;
    p.log_weight = -std::log(static_cast<double>(m));
    p.map = LandmarkMap(o_.cell_size);
    p.rng = ParticleRng(o_.seed, static_cast<std::uint64_t>(k));
    if (o_.bearing_offset_sigma > 0.0) p.bearing_offset = o_.bearing_offset_sigma * p.rng.normal();  // stationary
    if (o_.record_path) p.path.push(p.pose);
  }
  next_stream_ = static_cast<std::uint64_t>(m);
  rng_ = ParticleRng(o_.seed, kFilterStream);
}

FastSlam::FastSlam(const FastSlam& other)
    : o_(other.o_),
      motion_noise_(other.motion_noise_),
      measurement_noise_(other.measurement_noise_),
      initial_pose_(other.initial_pose_),
      motion_factor_(other.motion_factor_),
      control_factor_(other.control_factor_),
      control_noise_(other.control_noise_),
      q2_(other.q2_),
      q_signature_(other.q_signature_),
      particles_(other.particles_),
      rng_(other.rng_),
      next_stream_(other.next_stream_),
      resamples_(other.resamples_),
      last_resampled_(other.last_resampled_),
      last_ancestors_(other.last_ancestors_) {}

FastSlam& FastSlam::operator=(const FastSlam& other) {
  if (this != &other) {
    FastSlam copy(other);
    *this = std::move(copy);
  }
  return *this;
}

FastSlam::FastSlam(FastSlam&&) noexcept = default;
FastSlam& FastSlam::operator=(FastSlam&&) noexcept = default;
FastSlam::~FastSlam() = default;

template <class F>
void FastSlam::for_particles(F&& f) {
  const int m = num_particles();
  const int workers = std::min(o_.threads, std::max(1, m / kMinParticlesPerThread));
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

void FastSlam::drop_spare_if_serial() {
  // With workers, the next call's workers let go of spare_ as they overwrite it; alone, at once.
  if (!pool_)
    for (FastSlamParticle& p : spare_) p.drop_shared();
}

std::vector<int> FastSlam::commit() {
  // Table 4.4's resampling when N_eff is low; the weights normalised by log-sum-exp.
  const double n_eff = normalise_log_weights(weights_);
  std::vector<int> ancestors;
  if (n_eff < o_.resample_threshold * num_particles()) ancestors = resampling_ancestors(weights_, rng_);
  settle(ancestors);
  return ancestors;
}

void FastSlam::settle(const std::vector<int>& ancestors) {
  last_ancestors_ = ancestors;
  last_resampled_ = !ancestors.empty();
  if (ancestors.empty()) {
    for_particles([&](int k) { particles_[static_cast<std::size_t>(k)].log_weight = weights_[static_cast<std::size_t>(k)]; });
    return;
  }
  // Copies share their ancestor's map and path: O(1) each. The j-th new particle takes random
  // stream next_stream_ + j, so a seed gives the same result for any number of threads.
  const double log_weight = -std::log(static_cast<double>(num_particles()));
  const std::uint64_t first_stream = next_stream_;
  for_particles([&](int k) {
    const auto i = static_cast<std::size_t>(k);
    FastSlamParticle& p = spare_[i];
    p = particles_[static_cast<std::size_t>(ancestors[i])];
    p.rng = ParticleRng(o_.seed, first_stream + static_cast<std::uint64_t>(k));
    p.log_weight = log_weight;
  });
  particles_.swap(spare_);
  drop_spare_if_serial();
  next_stream_ += static_cast<std::uint64_t>(num_particles());
  ++resamples_;
}

void FastSlam::resample() {
  weights_.resize(particles_.size());
  for (std::size_t k = 0; k < particles_.size(); ++k) weights_[k] = particles_[k].log_weight;
  if (spare_.size() != particles_.size()) spare_.resize(particles_.size());
  settle(resampling_ancestors(weights_, rng_));
}

template <class Sample>
void FastSlam::move_particles(int steps, Sample&& sample) {
  // One pass, in place (no particle is copied, so no shared node's count changes): worker k
  // keeps particle k's state in moves_[k], stamped with this call, before it moves the particle.
  // A sample that throws leaves its particle untouched (the path poses it appended are popped);
  // every particle already moved is then put back from moves_, so the call changes nothing.
  moves_.resize(particles_.size());
  const std::uint64_t stamp = ++move_calls_;
  try {
    for_particles([&](int k) {
      const auto i = static_cast<std::size_t>(k);
      FastSlamParticle& p = particles_[i];
      ParticleRng rng = p.rng;
      const Motion before{p.pose, p.prior_mean, p.prior_cov};
      Motion now = before;
      // Version 2: the motion prior composes from the last update's pose (has_prior: no update
      // since), so the proposal covers every motion between two updates.
      bool has_prior = p.has_prior;
      int moves = p.moves_since_update;
      int pushed = 0;
      try {
        for (int step = 0; step < steps; ++step) {
          Motion next;
          sample(step, now.pose, rng, next, o_.version == 2 && has_prior ? &now : nullptr);
          now.pose = next.pose;
          if (o_.version == 2) {
            now.prior_mean = next.prior_mean;
            now.prior_cov = next.prior_cov;
            moves = has_prior ? moves + 1 : 1;
            has_prior = true;
          }
          // Version 2's path holds the motion prior's mean: an update draws the pose and bridges
          // the poses since the last one to it (bridge_path), so they carry no noise of their own.
          if (o_.record_path) {
            p.path.push(o_.version == 2 ? next.prior_mean : next.pose);
            ++pushed;
          }
        }
      } catch (...) {
        for (; pushed > 0; --pushed) p.path.pop();
        throw;
      }
      moves_[i] = Move{before, p.rng, p.has_prior, p.moves_since_update, stamp, pushed};
      p.rng = rng;
      p.pose = now.pose;
      p.prior_mean = now.prior_mean;
      p.prior_cov = now.prior_cov;
      p.has_prior = has_prior;
      p.moves_since_update = moves;
    });
  } catch (...) {
    for (std::size_t i = 0; i < particles_.size(); ++i) {
      const Move& kept = moves_[i];
      if (kept.stamp != stamp) continue;
      FastSlamParticle& p = particles_[i];
      p.pose = kept.before.pose;
      p.prior_mean = kept.before.prior_mean;
      p.prior_cov = kept.before.prior_cov;
      p.rng = kept.rng;
      p.has_prior = kept.has_prior;
      p.moves_since_update = kept.moves_since_update;
      for (int n = 0; n < kept.pushed; ++n) p.path.pop();
    }
    throw;
  }
  last_ancestors_.clear();
}

void FastSlam::predict(double v, double w, double dt) {
  // Validates v, w, dt (finite, dt > 0) before anything changes.
  velocity_motion_jacobian(initial_pose_, v, w, dt);
  require(std::fabs(v * dt) <= kMaxCoordinate, "v", "* dt must be <= 1e9 m (kMaxCoordinate)");
  const Eigen::Matrix3d r = control_noise_ ? Eigen::Matrix3d::Zero() : Eigen::Matrix3d(motion_noise_);
  const Eigen::Matrix2d mc = control_noise_ ? Eigen::Matrix2d(motion_noise_) : Eigen::Matrix2d::Zero();
  move_particles(1, [&](int, const Eigen::Vector3d& x, ParticleRng& rng, Motion& mv, const Motion* since) {
    if (control_noise_) {
      const Eigen::Vector2d e = control_factor_ * Eigen::Vector2d(rng.normal(), rng.normal());
      mv.pose = velocity_motion(x, v + e[0], w + e[1], dt);
    } else {
      const Eigen::Vector3d e = motion_factor_ * Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
      mv.pose = velocity_motion(x, v, w, dt) + e;
      mv.pose[2] = wrap_angle(mv.pose[2]);
    }
    require(on_map(mv.pose), "v", "moves the robot beyond 1e9 m (kMaxCoordinate)");
    if (o_.version == 2) {
      const Eigen::Vector3d& from = since ? since->prior_mean : x;
      mv.prior_mean = velocity_motion(from, v, w, dt);
      if (control_noise_) {
        const Eigen::Matrix<double, 3, 2> vj = velocity_motion_control_jacobian(from, v, w, dt);
        mv.prior_cov = symmetric<3>(vj * mc * vj.transpose());
      } else {
        mv.prior_cov = r;
      }
      if (since) {
        const Eigen::Matrix3d g = velocity_motion_jacobian(from, v, w, dt);
        mv.prior_cov = symmetric<3>(g * since->prior_cov * g.transpose() + mv.prior_cov);
      }
    }
  });
}

void FastSlam::predict_odometry(const Eigen::Vector3d& delta, const Eigen::Matrix3d& noise) {
  require_odometry_step(delta, noise, "delta", "noise");
  const Eigen::Matrix3d cov = symmetric<3>(noise);
  odometry_steps({delta}, {cov}, {psd_factor<3>(cov)}, "delta");
}

void FastSlam::predict_odometry_batch(const Eigen::Ref<const RowMatrixXd>& deltas,
                                      const Eigen::Ref<const RowMatrixXd>& noises) {
  require_odometry_batch(deltas, noises);
  const auto n = static_cast<std::size_t>(deltas.rows());
  require(n <= static_cast<std::size_t>(std::numeric_limits<int>::max()), "deltas", "has too many rows");
  std::vector<Eigen::Vector3d> d(n);
  std::vector<Eigen::Matrix3d> covs(n), factors(n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto row = static_cast<Eigen::Index>(k);
    d[k] = deltas.row(row).transpose();
    const Eigen::Matrix3d noise = odometry_batch_noise(noises, row);
    const std::string dn = "deltas[" + std::to_string(k) + "]", nn = "noises[" + std::to_string(k) + "]";
    require_odometry_step(d[k], noise, dn.c_str(), nn.c_str());
    covs[k] = symmetric<3>(noise);
    factors[k] = psd_factor<3>(covs[k]);
  }
  if (n > 0) odometry_steps(d, covs, factors, "deltas");
}

void FastSlam::odometry_steps(const std::vector<Eigen::Vector3d>& deltas, const std::vector<Eigen::Matrix3d>& covs,
                              const std::vector<Eigen::Matrix3d>& factors, const char* name) {
  move_particles(static_cast<int>(deltas.size()), [&](int step, const Eigen::Vector3d& x, ParticleRng& rng, Motion& mv,
                                                      const Motion* since) {
    const auto k = static_cast<std::size_t>(step);
    const Eigen::Vector3d& delta = deltas[k];
    const Eigen::Matrix2d rx = rotation_matrix(x[2]);
    const Eigen::Vector3d d = delta + factors[k] * Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
    mv.pose.head<2>() = x.head<2>() + rx * d.head<2>();
    mv.pose[2] = wrap_angle(x[2] + d[2]);
    require(on_map(mv.pose), name, "moves the robot beyond 1e9 m (kMaxCoordinate)");
    if (o_.version == 2) {
      const Eigen::Vector3d& from = since ? since->prior_mean : x;
      const Eigen::Matrix2d rf = rotation_matrix(from[2]);
      const Eigen::Vector2d step_xy = rf * delta.head<2>();
      mv.prior_mean.head<2>() = from.head<2>() + step_xy;
      mv.prior_mean[2] = wrap_angle(from[2] + delta[2]);
      Eigen::Matrix3d j = Eigen::Matrix3d::Identity();  // d(from (+) delta) / d delta
      j.topLeftCorner<2, 2>() = rf;
      mv.prior_cov = symmetric<3>(j * covs[k] * j.transpose());
      if (since) {
        Eigen::Matrix3d g = Eigen::Matrix3d::Identity();  // d(from (+) delta) / d from
        g(0, 2) = -step_xy[1];
        g(1, 2) = step_xy[0];
        mv.prior_cov = symmetric<3>(g * since->prior_cov * g.transpose() + mv.prior_cov);
      }
    }
  });
}

void FastSlam::check_measurements(const Eigen::Ref<const RowMatrixXd>& z) const {
  require_measurement_rows(z, landmark_dim());
}

void FastSlam::check_room(const FastSlamParticle& p, Eigen::Index added) {
  require(static_cast<long>(p.map.size()) + added <= kFastSlamMaxLandmarks, "z",
          "would grow a map beyond 2^26 landmarks (kFastSlamMaxLandmarks)");
  require(p.next_id <= kMaxLandmarkId - added, "z", "would need landmark ids beyond 2^62");
}

bool FastSlam::update(const Eigen::Ref<const RowMatrixXd>& z, const std::vector<long>& ids) {
  check_measurements(z);
  require(static_cast<Eigen::Index>(ids.size()) == z.rows(), "ids", "must have one id per measurement");
  for (long id : ids) require(id >= 0 && id <= kMaxLandmarkId, "ids", "must be in [0, 2^62]");
  const Context c{o_, q2_, q_signature_, std::log(o_.p_new), std::log(o_.outlier_density)};
  const Scan s{z, o_.use_signatures};
  staged([&](int, FastSlamParticle& p) {
    check_room(p, z.rows());  // in the workers: the caller reads no particle
    c.update_known(p, s, ids);
  });
  commit();
  return last_resampled_;
}

FastSlamAssociation FastSlam::update_unknown(const Eigen::Ref<const RowMatrixXd>& z) {
  return update_unknown(z, o_.p_new);
}

FastSlamAssociation FastSlam::update_unknown(const Eigen::Ref<const RowMatrixXd>& z, double p_new) {
  check_measurements(z);
  require(std::isfinite(p_new) && p_new > 0.0 && std::isfinite(std::log(p_new)), "p_new", "must be finite and > 0");
  const Context c{o_, q2_, q_signature_, std::log(o_.p_new), std::log(o_.outlier_density)};
  const Scan s{z, o_.use_signatures};
  const int m = num_particles();
  const auto k = static_cast<std::size_t>(z.rows());
  FastSlamAssociation out;
  out.num_particles = m;
  out.num_measurements = static_cast<int>(k);
  out.ids.assign(static_cast<std::size_t>(m) * k, -1);
  out.is_new.assign(static_cast<std::size_t>(m) * k, 0);
  std::vector<std::vector<long>> removed(static_cast<std::size_t>(m));
  out.removed.resize(static_cast<std::size_t>(m));
  const double log_p_new = std::log(p_new);
  staged([&](int j, FastSlamParticle& p) {
    check_room(p, z.rows());
    const auto at = static_cast<std::size_t>(j) * k;
    c.update_unknown(p, s, log_p_new, out.ids.data() + at, out.is_new.data() + at, removed[static_cast<std::size_t>(j)]);
  });
  const std::vector<int> ancestors = commit();
  if (!ancestors.empty()) {  // rows follow the particles after resampling
    FastSlamAssociation moved = out;
    for (int j = 0; j < m; ++j) {
      const auto from = static_cast<std::size_t>(ancestors[static_cast<std::size_t>(j)]);
      std::copy_n(out.ids.begin() + static_cast<std::ptrdiff_t>(from * k), k,
                  moved.ids.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(j) * k));
      std::copy_n(out.is_new.begin() + static_cast<std::ptrdiff_t>(from * k), k,
                  moved.is_new.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(j) * k));
      moved.removed[static_cast<std::size_t>(j)] = removed[from];
    }
    return moved;
  }
  out.removed = std::move(removed);
  return out;
}

const FastSlamParticle& FastSlam::particle(int k) const {
  require(k >= 0 && k < num_particles(), "index", "is not a particle index");
  return particles_[static_cast<std::size_t>(k)];
}

Poses2 FastSlam::poses() const { return particle_poses(particles_); }

Eigen::VectorXd FastSlam::log_weights() const { return particle_log_weights(particles_); }

Eigen::VectorXd FastSlam::per_particle(double FastSlamParticle::*field) const {
  Eigen::VectorXd out(num_particles());
  for (int k = 0; k < num_particles(); ++k) out[k] = particles_[static_cast<std::size_t>(k)].*field;
  return out;
}

Eigen::VectorXd FastSlam::last_log_likelihoods() const { return per_particle(&FastSlamParticle::last_log_likelihood); }

Eigen::VectorXd FastSlam::bearing_offsets() const { return per_particle(&FastSlamParticle::bearing_offset); }

double FastSlam::effective_sample_size() const {
  double s = 0.0;
  for (const FastSlamParticle& p : particles_) s += std::exp(2.0 * p.log_weight);
  return 1.0 / s;
}

int FastSlam::best_index() const { return heaviest_particle(particles_); }

Poses2 FastSlam::path(int k) const { return particle(k).path.poses(); }

Eigen::Vector3d FastSlam::mean_pose() const {
  double x = 0.0, y = 0.0, c = 0.0, s = 0.0;
  for (const FastSlamParticle& p : particles_) {
    const double w = std::exp(p.log_weight);
    x += w * p.pose[0];
    y += w * p.pose[1];
    c += w * std::cos(p.pose[2]);
    s += w * std::sin(p.pose[2]);
  }
  return {x, y, std::atan2(s, c)};
}

Eigen::Matrix3d FastSlam::pose_covariance() const {
  const Eigen::Vector3d mean = mean_pose();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const FastSlamParticle& p : particles_) {
    Eigen::Vector3d e = p.pose - mean;
    e[2] = wrap_angle(e[2]);
    cov += std::exp(p.log_weight) * e * e.transpose();
  }
  return symmetric<3>(cov);
}

std::vector<Landmark> FastSlam::landmarks(int k) const {
  std::vector<Landmark> out;
  const LandmarkMap& map = particle(k).map;
  out.reserve(map.size());
  map.for_each([&](const Landmark& lm) { out.push_back(lm); });
  std::sort(out.begin(), out.end(), [](const Landmark& a, const Landmark& b) { return a.id < b.id; });
  return out;
}

MapSharing FastSlam::map_sharing() const {
  MapSharing s;
  std::unordered_set<const void*> seen, path_seen;
  for (const FastSlamParticle& p : particles_) {
    s.distinct_nodes += p.map.collect_nodes(seen);
    s.total_nodes += p.map.num_nodes();
    s.landmarks += p.map.size();
    s.path_nodes += p.path.collect_nodes(path_seen);
  }
  return s;
}

}  // namespace probslam
