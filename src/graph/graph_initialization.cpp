#include "probslam/graph/graph_initialization.hpp"

#include <algorithm>
#include <deque>
#include <stdexcept>
#include <string>

#include "graph_growth.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"

namespace probslam {
namespace {

using graph_detail::joined;

// The value of `target` that makes pose edge `e` exact, given the other end's value.
Eigen::Vector3d propagate(const PoseGraph2D& graph, const PoseEdge& e, int target) {
  const Pose2 z = Pose2::from_vector(e.measurement);
  if (target == e.to)
    return Pose2::from_vector(graph.vertex(e.from).value).compose(z).vector();
  return Pose2::from_vector(graph.vertex(e.to).value).compose(z.inverse()).vector();
}

// The point of edge `e` where its pose sees it.
void place_point(PoseGraph2D& graph, const PointEdge& e) {
  const Eigen::Vector2d p = Pose2::from_vector(graph.vertex(e.pose).value).transform_from(e.measurement);
  graph.vertex(e.point).value = {p.x(), p.y(), 0.0};
}

// The vertices that joined by `step` and the edges between them, with the held vertices held;
// `full_index` maps the part's vertex indices to the graph's.
PoseGraph2D part_of(const PoseGraph2D& graph, const std::vector<int>& joins, int step,
                    std::vector<int>& full_index) {
  PoseGraph2D part;
  full_index.clear();
  auto active = [&](int v) { return joined(joins, v, step); };
  for (int v = 0; v < graph.num_vertices(); ++v) {
    if (!active(v)) continue;
    const GraphVertex& vertex = graph.vertex(v);
    if (vertex.kind == VertexKind::kPose)
      part.add_pose(vertex.id, vertex.value);
    else
      part.add_point(vertex.id, vertex.value.head<2>());
    if (vertex.fixed) part.set_fixed(vertex.id);
    full_index.push_back(v);
  }
  for (const PoseEdge& e : graph.pose_edges())
    if (active(e.from) && active(e.to))
      part.add_pose_edge(graph.vertex(e.from).id, graph.vertex(e.to).id, e.measurement, e.information);
  for (const PointEdge& e : graph.point_edges())
    if (active(e.pose) && active(e.point))
      part.add_point_edge(graph.vertex(e.pose).id, graph.vertex(e.point).id, e.measurement,
                          e.information);
  return part;
}

}  // namespace

void initialize_odometry(PoseGraph2D& target) {
  PoseGraph2D graph = target;  // committed only when every value is finite
  const int n = graph.num_vertices();
  std::vector<char> reached(n, 0);
  std::deque<int> queue;
  for (int v = 0; v < n; ++v) {
    if (!graph.vertex(v).fixed) continue;
    reached[v] = 1;
    if (graph.vertex(v).kind == VertexKind::kPose) queue.push_back(v);
  }
  for (int v = 0; v < n && queue.empty(); ++v) {
    if (graph.vertex(v).kind != VertexKind::kPose) continue;
    reached[v] = 1;
    queue.push_back(v);
  }
  graph_detail::spread_along_pose_edges(graph, reached, std::move(queue), propagate);
  graph_detail::place_points(graph, reached, place_point);
  target.assign_values(graph.values());
}

OptimizerOptions IncrementalOptions::default_step() {
  OptimizerOptions o;
  o.max_iterations = 10;
  o.relative_tolerance = 1e-6;
  return o;
}

void IncrementalOptions::validate() const {
  require(poses_per_step >= 1, "poses_per_step", "must be >= 1");
  try {
    step.check_ranges();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("step.") + e.what());
  }
}

IncrementalReport optimize_incremental(PoseGraph2D& target, const IncrementalOptions& options) {
  return graph_detail::optimize_incremental_graph(target, options, propagate, place_point, part_of);
}

}  // namespace probslam
