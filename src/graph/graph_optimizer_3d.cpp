// The 3-D pose graph's entry points to the optimiser shared with the 2-D one.
#include "pose_graph_3d_traits.hpp"
#include "probslam/graph/graph_optimizer.hpp"

namespace probslam {

OptimizationReport optimize(PoseGraph3D& graph, const OptimizerOptions& options,
                            const IterationCallback& on_iteration) {
  return graph_detail::optimize_graph(graph, options, on_iteration);
}

std::vector<Eigen::MatrixXd> marginal_covariances(const PoseGraph3D& graph, const std::vector<int>& ids,
                                                  const SparseCholeskyOptions& linear_solver) {
  return graph_detail::marginals(graph, ids, linear_solver);
}

std::vector<Eigen::MatrixXd> joint_marginal_covariances(const PoseGraph3D& graph,
                                                        const std::vector<std::vector<int>>& groups,
                                                        const SparseCholeskyOptions& linear_solver) {
  return graph_detail::joint_marginals(graph, groups, linear_solver);
}

}  // namespace probslam
