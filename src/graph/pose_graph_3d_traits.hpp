#pragma once
// Private to src/graph: PoseGraph3D on the shared optimiser (optimizer_core.hpp): only the
// linearisation, the block sizes (6 per pose, 3 per point) and the manifold update are its own.
#include "optimizer_core.hpp"
#include "probslam/graph/pose_graph_3d.hpp"

namespace probslam {
namespace graph_detail {

template <>
struct GraphTraits<PoseGraph3D> {
  /// Nested dissection orders sphere2500 and torus3D with less fill than AMD (torus3D: 1.0e9
  /// flops against 1.35e9 a factorisation; parking-garage a little more, 3e7 against 2.2e7).
  static constexpr FillOrdering kDefaultOrdering = FillOrdering::kMetis;
  static std::vector<std::pair<int, int>> couplings(const PoseGraph3D& graph) {
    std::vector<std::pair<int, int>> pairs;
    pairs.reserve(graph.pose_edges().size() + graph.point_edges().size());
    for (const Pose3Edge& e : graph.pose_edges()) pairs.emplace_back(e.from, e.to);
    for (const Point3Edge& e : graph.point_edges()) pairs.emplace_back(e.pose, e.point);
    return pairs;
  }
  // A point cannot hold the gauge: held alone it leaves the rotation about it free.
  static bool holdable(const PoseGraph3D& graph, int v) { return graph.vertex(v).kind == VertexKind::kPose; }
  static int tangent_size(const PoseGraph3D& graph, int v) { return holdable(graph, v) ? 6 : 3; }
  static bool has_edges(const PoseGraph3D& graph) {
    return !graph.pose_edges().empty() || !graph.point_edges().empty();
  }
  static std::vector<int> anchors(const PoseGraph3D& graph) {
    std::vector<int> out;
    for (const Pose3Prior& p : graph.pose_priors()) out.push_back(p.vertex);
    return out;
  }
  static Eigen::VectorXd term_chi2(const PoseGraph3D& graph) {
    const Eigen::VectorXd edges = graph.edge_chi2(), priors = graph.prior_chi2();
    Eigen::VectorXd out(edges.size() + priors.size());
    out << edges, priors;
    return out;
  }

  class Equations : public EdgeAssembler {
   public:
    explicit Equations(const PoseGraph3D& graph) : EdgeAssembler(variable_sizes(graph), couplings(graph)) {
      for (const Pose3Edge& e : graph.pose_edges()) handles_.push_back(handles(e.from, e.to));
      for (const Pose3Prior& p : graph.pose_priors()) prior_handles_.push_back(system().block(p.vertex, p.vertex));
      for (const Point3Edge& e : graph.point_edges()) point_handles_.push_back(handles(e.pose, e.point));
    }

    Objective assemble(const PoseGraph3D& graph, RobustKernel kernel, double width) {
      system().set_zero();
      Objective total;
      const auto& vertices = graph.vertices();
      for (size_t k = 0; k < graph.pose_edges().size(); ++k) {
        const Pose3Edge& e = graph.pose_edges()[k];
        const auto lin = linearize_pose3_edge(vertices[e.from].value, vertices[e.to].value, e.measurement);
        add_edge(handles_[k], e.from, e.to, lin.error, lin.d_from, lin.d_to, e.information, kernel, width, total);
      }
      for (size_t k = 0; k < graph.pose_priors().size(); ++k) {
        const Pose3Prior& p = graph.pose_priors()[k];
        const auto lin = linearize_pose3_prior(vertices[p.vertex].value, p.measurement);
        add_unary(prior_handles_[k], p.vertex, lin.error, lin.d_pose, p.information, kernel, width, total);
      }
      for (size_t k = 0; k < graph.point_edges().size(); ++k) {
        const Point3Edge& e = graph.point_edges()[k];
        const auto lin =
            linearize_point3_edge(vertices[e.pose].value, vertices[e.point].value.translation, e.measurement, e.offset);
        add_edge(point_handles_[k], e.pose, e.point, lin.error, lin.d_pose, lin.d_point, e.information, kernel, width,
                 total);
      }
      return total;
    }

    // x <- x (+) dx, right-multiplicative for a pose, additive for a point (pose_graph_3d.hpp's
    // tangent convention).
    void apply(PoseGraph3D& graph, const Eigen::VectorXd& dx) const {
      for (int v = 0; v < graph.num_vertices(); ++v) {
        if (system().size(v) == 0) continue;
        Pose3Vertex& vertex = graph.vertex(v);
        if (vertex.kind == VertexKind::kPoint)
          vertex.value.translation += dx.segment<3>(system().offset(v));
        else
          vertex.value = retract(vertex.value, dx.segment<6>(system().offset(v)));
      }
    }

   private:
    std::vector<std::array<BlockHandle, 3>> handles_;
    std::vector<BlockHandle> prior_handles_;
    std::vector<std::array<BlockHandle, 3>> point_handles_;
  };
};

}  // namespace graph_detail

}  // namespace probslam
