#include "probslam/graph/information_form.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <string>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/velocity_motion_model.hpp"
#include "probslam/graph/block_system.hpp"
#include "feature_block.hpp"

namespace probslam {
namespace {

// The finite-or-raise rule for an information form computed from finite input (overflow).
void require_finite_form(const SparseMatrixd& omega, const Eigen::VectorXd& xi, const char* where) {
  const Eigen::Map<const Eigen::VectorXd> values(omega.valuePtr(), omega.nonZeros());
  if (!values.allFinite() || !xi.allFinite())
    throw_invalid_argument(where, "result is not finite (controls, measurements or noise too large or too small?)");
}

// Asymmetry tolerated in R and Q relative to their largest entry: matrices built in code are
// symmetric to rounding; more is a mistake.
constexpr double kSymmetryTolerance = 1e-12;

// Checks the problem's arrays against each other; returns the number of features N.
int validate(const Eigen::Ref<const RowMatrixXd>& controls, const Eigen::VectorXd& dt,
             const FeatureMeasurements& meas) {
  require(controls.cols() == 2, "controls", "must have shape (T, 2): (v, w) per step");
  require_all_finite(controls, "controls");
  require(dt.size() == controls.rows(), "dt", "must have one entry per control");
  require((dt.array() > 0.0).all() && dt.allFinite(), "dt", "must be finite and > 0");
  const Eigen::Index m = meas.z.rows();
  require(meas.z.cols() == 2 || meas.z.cols() == 3, "z", "must have 2 or 3 columns");
  require(meas.time.size() == m, "time", "must have one entry per measurement");
  require(meas.feature.size() == m, "correspondences", "must have one entry per measurement");
  require(controls.rows() > 0 || m > 0, "controls", "and measurements are both empty");
  require_all_finite(meas.z, "z");
  if (m == 0) return 0;
  require((meas.z.col(0).array() > 0.0).all(), "z", "ranges must be > 0");
  require(meas.time.minCoeff() >= 0 && meas.time.maxCoeff() <= controls.rows(), "time",
          "must index a pose 0 .. T");
  require(meas.feature.minCoeff() >= 0, "correspondences", "must be >= 0");
  // Every feature 0 .. N-1 is observed, so N <= M: a larger index is refused before anything
  // is sized by it (one index of 1e9 would otherwise allocate a gigabyte before the error).
  require(meas.feature.maxCoeff() < m, "correspondences",
          "must index features 0 .. N-1, each observed, so every index must be < the number of measurements");
  const int n = meas.feature.maxCoeff() + 1;
  std::vector<char> seen(n, 0);
  for (Eigen::Index k = 0; k < m; ++k) seen[meas.feature[k]] = 1;
  for (int j = 0; j < n; ++j)
    if (!seen[j])
      throw_invalid_argument("correspondences", "feature " + std::to_string(j) +
                                                    " is never observed (indices must be 0 .. N-1)");
  return n;
}

void validate_state(const Eigen::Ref<const RowMatrixXd>& poses, const Eigen::Ref<const RowMatrixXd>& features,
                    Eigen::Index num_poses, int n, int d) {
  require(poses.rows() == num_poses && poses.cols() == 3, "poses", "must have shape (T + 1, 3)");
  require(features.rows() == n && features.cols() == d, "features",
          "must have shape (N, d), d the measurement's dimension");
  require_all_finite(poses, "poses");
  require_all_finite(features, "features");
}

// The two Gaussian factors of eq. 11.11 at a linearisation point: residual r (wrapped), the
// Jacobian of the prediction, and the inverse noise.
struct MotionFactor {
  Eigen::Vector3d residual;  // g(u_t, mu_{t-1}) - mu_t
  Eigen::Matrix3d g;         // G_t
};
MotionFactor motion_factor(const Eigen::Vector3d& prev, const Eigen::Vector3d& cur, double v,
                           double w, double dt) {
  MotionFactor f;
  f.residual = velocity_motion(prev, v, w, dt) - cur;
  f.residual[2] = wrap_angle(f.residual[2]);
  f.g = velocity_motion_jacobian(prev, v, w, dt);
  return f;
}

template <int D>
struct MeasurementFactor {
  Eigen::Matrix<double, D, 1> residual;  // z - h(mu), bearing wrapped
  MeasurementJacobians<D> h;
};
template <int D>
MeasurementFactor<D> measurement_factor(const Eigen::Vector3d& pose,
                                        const Eigen::Matrix<double, D, 1>& feature,
                                        const Eigen::Matrix<double, D, 1>& z) {
  MeasurementFactor<D> f;
  f.residual = z - range_bearing(pose, feature);
  f.residual[1] = wrap_angle(f.residual[1]);
  f.h = range_bearing_jacobians(pose, feature);
  return f;
}

template <int D>
void add_measurements(BlockSystem& system, const FeatureMeasurements& meas,
                      const Eigen::Ref<const RowMatrixXd>& poses,
                      const Eigen::Ref<const RowMatrixXd>& features, const Eigen::MatrixXd& Q,
                      int num_poses) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  const Mat q_inv = Q.inverse();
  // Table 11.2 lines 12-19: H^T Q^-1 H and H^T Q^-1 (z - z_hat) (the + H mu is added with
  // Omega mu in eif_construct).
  for (Eigen::Index k = 0; k < meas.z.rows(); ++k) {
    const int t = meas.time[k], j = meas.feature[k];
    const Eigen::Vector3d pose = poses.row(t).transpose();
    const Vec feature = features.row(j).transpose();
    const Vec z = meas.z.row(k).transpose();
    const auto f = measurement_factor<D>(pose, feature, z);
    const Eigen::Matrix<double, 3, D> hp_t_w = f.h.pose.transpose() * q_inv;
    const Mat hm_t_w = f.h.landmark.transpose() * q_inv;
    const int fv = num_poses + j;
    system.add(system.block(t, t), hp_t_w * f.h.pose);
    system.add(system.block(fv, fv), hm_t_w * f.h.landmark);
    system.add(system.block(t, fv), hp_t_w * f.h.landmark);
    system.add_rhs(t, hp_t_w * f.residual);
    system.add_rhs(fv, hm_t_w * f.residual);
  }
}

Eigen::VectorXd stack(const Eigen::Ref<const RowMatrixXd>& poses,
                      const Eigen::Ref<const RowMatrixXd>& features) {
  Eigen::VectorXd y(poses.size() + features.size());
  for (Eigen::Index t = 0; t < poses.rows(); ++t) y.segment<3>(3 * t) = poses.row(t).transpose();
  const Eigen::Index d = features.cols();
  for (Eigen::Index j = 0; j < features.rows(); ++j)
    y.segment(poses.size() + d * j, d) = features.row(j).transpose();
  return y;
}

}  // namespace

