#include "probslam/fastslam/scan_proposal.hpp"

#include <Eigen/Cholesky>
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

 private:
  Eigen::Vector3d mean_;
  Eigen::LLT<Eigen::Matrix3d> llt_;
  double log_norm_;
};

}  // namespace

void ScanProposalOptions::validate() const {
  require_positive(linear_step, "linear_step");
  require_positive(angular_step, "angular_step");
  require(refinements >= 0 && refinements <= 30, "refinements", "must lie in [0, 30]");
  require(max_moves >= 0 && max_moves <= 1000000, "max_moves", "must lie in [0, 1000000]");
  require_positive(sample_linear, "sample_linear");
  require_positive(sample_angular, "sample_angular");
  require(std::isfinite(min_quality) && min_quality >= 0.0 && min_quality <= 1.0, "min_quality",
          "must lie in [0, 1]");
}

double log_gaussian_pose(const Eigen::Vector3d& pose, const Eigen::Vector3d& prior, const Eigen::Matrix3d& prior_cov) {
  return PoseGaussian(prior, prior_cov).log_density(pose);
}

double fit_pose_gaussian(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& poses,
                         const Eigen::Ref<const Eigen::VectorXd>& log_weights, const Eigen::Vector3d& floor,
                         Eigen::Vector3d& mean, Eigen::Matrix3d& covariance) {
  require(poses.rows() > 0 && poses.rows() == log_weights.size(), "log_weights", "must have one entry per pose");
  require(log_weights.allFinite(), "log_weights", "must be finite");
  require_all_finite(poses, "poses");
  const double top = log_weights.maxCoeff();
  const Eigen::Vector3d ref = poses.row(0).transpose();
  double total = 0.0;
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (Eigen::Index j = 0; j < poses.rows(); ++j) {
    const double w = std::exp(log_weights[j] - top);
    m += w * pose_offset(poses.row(j).transpose(), ref);
    total += w;
  }
  m /= total;
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (Eigen::Index j = 0; j < poses.rows(); ++j) {
    const double w = std::exp(log_weights[j] - top);
    const Eigen::Vector3d d = pose_offset(poses.row(j).transpose(), ref) - m;
    c += w * d * d.transpose();
  }
  covariance = c / total;
  covariance.diagonal() += floor;
  covariance = 0.5 * (covariance + covariance.transpose());
  mean = Eigen::Vector3d(ref.x() + m.x(), ref.y() + m.y(), wrap_angle(ref.z() + m.z()));
  return top + std::log(total);
}

ScanProposal scan_matching_proposal(const EndpointLikelihood& likelihood, const TiledGrid2D& grid,
                                    const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                    const Eigen::Matrix3d& prior_cov, const ScanProposalOptions& options) {
  options.validate();
  require_all_finite(prior, "prior");
  require_symmetric_positive_definite(prior_cov, "prior_cov", kCovarianceSymmetry);
  require_all_finite(points, "points");
  require(grid.resolution() == likelihood.resolution(), "grid", "must have the likelihood's resolution");

  const PoseGaussian motion(prior, prior_cov);
  auto score = [&](const Eigen::Vector3d& x) { return likelihood.log_likelihood(grid, x, points) + motion.log_density(x); };

  // Hill climbing over +-x, +-y, +-theta moves with step halving (GMapping's optimiser).
  ScanProposal p;
  Eigen::Vector3d best = prior;
  double best_score = score(best);
  double lin = options.linear_step, ang = options.angular_step;
  int halvings = 0;
  for (int moves = 0; moves < options.max_moves && halvings <= options.refinements;) {
    const Eigen::Vector3d steps[6] = {{lin, 0, 0}, {-lin, 0, 0}, {0, lin, 0}, {0, -lin, 0}, {0, 0, ang}, {0, 0, -ang}};
    Eigen::Vector3d next = best;
    double next_score = best_score;
    for (const Eigen::Vector3d& s : steps) {
      Eigen::Vector3d cand = best + s;
      cand.z() = wrap_angle(cand.z());
      const double sc = score(cand);
      if (sc > next_score) {
        next_score = sc;
        next = cand;
      }
    }
    if (next_score > best_score) {
      best = next;
      best_score = next_score;
      ++moves;
    } else {
      lin *= 0.5;
      ang *= 0.5;
      ++halvings;
    }
  }
  p.mode = best;
  likelihood.log_likelihood(grid, best, points, &p.quality);
  p.matched = p.quality >= options.min_quality;
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
        p.log_scores[k] = score(x);
        ++k;
      }
  const Eigen::Vector3d floor(std::pow(options.sample_linear / 4.0, 2), std::pow(options.sample_linear / 4.0, 2),
                              std::pow(options.sample_angular / 4.0, 2));
  p.log_normaliser = fit_pose_gaussian(p.samples, p.log_scores, floor, p.mean, p.covariance);
  return p;
}

}  // namespace probslam
