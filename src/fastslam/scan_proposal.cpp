#include "probslam/fastslam/scan_proposal.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <cmath>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/chi_square.hpp"

namespace probslam {
namespace {

/// Symmetry tolerance of a prior covariance, relative to its largest entry: covariances composed
/// in double (J P J^T) are symmetric to a few ulps.
constexpr double kCovarianceSymmetry = 1e-9;
constexpr double kLog2Pi = 1.8378770664093453;
/// Gauss-Newton ascent: at most this many iterations (each at most halves its step until the
/// step is below the climb's precision); an ascent still moving after them is not trusted.
constexpr int kMaxAscentIterations = 30;
/// The ascent's mode is kept when it lies within the motion prior's gate at this probability
/// (the frontend's local match uses the same: IncrementalScanMatcher).
constexpr double kLocalModeProbability = 0.999;

Eigen::Vector3d pose_offset(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return {a.x() - b.x(), a.y() - b.y(), wrap_angle(a.z() - b.z())};
}

/// N(mean, cov) over poses, factorised once: the hill climb evaluates it at every candidate.
class PoseGaussian {
 public:
  PoseGaussian(const Eigen::Vector3d& mean, const Eigen::Matrix3d& cov)
      : mean_(mean), llt_(cov), log_norm_(-0.5 * (2.0 * llt_.matrixLLT().diagonal().array().log().sum() + 3.0 * kLog2Pi)) {}
  /// The full log density, the heading difference wrapped.
  double log_density(const Eigen::Vector3d& pose) const {
    return log_norm_ - 0.5 * llt_.matrixL().solve(pose_offset(pose, mean_)).squaredNorm();
  }
  /// cov^-1, symmetrised, from the same factor.
  Eigen::Matrix3d information() const {
    const Eigen::Matrix3d i = llt_.solve(Eigen::Matrix3d::Identity());
    return 0.5 * (i + i.transpose());
  }
  /// pose - mean, the heading difference wrapped.
  Eigen::Vector3d offset(const Eigen::Vector3d& pose) const { return pose_offset(pose, mean_); }