int InformationForm::num_features() const {
  return feature_dim > 0 ? static_cast<int>((xi.size() - pose_dim()) / feature_dim) : 0;
}

// Table 11.1.
Poses2 eif_initialize(const Eigen::Ref<const RowMatrixXd>& controls, const Eigen::VectorXd& dt,
                      const Eigen::Vector3d& initial_pose) {
  validate(controls, dt, FeatureMeasurements{Eigen::VectorXi(0), RowMatrixXd(0, 2), Eigen::VectorXi(0)});
  require_all_finite(initial_pose, "initial_pose");
  Poses2 path(controls.rows() + 1, 3);
  path.row(0) = initial_pose.transpose();
  path(0, 2) = wrap_angle(initial_pose[2]);
  for (Eigen::Index t = 0; t < controls.rows(); ++t)
    path.row(t + 1) = velocity_motion(path.row(t).transpose(), controls(t, 0), controls(t, 1), dt[t]).transpose();
  require(path.allFinite(), "controls", "give a path that is not finite (too large?)");
  return path;
}

RowMatrixXd eif_initial_features(const Eigen::Ref<const RowMatrixXd>& poses,
                                 const FeatureMeasurements& meas, int num_features) {
  require(poses.cols() == 3, "poses", "must have shape (T + 1, 3)");
  require_all_finite(poses, "poses");
  require(meas.z.cols() == 2 || meas.z.cols() == 3, "z", "must have 2 or 3 columns");
  require(meas.time.size() == meas.z.rows(), "time", "must have one entry per measurement");
  require(meas.feature.size() == meas.z.rows(), "correspondences", "must have one entry per measurement");
  require_all_finite(meas.z, "z");
  require((meas.z.col(0).array() > 0.0).all(), "z", "ranges must be > 0");
  // Each feature is observed at least once: more features than measurements is a bad index,
  // refused before the (num_features, d) array is allocated.
  require(num_features >= 0 && num_features <= meas.z.rows(), "correspondences",
          "must index features 0 .. N-1, each observed, so every index must be < the number of measurements");
  const int d = static_cast<int>(meas.z.cols());
  RowMatrixXd features(num_features, d);
  std::vector<char> done(num_features, 0);
  for (Eigen::Index k = 0; k < meas.z.rows(); ++k) {
    const int j = meas.feature[k];
    require(j >= 0 && j < num_features, "correspondences", "must index a feature 0 .. N-1");
    require(meas.time[k] >= 0 && meas.time[k] < poses.rows(), "time", "must index a pose");
    if (done[j]) continue;
    done[j] = 1;
    const Eigen::Vector3d pose = poses.row(meas.time[k]).transpose();
    features.row(j).head<2>() = landmark_from_range_bearing(pose, meas.z.row(k).head<2>().transpose()).transpose();
    if (d == 3) features(j, 2) = meas.z(k, 2);
  }
  for (int j = 0; j < num_features; ++j)
    if (!done[j]) throw_invalid_argument("correspondences", "feature " + std::to_string(j) + " is never observed");
  require(features.allFinite(), "z", "places features at non-finite positions (too large?)");
  return features;
}

