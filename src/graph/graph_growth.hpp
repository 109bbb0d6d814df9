#pragma once
// Private to src/graph: growing a graph's values from its edges, written once for PoseGraph2D and
// PoseGraph3D (graph_initialization.cpp, pose_graph_3d_initialization.cpp): dead reckoning along
// a breadth-first spanning tree, each point from its first sighting, and the incremental
// optimisation's schedule. A graph type brings two functions:
//   propagate(graph, pose_edge, v)   the value of pose v that makes the edge exact, from its other end
//   place(graph, point_edge)         writes the point's value from its pose's (the edge made exact)
// Vertices expose .kind and .fixed; pose edges .from / .to; point edges .pose / .point.
#include <algorithm>
#include <deque>
#include <vector>

#include "probslam/core/check.hpp"
#include "probslam/graph/graph_initialization.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/vertex_kind.hpp"

namespace probslam::graph_detail {

constexpr int kNone = -1;

template <typename Graph>
bool is_pose(const Graph& graph, int v) {
  return graph.vertex(v).kind == VertexKind::kPose;
}

// Pose-edge indices touching each vertex, in edge order.
template <typename Graph>
std::vector<std::vector<int>> incident_pose_edges(const Graph& graph) {
  std::vector<std::vector<int>> incident(graph.num_vertices());
  for (int k = 0; k < static_cast<int>(graph.pose_edges().size()); ++k) {
    incident[graph.pose_edges()[k].from].push_back(k);
    incident[graph.pose_edges()[k].to].push_back(k);
  }
  return incident;
}

// The first point edge of each point seen from a pose that `rank` ranks first (a rank below 0:
// not eligible); kNone for a point no eligible pose sees.
template <typename Graph, typename Rank>
std::vector<int> first_observations(const Graph& graph, Rank rank) {
  std::vector<int> first(graph.num_vertices(), kNone);
  const auto& edges = graph.point_edges();
  for (int k = 0; k < static_cast<int>(edges.size()); ++k) {
    int& f = first[edges[k].point];
    if (rank(edges[k].pose) < 0) continue;
    if (f == kNone || rank(edges[k].pose) < rank(edges[f].pose)) f = k;
  }
  return first;
}

// Every free point not yet placed (placed[v] == 0) placed by its first edge, in the order added,
// from a placed pose.
template <typename Graph, typename Place>
void place_points(Graph& graph, const std::vector<char>& placed, Place place) {
  const auto first = first_observations(graph, [&](int pose) { return placed[pose] ? 0 : -1; });
  for (int v = 0; v < graph.num_vertices(); ++v)
    if (!placed[v] && !graph.vertex(v).fixed && first[v] != kNone) place(graph, graph.point_edges()[first[v]]);
}

// Dead reckoning: from the poses in `queue` (marked in `reached`), each pose reached first along
// a pose edge, edges taken in the order they were added, gets the value that makes that edge exact.
template <typename Graph, typename Propagate>
void spread_along_pose_edges(Graph& graph, std::vector<char>& reached, std::deque<int> queue, Propagate propagate) {
  const auto incident = incident_pose_edges(graph);
  while (!queue.empty()) {
    const int v = queue.front();
    queue.pop_front();
    for (const int k : incident[v]) {
      const auto& e = graph.pose_edges()[k];
      const int other = e.from == v ? e.to : e.from;
      if (reached[other]) continue;
      reached[other] = 1;
      graph.vertex(other).value = propagate(graph, e, other);
      queue.push_back(other);
    }
  }
}

// The vertices that joined by `step` (joins[v] <= step), as optimize_incremental's part_of keeps
// them.
inline bool joined(const std::vector<int>& joins, int v, int step) { return joins[v] != kNone && joins[v] <= step; }

// optimize_incremental for either graph (graph_initialization.hpp): poses join in the order they
// were added, poses_per_step to a step, each seeded from its first edge to an earlier pose; a
// point joins with the earliest pose that sees it, placed by that pose's first edge to it; after
// each step part_of(graph, joins, step, full_index) (the joined vertices with the terms among
// them, full_index mapping its vertices to the graph's) is optimised with options.step. The
// target changes only when every step succeeded.
template <typename Graph, typename Propagate, typename Place, typename PartOf>
IncrementalReport optimize_incremental_graph(Graph& target, const IncrementalOptions& options, Propagate propagate,
                                             Place place, PartOf part_of) {
  options.validate();
  Graph graph = target;  // committed only when every step succeeded with finite values
  const int n = graph.num_vertices();
  std::vector<int> order, position(n, kNone), joins(n, kNone);
  for (int v = 0; v < n; ++v) {
    if (!is_pose(graph, v)) continue;
    position[v] = static_cast<int>(order.size());
    joins[v] = position[v] / options.poses_per_step;
    order.push_back(v);
  }
  require(!order.empty(), "graph", "has no poses");
  std::vector<int> parent(n, kNone);
  const auto incident = incident_pose_edges(graph);
  for (const int v : order)
    for (const int k : incident[v]) {
      const auto& e = graph.pose_edges()[k];
      if (position[e.from == v ? e.to : e.from] < position[v]) {
        parent[v] = k;
        break;
      }
    }
  const auto first = first_observations(graph, [&](int pose) { return position[pose]; });
  std::vector<std::vector<int>> points_joining(joins[order.back()] + 1);
  for (int v = 0; v < n; ++v) {
    if (is_pose(graph, v) || first[v] == kNone) continue;
    joins[v] = joins[graph.point_edges()[first[v]].pose];
    points_joining[joins[v]].push_back(v);
  }

  IncrementalReport report;
  std::vector<int> full_index;
  IterationCallback on_iteration;
  if (options.interrupt)
    on_iteration = [&options](int, double) {
      options.interrupt();
      return true;
    };
  for (int step = 0; step < static_cast<int>(points_joining.size()); ++step) {
    if (options.interrupt) options.interrupt();
    const int end = std::min<int>((step + 1) * options.poses_per_step, static_cast<int>(order.size()));
    for (int i = step * options.poses_per_step; i < end; ++i) {
      const int v = order[i];
      if (!graph.vertex(v).fixed && parent[v] != kNone)
        graph.vertex(v).value = propagate(graph, graph.pose_edges()[parent[v]], v);
    }
    for (const int v : points_joining[step])
      if (!graph.vertex(v).fixed) place(graph, graph.point_edges()[first[v]]);
    Graph part = part_of(graph, joins, step, full_index);
    // A lone first pose (and its prior): nothing relates it to anything yet.
    if (part.pose_edges().empty() && part.point_edges().empty()) continue;
    report.add_step(optimize(part, options.step, on_iteration));
    for (int j = 0; j < part.num_vertices(); ++j) graph.vertex(full_index[j]).value = part.vertex(j).value;
  }
  report.chi2 = graph.chi2();
  target.assign_values(graph.values());
  return report;
}

}  // namespace probslam::graph_detail
