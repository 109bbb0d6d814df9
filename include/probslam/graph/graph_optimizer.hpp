#pragma once
// Gauss-Newton and Levenberg-Marquardt for PoseGraph2D and PoseGraph3D on one shared sparse path
// (BlockSystem assembly, SparseCholesky solve with the analysis reused across iterations): the
// iterations are written once, the graphs differ only in their edges' linearisation and their
// vertices' update.
#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "probslam/graph/pose_graph_2d.hpp"
#include "probslam/graph/pose_graph_3d.hpp"
#include "probslam/graph/sparse_cholesky.hpp"

namespace probslam {

enum class OptimizerAlgorithm { kGaussNewton, kLevenbergMarquardt };

/// Robust kernels reweight an edge by rho'(s), s = e^T Omega e (iteratively reweighted least
/// squares): Huber is quadratic up to s = width^2 and linear in sqrt(s) beyond; Cauchy is
/// width^2 log(1 + s / width^2).
enum class RobustKernel { kNone, kHuber, kCauchy };

/// Levenberg-Marquardt's damping term lambda * D: Marquardt's D = diag(H) is invariant to the
/// units of the variables (metres against radians, or information entries from 10 to 1e12 in
/// one graph); Levenberg's D = I is not.
/// Levenberg's damping took 5 / 12 / 12 / 621 iterations where Marquardt's took 5 / 7 / 7 / 556
/// (Intel, M3500, manhattanOlson3500, input_INTEL_g2o), and on input_INTEL_g2o it stopped in
/// another minimum (chi2 6241 against 215.83).
enum class Damping { kMarquardt, kLevenberg };

template <>
struct OptionEnum<OptimizerAlgorithm> {
  static constexpr std::array<const char*, 2> names{"gauss-newton", "levenberg-marquardt"};
};
template <>
struct OptionEnum<RobustKernel> {
  static constexpr std::array<const char*, 3> names{"none", "huber", "cauchy"};
};
template <>
struct OptionEnum<Damping> {
  static constexpr std::array<const char*, 2> names{"marquardt", "levenberg"};
};

struct OptimizerOptions {
  OptimizerAlgorithm algorithm = OptimizerAlgorithm::kGaussNewton;
  Damping damping = Damping::kMarquardt;  ///< Levenberg-Marquardt only
  int max_iterations = 100;
  /// Stop when an iteration lowers the objective by less than this fraction of it.
  double relative_tolerance = 1e-10;
  /// Stop when the largest entry of the update is below this (metres / radians; for 3-D poses
  /// the tangent of pose_graph_3d.hpp).
  double step_tolerance = 1e-10;
  RobustKernel kernel = RobustKernel::kNone;
  double kernel_width = 1.0;  ///< in units of sqrt(chi2), e.g. 1.345 or chi2 quantiles' roots
  /// Its fill ordering kDefault is each graph's own: AMD for a PoseGraph2D, METIS for a
  /// PoseGraph3D (GraphTraits::kDefaultOrdering); the marginals' and chordal start's likewise.
  SparseCholeskyOptions linear_solver;

