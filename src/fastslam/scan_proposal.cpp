#include "probslam/fastslam/scan_proposal.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <cmath>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"

namespace probslam {
namespace {

/// Symmetry tolerance of a prior covariance, relative to its largest entry: covariances composed
/// in double (J P J^T) are symmetric to a few ulps.
constexpr double kCovarianceSymmetry = 1e-9;
constexpr double kLog2Pi = 1.8378770664093453;

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
  // Every evaluation below is on this grid: the end points' searches are remembered per cell.
  EndpointLikelihood::Memo memo;
  auto score = [&](const Eigen::Vector3d& x) {
    return likelihood.log_likelihood(grid, x, points, memo) + motion.log_density(x);
  };

  ScanProposal p;
  double best_score = 0.0;
  Eigen::Vector3d best = climb(score, prior, score(prior), options, best_score);
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
  p.mode = best;
  likelihood.log_likelihood(grid, best, points, memo, &p.quality);
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