// Table 11.2.
InformationForm eif_construct(const Eigen::Ref<const RowMatrixXd>& controls,
                              const Eigen::VectorXd& dt, const FeatureMeasurements& meas,
                              const Eigen::Ref<const RowMatrixXd>& poses,
                              const Eigen::Ref<const RowMatrixXd>& features,
                              const Eigen::Matrix3d& R, const Eigen::MatrixXd& Q) {
  const int n = validate(controls, dt, meas);
  const int d = static_cast<int>(meas.z.cols());
  const int num_poses = static_cast<int>(controls.rows()) + 1;
  validate_state(poses, features, num_poses, n, d);
  require_symmetric_positive_definite(R, "R", kSymmetryTolerance);
  require(Q.rows() == d && Q.cols() == d, "Q", "must be d x d, d the measurement's dimension");
  require_symmetric_positive_definite(Q, "Q", kSymmetryTolerance);

  std::vector<int> sizes(num_poses, 3);
  sizes.resize(num_poses + n, d);
  std::vector<std::pair<int, int>> couplings;
  for (int t = 1; t < num_poses; ++t) couplings.emplace_back(t - 1, t);
  for (Eigen::Index k = 0; k < meas.z.rows(); ++k) couplings.emplace_back(meas.time[k], num_poses + meas.feature[k]);
  BlockSystem system(sizes, couplings);

  // Lines 4-9: the factor x_t - G_t x_{t-1} = x_hat_t - G_t mu_{t-1} with noise R:
  // [I; -G^T] R^-1 [I, -G] into Omega, and J^T R^-1 r into the vector term.
  const Eigen::Matrix3d r_inv = R.inverse();
  for (int t = 1; t < num_poses; ++t) {
    const MotionFactor f = motion_factor(poses.row(t - 1).transpose(), poses.row(t).transpose(),
                                         controls(t - 1, 0), controls(t - 1, 1), dt[t - 1]);
    const Eigen::Matrix3d g_t_rinv = f.g.transpose() * r_inv;
    system.add(system.block(t, t), r_inv);
    system.add(system.block(t - 1, t - 1), g_t_rinv * f.g);
    system.add(system.block(t - 1, t), -g_t_rinv);
    system.add_rhs(t, r_inv * f.residual);
    system.add_rhs(t - 1, -(g_t_rinv * f.residual));
  }
  if (d == 2)
    add_measurements<2>(system, meas, poses, features, Q, num_poses);
  else
    add_measurements<3>(system, meas, poses, features, Q, num_poses);

  InformationForm form;
  form.num_poses = num_poses;
  form.feature_dim = d;
  form.omega = system.upper().selfadjointView<Eigen::Upper>();
  const Eigen::VectorXd mu = stack(poses, features);
  form.xi = form.omega * mu + system.rhs();

  // The anchor (line 3): condition on x_0 = mu_0.
  const Eigen::Vector3d x0 = mu.head<3>();
  form.xi -= form.omega.leftCols(3) * x0;
  form.omega.prune([](Eigen::Index row, Eigen::Index col, double) {
    return (row >= 3 && col >= 3) || row == col;
  });
  for (int i = 0; i < 3; ++i) form.omega.coeffRef(i, i) = 1.0;
  form.xi.head<3>() = x0;
  form.omega.makeCompressed();
  require_finite_form(form.omega, form.xi, "eif_construct");
  return form;
}