  /// std::invalid_argument naming the first bad option: max_iterations >= 1, kernel_width > 0.
  void validate() const;
  /// What optimize() accepts (std::invalid_argument naming the first bad field): max_iterations
  /// >= 0 (0 evaluates the start only), tolerances >= 0, a kernel's width > 0 with a finite,
  /// normal square (the kernels divide by it).
  void check_ranges() const;
  template <class V>
  static void describe(V& v) {
    using O = OptimizerOptions;
    v("algorithm", &O::algorithm, "", "\"gauss-newton\" or \"levenberg-marquardt\"");
    v("damping", &O::damping, "", "Levenberg-Marquardt's damping: \"marquardt\" (diag(H)) or \"levenberg\" (I)");
    v("max_iterations", &O::max_iterations, "", "iterations at most, >= 1");
    v("relative_tolerance", &O::relative_tolerance, "", "stop when an iteration lowers the objective by less than this fraction");
    v("step_tolerance", &O::step_tolerance, "", "stop when the update's largest entry is below this (m, rad)");
    v("kernel", &O::kernel, "", "robust kernel: \"none\", \"huber\" or \"cauchy\"");
    v("kernel_width", &O::kernel_width, "", "the kernel's width in units of sqrt(chi2)");
    v("linear_solver", &O::linear_solver, "", "the sparse Cholesky factorisation");
  }
};

struct OptimizationReport {
  int iterations = 0;
  double initial_chi2 = 0.0;
  double chi2 = 0.0;        ///< sum of e^T Omega e at the end (g2o's chi2)
  double objective = 0.0;   ///< the robust objective (equals chi2 without a kernel)
  bool converged = false;
  std::string stop_reason;
  std::vector<double> chi2_history;      ///< after each iteration
  std::vector<double> iteration_seconds; ///< linearise + factorise + solve + update
  long factor_nonzeros = 0;
};

/// Called on the calling thread after each completed iteration with its number (1 for the
/// first) and the chi2 after it; returning false stops the optimisation there. It lets a caller
/// show progress or stop a long run (Ctrl-C) without the optimiser knowing who is asking.
using IterationCallback = std::function<bool(int iteration, double chi2)>;

/// Minimises the graph's objective in place from its current values. Fixed vertices keep
/// their values; with none fixed the first pose is held (the gauge). Throws
/// std::invalid_argument for an empty graph, or a singular system (a part of the graph not
/// connected to a fixed vertex); the graph is then unchanged.
/// on_iteration (optional, see IterationCallback): false stops with stop_reason "stopped by the
/// callback" and the graph at that iteration's values. An exception it throws (a Python
/// KeyboardInterrupt) is rethrown after the graph is set to the last completed iteration's
/// values: an interrupted run keeps the work done, as a stopped one does. While it runs the graph
/// holds the values of the iteration just completed (a progress display may read them).
OptimizationReport optimize(PoseGraph2D& graph, const OptimizerOptions& options = {},
                            const IterationCallback& on_iteration = {});

/// Marginal covariances (3x3 for poses, 2x2 for points) of the given vertex ids at the
/// current values, from the sparse inverse of the information matrix. A fixed vertex has zero
/// covariance.
std::vector<Eigen::MatrixXd> marginal_covariances(const PoseGraph2D& graph,
                                                  const std::vector<int>& ids,
                                                  const SparseCholeskyOptions& linear_solver = {});

/// Joint marginal covariances of groups of vertices at the current values: for each group (ids),
/// the covariance of its vertices' variables stacked in the order given (3 per pose, 2 per
/// point), the cross-covariances between them included, from one factorisation of the
/// information matrix (entries inside the factor's pattern from the sparse inverse, the others
/// by solves; ch. 11.6 tests landmark pairs on these). A fixed vertex's rows and columns are
/// zero. Throws std::invalid_argument, before any work, for an unknown id or a group naming a
/// vertex twice (its joint covariance would be singular by construction), and as
/// marginal_covariances does for the graph.
std::vector<Eigen::MatrixXd> joint_marginal_covariances(const PoseGraph2D& graph,
                                                        const std::vector<std::vector<int>>& groups,
                                                        const SparseCholeskyOptions& linear_solver = {});

/// The same for a 3-D pose graph: the update is right-multiplicative (pose_graph_3d.hpp's tangent
/// convention), the first pose is held when none is fixed, errors and failures as for 2-D.
OptimizationReport optimize(PoseGraph3D& graph, const OptimizerOptions& options = {},
                            const IterationCallback& on_iteration = {});

/// 6x6 marginal covariances of 3-D poses in the tangent at each pose ([translation m in the pose's
/// frame, rotation vector rad], right perturbation); a fixed vertex has zero covariance.
std::vector<Eigen::MatrixXd> marginal_covariances(const PoseGraph3D& graph, const std::vector<int>& ids,
                                                  const SparseCholeskyOptions& linear_solver = {});
/// Joint marginal covariances of groups of 3-D poses (6 rows per pose), as for 2-D.
std::vector<Eigen::MatrixXd> joint_marginal_covariances(const PoseGraph3D& graph,
                                                        const std::vector<std::vector<int>>& groups,
                                                        const SparseCholeskyOptions& linear_solver = {});

}  // namespace probslam