 private:
  Eigen::Vector3d mean_;
  Eigen::LLT<Eigen::Matrix3d> llt_;
  double log_norm_;
};

/// Hill climbing over +-x, +-y, +-theta moves with step halving (GMapping's optimiser) from
/// `from`, whose score the caller has: the local maximum of `score`, its score in `best_score`.
template <class Score>
Eigen::Vector3d climb(const Score& score, const Eigen::Vector3d& from, double from_score,
                      const ScanProposalOptions& options, double& best_score) {
  Eigen::Vector3d best = from;
  best_score = from_score;
  double lin = options.linear_step, ang = options.angular_step;
  int halvings = 0;
  // The move just made, or -1: its reverse leads back to where the climb came from, which scored
  // lower than `best`, so it is not evaluated again (steps 2i and 2i + 1 are opposite).
  int last = -1;
  for (int moves = 0; moves < options.max_moves && halvings <= options.refinements;) {
    const Eigen::Vector3d steps[6] = {{lin, 0, 0}, {-lin, 0, 0}, {0, lin, 0}, {0, -lin, 0}, {0, 0, ang}, {0, 0, -ang}};
    Eigen::Vector3d next = best;
    double next_score = best_score;
    int chosen = -1;
    for (int k = 0; k < 6; ++k) {
      if (last >= 0 && k == (last ^ 1)) continue;
      Eigen::Vector3d cand = best + steps[k];
      cand.z() = wrap_angle(cand.z());
      const double sc = score(cand);
      if (sc > next_score) {
        next_score = sc;
        next = cand;
        chosen = k;
      }
    }
    if (next_score > best_score) {
      best = next;
      best_score = next_score;
      last = chosen;
      ++moves;
    } else {
      last = -1;
      lin *= 0.5;
      ang *= 0.5;
      ++halvings;
    }
  }
  return best;
}

/// The end of a Gauss-Newton ascent.
struct Ascent {
  Eigen::Vector3d pose;
  double score = 0.0, quality = 0.0;
  bool converged = false;
};

/// Gauss-Newton ascent of log p(z | x, m) + log N(x; motion) from `from` (iteratively reweighted
/// least squares on the end points' distances to their nearest occupied cells, the prior as a
/// quadratic): each step is halved until it ascends; the ascent has converged when no step down
/// to the climb's precision (`tolerance`, m, m, rad) ascends, or the step taken is below it.
Ascent ascend(const EndpointLikelihood& likelihood, const TiledGrid2D& grid, const Eigen::Ref<const Points2>& points,
              EndpointLikelihood::Memo& memo, const PoseGaussian& motion, const Eigen::Matrix3d& prior_information,
              const Eigen::Vector3d& from, const Eigen::Vector3d& tolerance, int& evaluations) {
  auto evaluate = [&](const Eigen::Vector3d& x, Eigen::Vector3d& g, Eigen::Matrix3d& H, double& q) {
    EndpointLikelihood::Derivatives d;
    const double s = likelihood.log_likelihood(grid, x, points, memo, d, &q) + motion.log_density(x);
    ++evaluations;
    g = d.gradient - prior_information * motion.offset(x);
    H = d.information + prior_information;
    return s;
  };
  Ascent a;
  a.pose = from;
  Eigen::Vector3d g;
  Eigen::Matrix3d H;
  a.score = evaluate(from, g, H, a.quality);
  for (int it = 0; it < kMaxAscentIterations; ++it) {
    // H holds the prior's information: positive definite.
    const Eigen::Vector3d step = Eigen::LLT<Eigen::Matrix3d>(H).solve(g);
    if (!step.allFinite()) return a;
    Eigen::Vector3d scaled = step;
    bool accepted = false;
    while (!accepted && (scaled.cwiseAbs().array() >= tolerance.array()).any()) {
      Eigen::Vector3d cand = a.pose + scaled;
      cand.z() = wrap_angle(cand.z());
      Eigen::Vector3d gc;
      Eigen::Matrix3d Hc;
      double qc = 0.0;
      const double sc = evaluate(cand, gc, Hc, qc);
      if (sc > a.score) {
        a.pose = cand, a.score = sc, a.quality = qc, g = gc, H = Hc;
        accepted = true;
      } else {
        scaled *= 0.5;
      }
    }
    if (!accepted || (scaled.cwiseAbs().array() < tolerance.array()).all()) {
      a.converged = true;
      return a;
    }
  }
  return a;
}

/// kFallback's mode: Gauss-Newton from the start (else the prior), and from the prior too if it
/// scores higher than where that ascent ended (the climb's two starts, the other way round: the
/// corrected start is the nearer). True, with `mode`, its score and quality, when the ascent
/// holds: it converged, its quality passes min_match_quality, and the mode lies inside the
/// motion prior's gate; false sends the proposal to the climb.
bool local_mode(const EndpointLikelihood& likelihood, const TiledGrid2D& grid, const Eigen::Ref<const Points2>& points,
                EndpointLikelihood::Memo& memo, const PoseGaussian& motion, const Eigen::Matrix3d& prior_information,
                const Eigen::Vector3d& prior, const std::optional<Eigen::Vector3d>& start,
                const ScanProposalOptions& options, Eigen::Vector3d& mode, double& score, double& quality,
                int& evaluations) {
  static const double gate = chi_square_quantile(kLocalModeProbability, 3);
  const double precision = std::ldexp(1.0, -options.refinements);
  const Eigen::Vector3d tolerance(options.linear_step * precision, options.linear_step * precision,
                                  options.angular_step * precision);
  Ascent a = ascend(likelihood, grid, points, memo, motion, prior_information, start ? *start : prior, tolerance,
                    evaluations);
  if (start) {
    ++evaluations;
    if (likelihood.log_likelihood(grid, prior, points, memo) + motion.log_density(prior) > a.score) {
      const Ascent b = ascend(likelihood, grid, points, memo, motion, prior_information, prior, tolerance, evaluations);
      if (b.converged && (!a.converged || b.score > a.score)) a = b;
    }
  }
  if (!a.converged || !(a.quality >= options.min_match_quality)) return false;
  const Eigen::Vector3d d = motion.offset(a.pose);
  if (!(d.dot(prior_information * d) <= gate)) return false;
  mode = a.pose;
  score = a.score;
  quality = a.quality;
  return true;
}

}  // namespace

void ScanProposalOptions::validate() const {
  require_positive(linear_step, "linear_step");
  require_positive(angular_step, "angular_step");
  require(refinements >= 0 && refinements <= 30, "refinements", "must lie in [0, 30]");
  require(max_moves >= 0 && max_moves <= 1000000, "max_moves", "must lie in [0, 1000000]");
  require_positive(sample_linear, "sample_linear");
  require_positive(sample_angular, "sample_angular");
  require(std::isfinite(min_match_quality) && min_match_quality >= 0.0 && min_match_quality <= 1.0, "min_match_quality",
          "must lie in [0, 1]");
  require(search == ProposalSearch::kFallback || search == ProposalSearch::kAlways, "search",
          "must be fallback or always");
}

double log_gaussian_pose(const Eigen::Vector3d& pose, const Eigen::Vector3d& prior, const Eigen::Matrix3d& prior_cov) {
  return PoseGaussian(prior, prior_cov).log_density(pose);
}

double fit_pose_laplace(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& poses,
                        const Eigen::Ref<const Eigen::VectorXd>& log_scores, const Eigen::Vector3d& spacing,
                        const Eigen::Matrix3d& prior_information, Eigen::Vector3d& mean, Eigen::Matrix3d& covariance) {
  require(poses.rows() == 27 && log_scores.size() == 27, "log_scores", "must have 27 entries, one per pose");
  require(log_scores.allFinite(), "log_scores", "must be finite");
  require_all_finite(poses, "poses");
  require((spacing.array() > 0.0).all() && spacing.allFinite(), "spacing", "must be positive");
  // s(u) = c + g.u + 1/2 u^T A u in grid units u = offset / spacing: 10 unknowns.
  const Eigen::Vector3d centre = poses.row(0).transpose();
  Eigen::Matrix<double, 27, 10> M;
  for (int j = 0; j < 27; ++j) {
    const Eigen::Vector3d u = pose_offset(poses.row(j).transpose(), centre).cwiseQuotient(spacing);
    M.row(j) << 1.0, u.x(), u.y(), u.z(), 0.5 * u.x() * u.x(), 0.5 * u.y() * u.y(), 0.5 * u.z() * u.z(),
        u.x() * u.y(), u.x() * u.z(), u.y() * u.z();
  }
  const Eigen::Matrix<double, 10, 1> q = M.colPivHouseholderQr().solve(log_scores);
  const Eigen::Vector3d inv = spacing.cwiseInverse();
  const Eigen::Vector3d g = q.segment<3>(1).cwiseProduct(inv);
  Eigen::Matrix3d A;
  A << q[4], q[7], q[8], q[7], q[5], q[9], q[8], q[9], q[6];
  A = inv.asDiagonal() * A * inv.asDiagonal();
  // The measurement's part of the curvature: what is left after the prior's (-information).
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(A + prior_information);
  const Eigen::Vector3d neg = es.eigenvalues().cwiseMin(0.0);
  const Eigen::Matrix3d info = prior_information - es.eigenvectors() * neg.asDiagonal() * es.eigenvectors().transpose();
  const Eigen::LLT<Eigen::Matrix3d> llt(0.5 * (info + info.transpose()));
  covariance = llt.solve(Eigen::Matrix3d::Identity());
  covariance = 0.5 * (covariance + covariance.transpose());
  const Eigen::Vector3d step = (covariance * g).cwiseMax(-spacing).cwiseMin(spacing);
  mean = Eigen::Vector3d(centre.x() + step.x(), centre.y() + step.y(), wrap_angle(centre.z() + step.z()));
  const double at_mean = q[0] + g.dot(step) - 0.5 * step.dot(info * step);
  return at_mean + 1.5 * kLog2Pi - llt.matrixLLT().diagonal().array().log().sum();
}

ScanProposal scan_matching_proposal(const EndpointLikelihood& likelihood, const TiledGrid2D& grid,
                                    const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                    const Eigen::Matrix3d& prior_cov, const ScanProposalOptions& options,
                                    const std::optional<Eigen::Vector3d>& start) {
  options.validate();
  require_all_finite(prior, "prior");
  if (start) require_all_finite(*start, "start");
  require_symmetric_positive_definite(prior_cov, "prior_cov", kCovarianceSymmetry);
  require_all_finite(points, "points");
  require(grid.resolution() == likelihood.resolution(), "grid", "must have the likelihood's resolution");

  const PoseGaussian motion(prior, prior_cov);
  const Eigen::Matrix3d prior_information = motion.information();
  // Every evaluation below is on this grid: the end points' searches are remembered per cell.
  EndpointLikelihood::Memo memo;
  ScanProposal p;
  auto score = [&](const Eigen::Vector3d& x) {
    ++p.evaluations;
    return likelihood.log_likelihood(grid, x, points, memo) + motion.log_density(x);
  };

  double best_score = 0.0;
  Eigen::Vector3d best = prior;
  if (options.search == ProposalSearch::kFallback) p.local = local_mode(likelihood, grid, points, memo, motion,
                                                                        prior_information, prior, start, options,
                                                                        best, best_score, p.quality, p.evaluations);
  if (p.local) {
    // The ascent stops once its step is below the climb's precision, but its Hessian (the points'
    // weights held) is steeper than the score's, so it stops a few millimetres short of the
    // optimum. The climb's last stages finish it: from its first step halved until it is within
    // the fit's spacing (the ascent's mode lies within that of the optimum) to its last.
    ScanProposalOptions finish = options;
    while (finish.refinements > 0 && finish.linear_step > options.sample_linear) {
      finish.linear_step *= 0.5;
      finish.angular_step *= 0.5;
      --finish.refinements;
    }
    best = climb(score, best, best_score, finish, best_score);
    ++p.evaluations;
    likelihood.log_likelihood(grid, best, points, memo, &p.quality);
  } else {
    best = climb(score, prior, score(prior), options, best_score);
    // The odometry pose of a scan may be stale; if the corrected start explains the scan better
    // than where the climb from the odometry ended, climb from it too and keep the better mode.
    if (start) {
      const double from = score(*start);
      if (from > best_score) {
        double other_score = 0.0;
        const Eigen::Vector3d other = climb(score, *start, from, options, other_score);
        if (other_score > best_score) {
          best = other;
          best_score = other_score;
        }
      }
    }
    ++p.evaluations;
    likelihood.log_likelihood(grid, best, points, memo, &p.quality);
  }
  p.mode = best;
  p.matched = p.quality >= options.min_match_quality;
  if (!p.matched) return p;

  // K = 27 poses around the mode; the mode first (the reference heading of the fit).
  p.samples.resize(27, 3);
  p.log_scores.resize(27);
  int k = 0;
  for (int i : {0, -1, 1})
    for (int j : {0, -1, 1})
      for (int a : {0, -1, 1}) {
        const Eigen::Vector3d x(best.x() + i * options.sample_linear, best.y() + j * options.sample_linear,
                                wrap_angle(best.z() + a * options.sample_angular));
        p.samples.row(k) = x.transpose();
        p.log_scores[k] = k == 0 ? best_score : score(x);  // the mode's score is known
        ++k;
      }
  const Eigen::Vector3d spacing(options.sample_linear, options.sample_linear, options.sample_angular);
  p.log_normaliser = fit_pose_laplace(p.samples, p.log_scores, spacing, motion.information(), p.mean, p.covariance);
  return p;
}

}  // namespace probslam
