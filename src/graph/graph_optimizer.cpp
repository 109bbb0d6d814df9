#include "probslam/graph/graph_optimizer.hpp"

#include "optimizer_core.hpp"
#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"

namespace probslam {
namespace graph_detail {

// Variable sizes: 3 per pose, 2 per point; the first pose holds the gauge when nothing is fixed.
template <>
struct GraphTraits<PoseGraph2D> {
  /// AMD: faster than METIS on every 2-D graph measured (docs/pose_graphs.md).
  static constexpr FillOrdering kDefaultOrdering = FillOrdering::kAmd;
  static std::vector<std::pair<int, int>> couplings(const PoseGraph2D& graph) {
    std::vector<std::pair<int, int>> pairs;
    pairs.reserve(graph.pose_edges().size() + graph.point_edges().size());
    for (const PoseEdge& e : graph.pose_edges()) pairs.emplace_back(e.from, e.to);
    for (const PointEdge& e : graph.point_edges()) pairs.emplace_back(e.pose, e.point);
    return pairs;
  }
  static bool holdable(const PoseGraph2D& graph, int v) { return graph.vertex(v).kind == VertexKind::kPose; }
  static int tangent_size(const PoseGraph2D& graph, int v) { return holdable(graph, v) ? 3 : 2; }
  static std::vector<int> anchors(const PoseGraph2D&) { return {}; }  // no unary terms
  static Eigen::VectorXd term_chi2(const PoseGraph2D& graph) { return graph.edge_chi2(); }
  static bool has_edges(const PoseGraph2D& graph) {
    return !graph.pose_edges().empty() || !graph.point_edges().empty();
  }

  // The Gauss-Newton normal equations of a graph: pattern and block handles built once.
  class Equations : public EdgeAssembler {
   public:
    explicit Equations(const PoseGraph2D& graph) : EdgeAssembler(variable_sizes(graph), couplings(graph)) {
      for (const PoseEdge& e : graph.pose_edges()) pose_handles_.push_back(handles(e.from, e.to));
      for (const PointEdge& e : graph.point_edges()) point_handles_.push_back(handles(e.pose, e.point));
    }

    // H = sum w J^T Omega J and b = -sum w J^T Omega e at the graph's values.
    Objective assemble(const PoseGraph2D& graph, RobustKernel kernel, double width) {
      system().set_zero();
      Objective total;
      const auto& vertices = graph.vertices();
      for (size_t k = 0; k < graph.pose_edges().size(); ++k) {
        const PoseEdge& e = graph.pose_edges()[k];
        const auto lin = linearize_pose_edge(vertices[e.from].value, vertices[e.to].value, e.measurement);
        add_edge(pose_handles_[k], e.from, e.to, lin.error, lin.d_from, lin.d_to, e.information, kernel, width, total);
      }
      for (size_t k = 0; k < graph.point_edges().size(); ++k) {
        const PointEdge& e = graph.point_edges()[k];
        const auto lin = linearize_point_edge(vertices[e.pose].value, vertices[e.point].value.head<2>(),
                                              e.measurement);
        add_edge(point_handles_[k], e.pose, e.point, lin.error, lin.d_pose, lin.d_point, e.information, kernel,
                 width, total);
      }
      return total;
    }

    void apply(PoseGraph2D& graph, const Eigen::VectorXd& dx) const {
      for (int v = 0; v < graph.num_vertices(); ++v) {
        const int size = system().size(v);
        if (size == 0) continue;
        GraphVertex& vertex = graph.vertex(v);
        vertex.value.head(size) += dx.segment(system().offset(v), size);
        if (vertex.kind == VertexKind::kPose) vertex.value[2] = wrap_angle(vertex.value[2]);
      }
    }

   private:
    std::vector<std::array<BlockHandle, 3>> pose_handles_, point_handles_;
  };
};

}  // namespace graph_detail

void OptimizerOptions::validate() const {
  require(max_iterations >= 1, "max_iterations", "must be >= 1");
  require_positive(kernel_width, "kernel_width");
}

void OptimizerOptions::check_ranges() const {
  require(max_iterations >= 0, "max_iterations", "must be >= 0");
  require(relative_tolerance >= 0.0, "relative_tolerance", "must be >= 0");
  require(step_tolerance >= 0.0, "step_tolerance", "must be >= 0");
  if (kernel != RobustKernel::kNone) {
    require_positive(kernel_width, "kernel_width");
    // The kernels divide by width^2: it must neither overflow nor underflow.
    const double w2 = kernel_width * kernel_width;
    require(std::isfinite(w2) && w2 >= std::numeric_limits<double>::min(), "kernel_width",
            "must have a finite, normal square");
  }
}

OptimizationReport optimize(PoseGraph2D& graph, const OptimizerOptions& options,
                            const IterationCallback& on_iteration) {
  return graph_detail::optimize_graph(graph, options, on_iteration);
}

std::vector<Eigen::MatrixXd> marginal_covariances(const PoseGraph2D& graph,
                                                  const std::vector<int>& ids,
                                                  const SparseCholeskyOptions& linear_solver) {
  return graph_detail::marginals(graph, ids, linear_solver);
}

std::vector<Eigen::MatrixXd> joint_marginal_covariances(const PoseGraph2D& graph,
                                                        const std::vector<std::vector<int>>& groups,
                                                        const SparseCholeskyOptions& linear_solver) {
  return graph_detail::joint_marginals(graph, groups, linear_solver);
}

}  // namespace probslam
