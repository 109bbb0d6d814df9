#pragma once
// GraphSLAM with unknown correspondences (Probabilistic Robotics ch. 11.5, Tables 11.8 and 11.9)
// on the information form of information_form.hpp.
#include <Eigen/Core>
#include <vector>

#include "probslam/graph/information_form.hpp"
#include "probslam/graph/sparse_cholesky.hpp"

namespace probslam {

/// The difference Delta = m_j - m_k of two features under the posterior, and the density of
/// Delta = 0 (Table 11.8 line 7).
struct CorrespondenceTest {
  double probability = 0.0;  ///< p(Delta = 0), a density in 1/m^2 (1/(m^2 s) with signatures)
  double distance2 = 0.0;    ///< squared Mahalanobis distance mu_Delta^T Sigma_Delta^-1 mu_Delta
  Eigen::VectorXd mean;       ///< mu_Delta = mu_j - mu_k, (d,)
  Eigen::MatrixXd covariance; ///< Sigma_Delta, (d, d)
};

/// Table 11.8 for many pairs of one posterior. `path_factor` is the factorised reduced
/// information Omega~ of Table 11.3 (eif_solve leaves it in the SparseCholesky it is given); it
/// stands for the path covariance Sigma_{0:t} = Omega~^-1, which is never formed. `features`
/// (N, d) are the means of eif_solve. Each feature's solves against the factor are made once and
/// reused by every pair it is part of. The referenced objects must outlive the tester.
class EifCorrespondenceTester {
 public:
  EifCorrespondenceTester(const InformationForm& form, const SparseCholesky& path_factor,
                          const Eigen::Ref<const RowMatrixXd>& features);
  ~EifCorrespondenceTester();
  EifCorrespondenceTester(const EifCorrespondenceTester&) = delete;
  EifCorrespondenceTester& operator=(const EifCorrespondenceTester&) = delete;

  /// Errata (seeds/README.md): the marginal of (m_j, m_k) has the covariance
  /// Sigma_[jk] = A^-1 + A^-1 B Sigma_tt B^T A^-1 with A = Omega_{jk,jk}, B = Omega_{jk,tau(j,k)}
  /// (line 2 and eq. 11.46 are wrong), Delta's covariance is D Sigma_[jk] D^T with D = (I, -I)
  /// (line 4 maps the information instead), and line 7's exponent weighs mu_Delta by the
  /// information Sigma_Delta^-1. Throws std::invalid_argument for j == k or an index out of range.
  CorrespondenceTest test(int j, int k);

  int num_features() const { return static_cast<int>(features_.rows()); }

 private:
  struct Feature;
  const Feature& feature(int j);

  const InformationForm& form_;
  const SparseCholesky& factor_;
  RowMatrixXd features_;
  std::vector<Feature> cache_;
  std::vector<char> cached_;
};

/// One-pair convenience of EifCorrespondenceTester.
CorrespondenceTest eif_correspondence_test(const InformationForm& form,
                                           const SparseCholesky& path_factor,
                                           const Eigen::Ref<const RowMatrixXd>& features, int j, int k);

/// Table 11.9 with the refinements of section 11.5: probe only pairs whose means lie within
/// `search_radius` (a uniform grid over the feature means), collect every accepted pair of a
/// round before re-solving (joined most probable first into groups, so one feature may absorb
/// several), and never merge features observed at the same time step (one scan sees distinct
/// features), neither directly nor through a group.
struct CorrespondenceSearchOptions {
  /// Table 11.9 line 10: merge when p(Delta = 0) > chi (a density, see CorrespondenceTest).
  double chi = 1e-4;
  /// Metres between two feature means beyond which a pair is not tested.
  double search_radius = 3.0;
  /// Rounds of test-merge-solve at most (each round re-solves Table 11.5 to convergence).
  int max_rounds = 100;
};

/// A merge made by Table 11.9 line 11. Features are named by the first measurement (index
/// into the measurement arrays) that belongs to them, which stays valid across rounds.
struct FeatureMerge {
  int round = 0;
  int kept = 0;    ///< first measurement of the feature that absorbs the other
  int merged = 0;  ///< first measurement of the feature absorbed
  double probability = 0.0;
  double distance2 = 0.0;
};

struct GraphSlamUnknownResult {
  GraphSlamResult slam;             ///< the solution with the final correspondences
  Eigen::VectorXi correspondences;  ///< (M,) feature of each measurement, 0 .. N-1
  std::vector<FeatureMerge> merges;
  int rounds = 0;
  bool converged = false;  ///< no pair above chi was left (line 17) within max_rounds
};

/// Table 11.9: starts from a feature per measurement (`measurements.feature` is ignored), solves,
/// tests nearby pairs, merges, and repeats until no pair exceeds chi.
GraphSlamUnknownResult graph_slam_unknown(const Eigen::Ref<const RowMatrixXd>& controls,
                                          const Eigen::VectorXd& dt,
                                          const FeatureMeasurements& measurements,
                                          const Eigen::Matrix3d& R, const Eigen::MatrixXd& Q,
                                          const GraphSlamOptions& options = {},
                                          const CorrespondenceSearchOptions& search = {});

}  // namespace probslam