Eigen::MatrixXd graph_detail::feature_information_inverse(const InformationForm& form, int j) {
  const int p = form.pose_dim(), d = form.feature_dim;
  Eigen::MatrixXd block = Eigen::MatrixXd::Zero(d, d);
  for (int c = 0; c < d; ++c) {
    for (SparseMatrixd::InnerIterator it(form.omega, p + d * j + c); it; ++it) {
      if (it.row() < p) continue;
      if (it.row() < p + d * j || it.row() >= p + d * (j + 1)) {
        if (it.value() != 0.0)
          throw_invalid_argument("omega", "features " + std::to_string(j) + " and " +
                                              std::to_string((it.row() - p) / d) +
                                              " share information: Omega_mm must be block diagonal");
        continue;
      }
      block(it.row() - p - d * j, c) = it.value();
    }
  }
  require_all_finite(block, "omega");
  Eigen::LLT<Eigen::MatrixXd> llt(block);
  if (llt.info() != Eigen::Success)
    throw_invalid_argument("omega", "the block of feature " + std::to_string(j) +
                                        " is not positive definite (is it observed?)");
  return llt.solve(Eigen::MatrixXd::Identity(d, d));
}

namespace {

void validate_form(const InformationForm& form) {
  require(form.num_poses > 0, "num_poses", "must be > 0");
  require(form.feature_dim == 2 || form.feature_dim == 3, "feature_dim", "must be 2 or 3");
  const Eigen::Index dim = form.omega.rows();
  require(form.omega.cols() == dim, "omega", "must be square");
  require(form.xi.size() == dim, "xi", "must have one entry per row of omega");
  require(dim >= form.pose_dim() && (dim - form.pose_dim()) % form.feature_dim == 0, "omega",
          "must have 3 (T + 1) + d N rows");
  require_all_finite(form.xi, "xi");
  require_all_finite(Eigen::Map<const Eigen::VectorXd>(form.omega.valuePtr(), form.omega.nonZeros()), "omega");
}

// Omega_mm^-1 as a block-diagonal sparse matrix.
SparseMatrixd feature_block_inverse(const InformationForm& form) {
  const int d = form.feature_dim, n = form.num_features();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(n) * d * d);
  for (int j = 0; j < n; ++j) {
    const Eigen::MatrixXd inv = graph_detail::feature_information_inverse(form, j);
    for (int c = 0; c < d; ++c)
      for (int r = 0; r < d; ++r) triplets.emplace_back(d * j + r, d * j + c, inv(r, c));
  }
  SparseMatrixd out(d * n, d * n);
  out.setFromTriplets(triplets.begin(), triplets.end());
  return out;
}

}  // namespace

