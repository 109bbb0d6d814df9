#pragma once
// GraphSLAM in information form (Probabilistic Robotics ch. 11, Tables 11.1-11.5 and 11.8),
// with the errata of seeds/README.md applied. The state is y = (x_0 .. x_T, m_0 .. m_{N-1}):
// poses (x, y, theta) and features (m_x, m_y) or (m_x, m_y, s) with a signature.
#include <Eigen/Core>
#include <vector>

#include "probslam/core/types.hpp"
#include "probslam/graph/sparse_cholesky.hpp"

namespace probslam {

/// Feature measurements as flat arrays, one row per measurement.
struct FeatureMeasurements {
  Eigen::VectorXi time;     ///< (M,) index t of the pose x_t that measured it, 0 <= t <= T
  RowMatrixXd z;            ///< (M, 2): range [m], bearing [rad]; (M, 3) adds a signature
  Eigen::VectorXi feature;  ///< (M,) correspondence c: a feature index 0 <= c < N
};

/// Omega (symmetric, both triangles stored) and xi over y. x_0 is anchored exactly at its
/// mean: its rows and columns are cleared, Omega_00 = I and xi_0 = mu_0, and the information
/// it had with its neighbours is moved into their xi, which is the posterior conditioned on x_0
/// (the book's infinite anchor of Table 11.2 line 3 without an infinite number).
struct InformationForm {
  SparseMatrixd omega;
  Eigen::VectorXd xi;
  int num_poses = 0;    ///< T + 1
  int feature_dim = 2;  ///< 2, or 3 with signatures
  int num_features() const;
  int pose_dim() const { return 3 * num_poses; }
};

/// Table 11.1: the path (T + 1, 3) from chaining the noise-free velocity motion model from
/// initial_pose; controls (T, 2) rows (v [m/s], w [rad/s]), dt (T,) seconds.
Poses2 eif_initialize(const Eigen::Ref<const RowMatrixXd>& controls, const Eigen::VectorXd& dt,
                      const Eigen::Vector3d& initial_pose = Eigen::Vector3d::Zero());

/// Feature means from each feature's first measurement, seen from the given path (the
/// linearisation point Table 11.2 needs for features before any solve).
RowMatrixXd eif_initial_features(const Eigen::Ref<const RowMatrixXd>& poses,
                                 const FeatureMeasurements& measurements, int num_features);

/// Table 11.2 (errata: column factor (I; -G_t^T), vector term x_hat_t - G_t mu_{t-1}, the
/// Jacobian signs, Q_t of variances, and + H mu in line 19), linearised at the path `poses`
/// (T + 1, 3) and `features` (N, d). R is the 3x3 pose-space motion noise, Q the d x d
/// measurement noise. Bearing and heading residuals are wrapped, so xi = Omega mu + J^T W r.
InformationForm eif_construct(const Eigen::Ref<const RowMatrixXd>& controls,
                              const Eigen::VectorXd& dt, const FeatureMeasurements& measurements,
                              const Eigen::Ref<const RowMatrixXd>& poses,
                              const Eigen::Ref<const RowMatrixXd>& features,
                              const Eigen::Matrix3d& R, const Eigen::MatrixXd& Q);

/// Table 11.3: Omega~ = Omega_xx - Omega_xm Omega_mm^-1 Omega_mx over the path alone, with
/// Omega_mm inverted block by block (it is block diagonal: features share no factor).
struct ReducedInformationForm {
  SparseMatrixd omega;
  Eigen::VectorXd xi;
};
ReducedInformationForm eif_reduce(const InformationForm& form);

/// Table 11.4 (erratum: mu_j = Omega_jj^-1 (xi_j - Omega_{j,tau(j)} mu~_tau(j))). The path from
/// the sparse Cholesky factor of Omega~, then each feature; `covariance_blocks` lists pairs of
/// pose indices (s, t) whose 3x3 block Sigma_{s,t} of the path covariance is returned, from the
/// factor (never a dense inverse). x_0 is known exactly: its blocks are zero.
struct EifSolution {
  Poses2 poses;          ///< (T + 1, 3), headings wrapped
  RowMatrixXd features;  ///< (N, d)
  std::vector<Eigen::Matrix3d> covariance_blocks;
};
/// The sparse Cholesky factor of Omega~ into `cholesky`: the first step of Table 11.4, and the
/// path covariance Table 11.8 applies through solves.
void eif_factorize_path(const SparseMatrixd& reduced_omega, SparseCholesky& cholesky);

EifSolution eif_solve(const ReducedInformationForm& reduced, const InformationForm& form,
                      const std::vector<std::pair<int, int>>& covariance_blocks = {},
                      SparseCholesky* cholesky = nullptr);

/// Table 11.5: construct, reduce and solve from the dead-reckoned path until no pose or
/// feature coordinate moves by more than `tolerance` (metres / radians), eq. 11.11 stops falling
/// beyond rounding, or max_iterations. A step that would raise eq. 11.11 is halved until it does not.
struct GraphSlamOptions {
  int max_iterations = 50;
  double tolerance = 1e-9;
  Eigen::Vector3d initial_pose = Eigen::Vector3d::Zero();
  bool path_covariances = true;  ///< the 3x3 marginal of every pose
  SparseCholeskyOptions linear_solver;
};
struct GraphSlamResult {
  Poses2 poses;
  RowMatrixXd features;
  std::vector<Eigen::Matrix3d> pose_covariances;  ///< (T + 1) blocks when requested
  int iterations = 0;
  bool converged = false;
  double objective = 0.0;  ///< eq. 11.11 at the result (the anchor term is zero)
};
GraphSlamResult graph_slam(const Eigen::Ref<const RowMatrixXd>& controls, const Eigen::VectorXd& dt,
                           const FeatureMeasurements& measurements, const Eigen::Matrix3d& R,
                           const Eigen::MatrixXd& Q, const GraphSlamOptions& options = {});

/// Table 11.5's loop (lines 3-5 repeated) from the linearisation point (poses, features): what
/// graph_slam runs after Table 11.1. `cholesky` keeps the factor of the last reduction and
/// `last_form`, when given, receives the last information form: the inputs of Table 11.8.
GraphSlamResult graph_slam_from(const Eigen::Ref<const RowMatrixXd>& controls,
                                const Eigen::VectorXd& dt, const FeatureMeasurements& measurements,
                                const Eigen::Matrix3d& R, const Eigen::MatrixXd& Q, Poses2 poses,
                                RowMatrixXd features, const GraphSlamOptions& options,
                                SparseCholesky& cholesky, InformationForm* last_form = nullptr);

/// The 3x3 marginal covariance of every pose x_0 .. x_T from the factor of Omega~ (x_0's is zero).
std::vector<Eigen::Matrix3d> eif_pose_covariances(const SparseCholesky& path_factor, int num_poses);

/// Eq. 11.11 without the anchor term: sum of the motion and measurement squared Mahalanobis
/// residuals at (poses, features).
double eif_objective(const Eigen::Ref<const RowMatrixXd>& controls, const Eigen::VectorXd& dt,
                     const FeatureMeasurements& measurements,
                     const Eigen::Ref<const RowMatrixXd>& poses,
                     const Eigen::Ref<const RowMatrixXd>& features, const Eigen::Matrix3d& R,
                     const Eigen::MatrixXd& Q);

}  // namespace probslam
