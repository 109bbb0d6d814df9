#pragma once
// The improved proposal of grid-based FastSLAM (Grisetti et al. 2007, the lecture's "the
// proposal adapts to the structure of the environment"): from the odometry prediction, climb to
// the mode of p(z | x, m) p(x | x_t-1, u) on the particle's own map, evaluate that product at K
// poses around the mode, and fit a Gaussian to them; the new pose is drawn from the Gaussian and
// the particle's weight grows by the product's sum over the K poses (its normaliser).
#include <Eigen/Core>

#include "probslam/fastslam/endpoint_likelihood.hpp"

namespace probslam {

struct ScanProposalOptions {
  double linear_step = 0.05;   ///< first hill-climbing step, m
  double angular_step = 0.05;  ///< first hill-climbing step, rad
  int refinements = 5;         ///< step halvings before the climb stops
  int max_moves = 200;         ///< moves at most (bounds the climb on any map)
  double sample_linear = 0.01;   ///< spacing of the K = 27 evaluation poses (3 x 3 x 3), m
  double sample_angular = 0.005; ///< ... rad
  /// The match fails (the caller falls back to the motion model) when the mean hit likelihood
  /// of the scan at the mode is below this (0..1).
  double min_quality = 0.3;
  void validate() const;
};

struct ScanProposal {
  bool matched = false;  ///< the mode passed min_quality; otherwise only `mode` and `quality` are set
  Eigen::Vector3d mode = Eigen::Vector3d::Zero();
  double quality = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();      ///< of the fitted Gaussian, heading wrapped
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  /// log sum_j p(z | x_j, m) p(x_j | x_t-1, u) over the K poses: the log weight increment.
  double log_normaliser = 0.0;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> samples;  ///< the K poses (K x 3)
  Eigen::VectorXd log_scores;  ///< log p(z | x_j, m) + log N(x_j; prior, prior_cov), (K,)
};

/// log N(pose; prior, prior_cov) with the heading difference wrapped (the full density, its
/// normalising constant included). prior_cov must be symmetric positive definite.
double log_gaussian_pose(const Eigen::Vector3d& pose, const Eigen::Vector3d& prior, const Eigen::Matrix3d& prior_cov);

/// The weighted Gaussian of poses (K x 3) with log weights (K,): w_j = exp(s_j - max s),
/// mean = sum w x / sum w (headings as offsets from the first pose's, wrapped), covariance the
/// weighted scatter about the mean plus `floor` on the diagonal; returns log sum exp(s_j).
double fit_pose_gaussian(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& poses,
                         const Eigen::Ref<const Eigen::VectorXd>& log_weights, const Eigen::Vector3d& floor,
                         Eigen::Vector3d& mean, Eigen::Matrix3d& covariance);

/// The proposal for one particle: points (N, 2) in the sensor frame, prior = the odometry
/// prediction of the sensor pose, prior_cov its covariance (symmetric positive definite).
/// The diagonal floor of the fitted covariance is (sample_linear / 4)^2 (both axes) and
/// (sample_angular / 4)^2: a peak narrower than the 27 poses' spacing cannot be resolved.
ScanProposal scan_matching_proposal(const EndpointLikelihood& likelihood, const TiledGrid2D& grid,
                                    const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                    const Eigen::Matrix3d& prior_cov, const ScanProposalOptions& options);

}  // namespace probslam