// Table 11.3, all features at once: the same Schur complement as one feature at a time.
ReducedInformationForm eif_reduce(const InformationForm& form) {
  validate_form(form);
  const int p = form.pose_dim();
  const Eigen::Index m = form.omega.rows() - p;
  const SparseMatrixd dinv = feature_block_inverse(form);
  const SparseMatrixd omega_pm = form.omega.block(0, p, p, m);
  ReducedInformationForm out;
  const SparseMatrixd fill = omega_pm * dinv * SparseMatrixd(omega_pm.transpose());
  out.omega = SparseMatrixd(form.omega.topLeftCorner(p, p)) - fill;
  out.omega.makeCompressed();
  out.xi = form.xi.head(p) - omega_pm * (dinv * form.xi.tail(m));
  require_finite_form(out.omega, out.xi, "eif_reduce");
  return out;
}

void eif_factorize_path(const SparseMatrixd& reduced_omega, SparseCholesky& cholesky) {
  SparseMatrixd upper = reduced_omega.triangularView<Eigen::Upper>();
  upper.makeCompressed();
  cholesky.factorize(upper);
}

// Table 11.4.
EifSolution eif_solve(const ReducedInformationForm& reduced, const InformationForm& form,
                      const std::vector<std::pair<int, int>>& covariance_blocks,
                      SparseCholesky* cholesky) {
  validate_form(form);
  const int p = form.pose_dim(), d = form.feature_dim, n = form.num_features();
  require(reduced.omega.rows() == p && reduced.omega.cols() == p, "reduced",
          "omega must be 3 (T + 1) square");
  require(reduced.xi.size() == p, "reduced", "xi must have 3 (T + 1) entries");
  require_finite_form(reduced.omega, reduced.xi, "reduced");
  for (const auto& [s, t] : covariance_blocks)
    require(s >= 0 && t >= 0 && s < form.num_poses && t < form.num_poses, "covariance_blocks",
            "must index poses 0 .. T");
  SparseCholesky local;
  SparseCholesky& chol = cholesky ? *cholesky : local;
  eif_factorize_path(reduced.omega, chol);
  const Eigen::VectorXd path = chol.solve(reduced.xi);

  EifSolution out;
  out.poses.resize(form.num_poses, 3);
  for (int t = 0; t < form.num_poses; ++t) {
    out.poses.row(t) = path.segment<3>(3 * t).transpose();
    out.poses(t, 2) = wrap_angle(out.poses(t, 2));
  }
  const Eigen::Index m = form.omega.rows() - p;
  const SparseMatrixd omega_mp = form.omega.block(p, 0, m, p);
  const Eigen::VectorXd features = feature_block_inverse(form) * (form.xi.tail(m) - omega_mp * path);
  out.features = Eigen::Map<const RowMatrixXd>(features.data(), n, d);

  std::vector<InverseBlock> requests;
  for (const auto& [s, t] : covariance_blocks) requests.push_back({3 * s, 3, 3 * t, 3});
  const auto blocks = chol.inverse_blocks(requests);
  for (size_t k = 0; k < blocks.size(); ++k) {
    const bool anchored = covariance_blocks[k].first == 0 || covariance_blocks[k].second == 0;
    out.covariance_blocks.push_back(anchored ? Eigen::Matrix3d::Zero() : Eigen::Matrix3d(blocks[k]));
  }
  require(out.poses.allFinite() && out.features.allFinite(), "eif_solve",
          "result is not finite (information too large or too small?)");
  for (const Eigen::Matrix3d& b : out.covariance_blocks)
    require(b.allFinite(), "eif_solve", "covariance is not finite (information too large or too small?)");
  return out;
}

