#pragma once
// The improved proposal of grid-based FastSLAM (Grisetti et al. 2007, the lecture's "the
// proposal adapts to the structure of the environment"): from the odometry prediction, climb to
// the mode of p(z | x, m) p(x | x_t-1, u) on the particle's own map, evaluate that product at K
// poses around the mode, and fit a Gaussian to them (a Laplace approximation: a quadratic fitted
// to the log of the product); the new pose is drawn from the Gaussian and the particle's weight
// grows by the product's integral under that approximation (its normaliser).
//
// Why not the weighted scatter of the K poses (GMapping's fit): along a corridor p(z | x, m) is
// flat, and the scatter of poses 1 cm apart is then about 1 cm whatever the motion model says,
// so every particle lands within a centimetre of the odometry's guess along the corridor and the
// filter loses the spread it needs when the corridor's end comes into view. The quadratic fit
// gives the flat direction the motion model's width.
#include <Eigen/Core>
#include <array>
#include <optional>

#include "probslam/core/options_description.hpp"
#include "probslam/fastslam/endpoint_likelihood.hpp"

namespace probslam {

/// How the proposal finds the mode of p(z | x, m) p(x | x_t-1, u) (issue 54).
enum class ProposalSearch {
  /// Gauss-Newton from the start (the corrected odometry, else the prediction); the hill climb
  /// only where that ascent is poor.
  kFallback,
  kAlways,  ///< the hill climb for every proposal
};
template <>
struct OptionEnum<ProposalSearch> {
  static constexpr std::array<const char*, 2> names{"fallback", "always"};
};

struct ScanProposalOptions {
  double linear_step = 0.05;   ///< first hill-climbing step, m
  double angular_step = 0.05;  ///< first hill-climbing step, rad
  int refinements = 5;         ///< step halvings before the climb stops
  int max_moves = 200;         ///< moves at most (bounds the climb on any map)
  double sample_linear = 0.01;   ///< spacing of the K = 27 evaluation poses (3 x 3 x 3), m
  double sample_angular = 0.005; ///< ... rad
  /// The match fails (the caller falls back to the motion model) when the mean hit likelihood
  /// of the scan at the mode is below this (0..1).
  double min_match_quality = 0.3;
  /// kFallback: the mode is found by Gauss-Newton (the end points' squared distances to their
  /// nearest occupied cells, reweighted by their hit probability, with the motion prior) from the
  /// corrected start, or the prediction without one, then from the prediction too if that scores
  /// higher; it stops once its step is below the climb's last step (linear_step and angular_step
  /// halved `refinements` times: the climb's precision). The climb runs instead when the ascent
  /// did not converge, its mode's quality is below min_match_quality, or the mode lies beyond the
  /// motion prior's 99.9 % chi2 gate (3 dof). kAlways: the climb for every proposal. The
  /// default since 2026-11-30: ACES over 15 seeds and the simulated robot matrix over 3 seeds
  /// no worse, 25-30 % less CPU (docs/performance.md).
  ProposalSearch search = ProposalSearch::kFallback;
  void validate() const;
  template <class V>
  static void describe(V& v) {
    using O = ScanProposalOptions;
    v("linear_step", &O::linear_step, "m", "the hill climb's first step");
    v("angular_step", &O::angular_step, "rad", "the hill climb's first step");
    v("refinements", &O::refinements, "", "step halvings before the climb stops, in [0, 30]");
    v("max_moves", &O::max_moves, "", "moves at most");
    v("sample_linear", &O::sample_linear, "m", "spacing of the 3 x 3 x 3 evaluation poses");
    v("sample_angular", &O::sample_angular, "rad", "... in heading");
    v("min_match_quality", &O::min_match_quality, "", "a match below this mean hit likelihood (0 .. 1) falls back to the motion model");
    v("search", &O::search, "",
      "'fallback': Gauss-Newton from the corrected start, the hill climb only where that ascent is poor; "
      "'always': the hill climb for every proposal");
  }
};

struct ScanProposal {
  bool matched = false;  ///< the mode passed min_match_quality; otherwise only `mode` and `quality` are set
  Eigen::Vector3d mode = Eigen::Vector3d::Zero();
  double quality = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();      ///< of the fitted Gaussian, heading wrapped
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  /// log of the integral of p(z | x, m) p(x | x_t-1, u) dx under the Laplace approximation:
  /// the log weight increment.
  double log_normaliser = 0.0;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> samples;  ///< the K poses (K x 3)
  Eigen::VectorXd log_scores;  ///< log p(z | x_j, m) + log N(x_j; prior, prior_cov), (K,)
  bool local = false;  ///< the mode is the Gauss-Newton ascent's (search = kFallback), not the climb's
  int evaluations = 0;  ///< evaluations of p(z | x, m) this proposal made
};

/// log N(pose; prior, prior_cov) with the heading difference wrapped (the full density, its
/// normalising constant included). prior_cov must be symmetric positive definite.
double log_gaussian_pose(const Eigen::Vector3d& pose, const Eigen::Vector3d& prior, const Eigen::Matrix3d& prior_cov);

/// The Laplace approximation of exp(s) from K = 27 poses on the 3 x 3 x 3 grid centre +
/// (i, j, a) * spacing, i, j, a in {-1, 0, 1}, the centre first, with log scores s (K,): a quadratic fitted to s by
/// least squares gives the gradient g and Hessian A at the centre. The part of A not explained by
/// the motion prior (information `prior_information`, known exactly) is clamped to negative
/// semi-definite, so covariance = (prior_information - A_z)^-1 is positive definite and never
/// wider than the prior; mean = centre + covariance g (a Newton step, clamped to the grid's box).
/// Returns log of the integral of exp(s): s_fit(mean) + log sqrt((2 pi)^3 det covariance).
double fit_pose_laplace(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& poses,
                        const Eigen::Ref<const Eigen::VectorXd>& log_scores, const Eigen::Vector3d& spacing,
                        const Eigen::Matrix3d& prior_information, Eigen::Vector3d& mean, Eigen::Matrix3d& covariance);

/// The proposal for one particle: points (N, 2) in the sensor frame, prior = the odometry
/// prediction of the sensor pose, prior_cov its covariance (symmetric positive definite); the
/// climb starts at the prior; if `start` is given and scores higher than where that climb
/// ended, a second climb starts there and the better mode is kept.
ScanProposal scan_matching_proposal(const EndpointLikelihood& likelihood, const TiledGrid2D& grid,
                                    const Eigen::Ref<const Points2>& points, const Eigen::Vector3d& prior,
                                    const Eigen::Matrix3d& prior_cov, const ScanProposalOptions& options,
                                    const std::optional<Eigen::Vector3d>& start = std::nullopt);

}  // namespace probslam
