#include "probslam/graph/graph_initialization.hpp"

#include <algorithm>
#include <deque>

#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"

namespace probslam {
namespace {

constexpr int kNone = -1;

// The value of `target` that makes pose edge `e` exact, given the other end's value.
Eigen::Vector3d propagate(const PoseGraph2D& graph, const PoseEdge& e, int target) {
  const Pose2 z = Pose2::from_vector(e.measurement);
  if (target == e.to)
    return Pose2::from_vector(graph.vertex(e.from).value).compose(z).vector();
  return Pose2::from_vector(graph.vertex(e.to).value).compose(z.inverse()).vector();
}

Eigen::Vector3d place_point(const PoseGraph2D& graph, const PointEdge& e) {
  const Eigen::Vector2d p =
      Pose2::from_vector(graph.vertex(e.pose).value).transform_from(e.measurement);
  return {p.x(), p.y(), 0.0};
}

// Pose-edge indices touching each vertex, in edge order.
std::vector<std::vector<int>> incident_pose_edges(const PoseGraph2D& graph) {
  std::vector<std::vector<int>> incident(graph.num_vertices());
  for (int k = 0; k < static_cast<int>(graph.pose_edges().size()); ++k) {
    incident[graph.pose_edges()[k].from].push_back(k);
    incident[graph.pose_edges()[k].to].push_back(k);
  }
  return incident;
}

// The first point edge of each point seen from a pose that `earlier` ranks first.
template <typename Rank>
std::vector<int> first_observations(const PoseGraph2D& graph, Rank rank) {
  std::vector<int> first(graph.num_vertices(), kNone);
  const auto& edges = graph.point_edges();
  for (int k = 0; k < static_cast<int>(edges.size()); ++k) {
    int& f = first[edges[k].point];
    if (rank(edges[k].pose) < 0) continue;
    if (f == kNone || rank(edges[k].pose) < rank(edges[f].pose)) f = k;
  }
  return first;
}

// The vertices that joined by `step` and the edges between them, with the held vertices held;
// `full_index` maps the part's vertex indices to the graph's.
PoseGraph2D part_of(const PoseGraph2D& graph, const std::vector<int>& joins, int step,
                    std::vector<int>& full_index) {
  PoseGraph2D part;
  full_index.clear();
  auto active = [&](int v) { return joins[v] != kNone && joins[v] <= step; };
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
  const auto incident = incident_pose_edges(graph);
  while (!queue.empty()) {
    const int v = queue.front();
    queue.pop_front();
    for (const int k : incident[v]) {
      const PoseEdge& e = graph.pose_edges()[k];
      const int other = e.from == v ? e.to : e.from;
      if (reached[other]) continue;
      reached[other] = 1;
      graph.vertex(other).value = propagate(graph, e, other);
      queue.push_back(other);
    }
  }
  const auto first = first_observations(graph, [&](int pose) { return reached[pose] ? 0 : -1; });
  for (int v = 0; v < n; ++v)
    if (!reached[v] && first[v] != kNone) graph.vertex(v).value = place_point(graph, graph.point_edges()[first[v]]);
  target.assign_values(graph.values());
}

IncrementalReport optimize_incremental(PoseGraph2D& target, const IncrementalOptions& options) {
  require(options.poses_per_step >= 1, "poses_per_step", "must be >= 1");
  PoseGraph2D graph = target;  // committed only when every step succeeded with finite values
  const int n = graph.num_vertices();
  std::vector<int> order, position(n, kNone), joins(n, kNone);
  for (int v = 0; v < n; ++v) {
    if (graph.vertex(v).kind != VertexKind::kPose) continue;
    position[v] = static_cast<int>(order.size());
    joins[v] = position[v] / options.poses_per_step;
    order.push_back(v);
  }
  require(!order.empty(), "graph", "has no poses");
  // Each pose is seeded from its first edge to an earlier pose, each point from its first
  // observation by the earliest pose; a point joins with that pose.
  std::vector<int> parent(n, kNone);
  const auto incident = incident_pose_edges(graph);
  for (const int v : order)
    for (const int k : incident[v]) {
      const PoseEdge& e = graph.pose_edges()[k];
      if (position[e.from == v ? e.to : e.from] < position[v]) {
        parent[v] = k;
        break;
      }
    }
  const auto first = first_observations(graph, [&](int pose) { return position[pose]; });
  std::vector<std::vector<int>> points_joining(joins[order.back()] + 1);
  for (int v = 0; v < n; ++v) {
    if (graph.vertex(v).kind != VertexKind::kPoint || first[v] == kNone) continue;
    joins[v] = joins[graph.point_edges()[first[v]].pose];
    points_joining[joins[v]].push_back(v);
  }

  IncrementalReport report;
  std::vector<int> full_index;
  for (int step = 0; step < static_cast<int>(points_joining.size()); ++step) {
    const int end = std::min<int>((step + 1) * options.poses_per_step, order.size());
    for (int i = step * options.poses_per_step; i < end; ++i) {
      const int v = order[i];
      if (!graph.vertex(v).fixed && parent[v] != kNone)
        graph.vertex(v).value = propagate(graph, graph.pose_edges()[parent[v]], v);
    }
    for (const int v : points_joining[step])
      if (!graph.vertex(v).fixed) graph.vertex(v).value = place_point(graph, graph.point_edges()[first[v]]);
    PoseGraph2D part = part_of(graph, joins, step, full_index);
    if (part.pose_edges().empty() && part.point_edges().empty()) continue;  // a lone first pose
    report.add_step(optimize(part, options.step));
    for (int j = 0; j < part.num_vertices(); ++j) graph.vertex(full_index[j]).value = part.vertex(j).value;
  }
  report.chi2 = graph.chi2();
  target.assign_values(graph.values());
  return report;
}

}  // namespace probslam