double eif_objective(const Eigen::Ref<const RowMatrixXd>& controls, const Eigen::VectorXd& dt,
                     const FeatureMeasurements& meas, const Eigen::Ref<const RowMatrixXd>& poses,
                     const Eigen::Ref<const RowMatrixXd>& features, const Eigen::Matrix3d& R,
                     const Eigen::MatrixXd& Q) {
  const int n = validate(controls, dt, meas);
  const int d = static_cast<int>(meas.z.cols());
  validate_state(poses, features, controls.rows() + 1, n, d);
  require(Q.rows() == d && Q.cols() == d, "Q", "must be d x d, d the measurement's dimension");
  const Eigen::Matrix3d r_inv = R.inverse();
  const Eigen::MatrixXd q_inv = Q.inverse();
  double sum = 0.0;
  for (Eigen::Index t = 1; t < poses.rows(); ++t) {
    const Eigen::Vector3d r = motion_factor(poses.row(t - 1).transpose(), poses.row(t).transpose(),
                                            controls(t - 1, 0), controls(t - 1, 1), dt[t - 1]).residual;
    sum += r.dot(r_inv * r);
  }
  for (Eigen::Index k = 0; k < meas.z.rows(); ++k) {
    const Eigen::Vector3d pose = poses.row(meas.time[k]).transpose();
    Eigen::VectorXd r(d);
    if (d == 2) {
      r = meas.z.row(k).transpose() - range_bearing(pose, Eigen::Vector2d(features.row(meas.feature[k]).transpose()));
    } else {
      r = meas.z.row(k).transpose() - range_bearing(pose, Eigen::Vector3d(features.row(meas.feature[k]).transpose()));
    }
    r[1] = wrap_angle(r[1]);
    sum += r.dot(q_inv * r);
  }
  require(std::isfinite(sum), "eif_objective", "is not finite (residuals or noise too large or too small?)");
  return sum;
}

std::vector<Eigen::Matrix3d> eif_pose_covariances(const SparseCholesky& path_factor, int num_poses) {
  require(path_factor.rows() == 3 * num_poses, "num_poses", "does not match the factor's size");
  std::vector<InverseBlock> requests;
  for (int t = 1; t < num_poses; ++t) requests.push_back({3 * t, 3, 3 * t, 3});
  std::vector<Eigen::Matrix3d> out{Eigen::Matrix3d::Zero()};
  for (const auto& b : path_factor.inverse_blocks(requests)) {
    require(b.allFinite(), "pose_covariances", "are not finite (information too large or too small?)");
    out.emplace_back(b);
  }
  return out;
}

namespace {

// The largest coordinate change between two estimates (headings wrapped), metres / radians.
double largest_change(const EifSolution& next, const Poses2& poses, const RowMatrixXd& features) {
  Eigen::ArrayXXd pose_change = (next.poses - poses).cwiseAbs().array();
  for (Eigen::Index t = 0; t < poses.rows(); ++t)
    pose_change(t, 2) = std::abs(wrap_angle(next.poses(t, 2) - poses(t, 2)));
  double change = pose_change.size() ? pose_change.maxCoeff() : 0.0;
  if (features.size()) change = std::max(change, (next.features - features).cwiseAbs().maxCoeff());
  return change;
}

// A decrease of eq. 11.11 below this fraction of it is rounding: the estimate has converged even
// when rounding keeps its coordinates moving by more than the tolerance (a feature measured at
// millimetres eliminated by the Schur complement loses that many digits).
constexpr double kStalledDecrease = 1e-12;

// Halvings of a Gauss-Newton step tried before it is taken as it is.
constexpr int kMaxStepHalvings = 20;

// Table 11.5 takes the full Gauss-Newton step, which is what converges near the optimum; far from
// it (an inconsistent feature, a measurement at a few millimetres) the full step can raise eq.
// 11.11 and the iteration oscillates. The step is then halved until the objective drops, which
// leaves the fixed points, and every step that already descends, unchanged. Returns the
// objective at the (possibly shortened) step stored in `next`.
double shorten_until_descent(const Eigen::Ref<const RowMatrixXd>& controls, const Eigen::VectorXd& dt,
                             const FeatureMeasurements& meas, const Eigen::Matrix3d& R,
                             const Eigen::MatrixXd& Q, const GraphSlamResult& current,
                             EifSolution& next, double objective) {
  double trial = eif_objective(controls, dt, meas, next.poses, next.features, R, Q);
  Poses2 step = next.poses - current.poses;
  for (Eigen::Index t = 0; t < step.rows(); ++t) step(t, 2) = wrap_angle(step(t, 2));
  const RowMatrixXd feature_step = next.features - current.features;
  double alpha = 1.0;
  for (int k = 0; k < kMaxStepHalvings && !(trial <= objective); ++k) {
    alpha *= 0.5;
    next.poses = current.poses + alpha * step;
    for (Eigen::Index t = 0; t < step.rows(); ++t) next.poses(t, 2) = wrap_angle(next.poses(t, 2));
    next.features = current.features + alpha * feature_step;
    trial = eif_objective(controls, dt, meas, next.poses, next.features, R, Q);
  }
  return trial;
}

}  // namespace

// Table 11.5 lines 3-5, repeated.
GraphSlamResult graph_slam_from(const Eigen::Ref<const RowMatrixXd>& controls,
                                const Eigen::VectorXd& dt, const FeatureMeasurements& meas,
                                const Eigen::Matrix3d& R, const Eigen::MatrixXd& Q, Poses2 poses,
                                RowMatrixXd features, const GraphSlamOptions& options,
                                SparseCholesky& cholesky, InformationForm* last_form) {
  require(options.max_iterations > 0, "max_iterations", "must be > 0");
  require(options.tolerance >= 0.0, "tolerance", "must be >= 0");
  GraphSlamResult result;
  result.poses = std::move(poses);
  result.features = std::move(features);
  double objective = eif_objective(controls, dt, meas, result.poses, result.features, R, Q);
  for (int it = 0; it < options.max_iterations; ++it) {
    InformationForm form = eif_construct(controls, dt, meas, result.poses, result.features, R, Q);
    EifSolution sol = eif_solve(eif_reduce(form), form, {}, &cholesky);
    const double before = objective;
    objective = shorten_until_descent(controls, dt, meas, R, Q, result, sol, objective);
    const double change = largest_change(sol, result.poses, result.features);
    const bool stalled = before - objective <= kStalledDecrease * std::max(before, 1.0);
    result.poses = std::move(sol.poses);
    result.features = std::move(sol.features);
    result.iterations = it + 1;
    if (last_form) *last_form = std::move(form);
    if (change <= options.tolerance || stalled) {
      result.converged = true;
      break;
    }
  }
  if (options.path_covariances)
    result.pose_covariances = eif_pose_covariances(cholesky, static_cast<int>(result.poses.rows()));
  result.objective = objective;
  return result;
}

// Table 11.5.
GraphSlamResult graph_slam(const Eigen::Ref<const RowMatrixXd>& controls, const Eigen::VectorXd& dt,
                           const FeatureMeasurements& meas, const Eigen::Matrix3d& R,
                           const Eigen::MatrixXd& Q, const GraphSlamOptions& options) {
  const int n = validate(controls, dt, meas);
  Poses2 poses = eif_initialize(controls, dt, options.initial_pose);
  RowMatrixXd features = eif_initial_features(poses, meas, n);
  SparseCholesky cholesky(options.linear_solver);
  return graph_slam_from(controls, dt, meas, R, Q, std::move(poses), std::move(features), options,
                         cholesky);
}

}  // namespace probslam
