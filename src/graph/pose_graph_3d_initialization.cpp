#include "probslam/graph/pose_graph_3d_initialization.hpp"

#include <algorithm>
#include <deque>

#include "probslam/core/check.hpp"
#include "probslam/graph/graph_optimizer.hpp"

#include "graph_growth.hpp"
#include "pose_graph_3d_traits.hpp"

namespace probslam {
namespace {

Pose3 compose(const Pose3& a, const Pose3& b) {
  return {(a.rotation * b.rotation).normalized(), a.translation + a.rotation * b.translation};
}

Pose3 inverse(const Pose3& a) {
  const Eigen::Quaterniond r = a.rotation.conjugate();
  return {r, -(r * a.translation)};
}

using graph_detail::joined;

bool is_point(const PoseGraph3D& graph, int v) { return graph.vertex(v).kind == VertexKind::kPoint; }

// The vertices held when nothing else is: the fixed ones, or the first pose when none is fixed
// (the optimiser's gauge, optimizer_core.hpp's variable_sizes).
std::vector<char> held_vertices(const PoseGraph3D& graph) {
  std::vector<char> held(graph.num_vertices(), 0);
  bool any = false;
  for (int v = 0; v < graph.num_vertices(); ++v) any = (held[v] = graph.vertex(v).fixed) || any;
  for (int v = 0; v < graph.num_vertices() && !any; ++v)
    if (!is_point(graph, v)) {
      held[v] = 1;
      any = true;
    }
  return held;
}

// p = x * offset * z: the point of edge `e` where its pose's sensor sees it.
void place_point(PoseGraph3D& graph, const Point3Edge& e) {
  const Pose3& x = graph.vertex(e.pose).value;
  graph.vertex(e.point).value.translation =
      x.translation + x.rotation * (e.offset.translation + e.offset.rotation * e.measurement);
}

// The value of `other`, an end of edge e, composed from its other end's value.
Pose3 propagate(const PoseGraph3D& graph, const Pose3Edge& e, int other) {
  return other == e.to ? compose(graph.vertex(e.from).value, e.measurement)
                       : compose(graph.vertex(e.to).value, inverse(e.measurement));
}

// The vertices that joined by `step` (joins[v] <= step) with the edges and priors among them, the
// fixed vertices fixed; `full_index` maps the part's vertex indices to the graph's.
PoseGraph3D part_of(const PoseGraph3D& graph, const std::vector<int>& joins, int step, std::vector<int>& full_index) {
  PoseGraph3D part;
  full_index.clear();
  auto active = [&](int v) { return joined(joins, v, step); };
  for (int v = 0; v < graph.num_vertices(); ++v) {
    if (!active(v)) continue;
    const Pose3Vertex& vertex = graph.vertex(v);
    if (vertex.kind == VertexKind::kPoint)
      part.add_point(vertex.id, vertex.value.translation);
    else
      part.add_pose(vertex.id, vertex.value);
    if (vertex.fixed) part.set_fixed(vertex.id);
    full_index.push_back(v);
  }
  for (const Pose3Edge& e : graph.pose_edges())
    if (active(e.from) && active(e.to))
      part.add_pose_edge(graph.vertex(e.from).id, graph.vertex(e.to).id, e.measurement, e.information);
  for (const Pose3Prior& p : graph.pose_priors())
    if (active(p.vertex)) part.add_pose_prior(graph.vertex(p.vertex).id, p.measurement, p.information);
  for (const Point3Edge& e : graph.point_edges())
    if (active(e.pose) && active(e.point))
      part.add_point_edge(graph.vertex(e.pose).id, graph.vertex(e.point).id, e.measurement, e.information, e.offset);
  return part;
}

}  // namespace

void initialize_odometry(PoseGraph3D& target) {
  PoseGraph3D graph = target;  // committed only when every value is finite
  const int n = graph.num_vertices();
  std::vector<char> reached = held_vertices(graph);
  std::deque<int> queue;
  for (int v = 0; v < n; ++v)
    if (reached[v]) queue.push_back(v);
  graph_detail::spread_along_pose_edges(graph, reached, std::move(queue), propagate);
  graph_detail::place_points(graph, reached, place_point);
  target.assign_values(graph.values());
}

void initialize_chordal(PoseGraph3D& target, const SparseCholeskyOptions& linear_solver) {
  using graph_detail::EdgeAssembler;
  using graph_detail::Objective;
  require(target.num_vertices() > 0, "graph", "has no vertices");
  require(!target.pose_edges().empty(), "graph", "has no pose edges");
  graph_detail::require_anchored(target);
  PoseGraph3D graph = target;  // committed only when every value is finite
  const int n = graph.num_vertices();
  const std::vector<char> held_or_fixed = held_vertices(graph);
  // Points take no part in the two solves (they have no rotation, and are placed from their
  // poses at the end): to the solves they are held, outside the system.
  std::vector<char> held = held_or_fixed;
  for (int v = 0; v < n; ++v) held[v] = held[v] || is_point(graph, v);
  const auto& edges = graph.pose_edges();
  std::vector<std::pair<int, int>> couplings;
  for (const Pose3Edge& e : edges) couplings.emplace_back(e.from, e.to);
  auto sizes = [&](int size) {
    std::vector<int> out(n);
    for (int v = 0; v < n; ++v) out[v] = held[v] ? 0 : size;
    return out;
  };
  Objective unused;

  // 1. Rotations. R_to = R_from R_z row by row: row a of R_to is row a of R_from times R_z, so
  // with rho_a(v) row a of R_v as a column vector the residual
  // rho_a(to) - R_z^T rho_a(from) is linear, and the three rows a are three independent problems
  // with one matrix (3x3 blocks, not the 9x9 of vec(R): a 27th of the factorisation's work).
  // Each is posed at rho = 0 for the free vertices (their stored rotations are not used), so
  // that the Gauss-Newton step is the solution.
  EdgeAssembler system(sizes(3), couplings);
  SparseCholesky cholesky(linear_solver.resolved(graph_detail::GraphTraits<PoseGraph3D>::kDefaultOrdering));
  std::vector<Eigen::Matrix3d> rotation(n, Eigen::Matrix3d::Zero());
  for (int v = 0; v < n; ++v)
    if (held[v]) rotation[v] = graph.vertex(v).value.rotation.toRotationMatrix();
  std::vector<Eigen::Matrix3d> solved(n, Eigen::Matrix3d::Zero());
  for (int a = 0; a < 3; ++a) {
    system.system().set_zero();
    for (const Pose3Edge& e : edges) {
      const Eigen::Matrix3d rz_t = e.measurement.rotation.conjugate().toRotationMatrix();
      const Eigen::Matrix3d d_from = -rz_t, d_to = Eigen::Matrix3d::Identity();
      const Eigen::Vector3d residual =
          d_from * rotation[e.from].row(a).transpose() + rotation[e.to].row(a).transpose();
      const double kappa = e.information.bottomRightCorner<3, 3>().trace() / 3.0;
      system.add_edge(system.handles(e.from, e.to), e.from, e.to, residual, d_from, d_to,
                      Eigen::Matrix3d(kappa * Eigen::Matrix3d::Identity()), RobustKernel::kNone, 1.0, unused);
    }
    if (a == 0) graph_detail::factorize(cholesky, graph, system.system());
    const Eigen::VectorXd rows = cholesky.solve(system.system().rhs());
    require(rows.allFinite(), "graph", "chordal initialisation is not finite (information too large?)");
    for (int v = 0; v < n; ++v)
      if (!held[v]) solved[v].row(a) = rows.segment<3>(system.system().offset(v)).transpose();
  }
  for (int v = 0; v < n; ++v)
    if (!held[v]) graph.vertex(v).value.rotation = Eigen::Quaterniond(project_to_rotation(solved[v])).normalized();

  // 2. Translations, rotations fixed: e_t = R_z^T (R_from^T (t_to - t_from) - t_z) is linear in
  // the translations; posed at t = 0 for the free vertices as above.
  EdgeAssembler& translations = system;  // the same pattern: CHOLMOD's analysis is reused
  translations.system().set_zero();
  auto position = [&](int v) -> Eigen::Vector3d {
    return held[v] ? graph.vertex(v).value.translation : Eigen::Vector3d::Zero();
  };
  for (const Pose3Edge& e : edges) {
    const Eigen::Matrix3d a = e.measurement.rotation.conjugate().toRotationMatrix() *
                              graph.vertex(e.from).value.rotation.conjugate().toRotationMatrix();
    const Eigen::Matrix3d d_from = -a, d_to = a;
    const Eigen::Vector3d residual =
        a * (position(e.to) - position(e.from)) - e.measurement.rotation.conjugate() * e.measurement.translation;
    const Eigen::Matrix3d omega = e.information.topLeftCorner<3, 3>();
    translations.add_edge(translations.handles(e.from, e.to), e.from, e.to, residual, d_from, d_to, omega,
                          RobustKernel::kNone, 1.0, unused);
  }
  graph_detail::factorize(cholesky, graph, translations.system());
  const Eigen::VectorXd t = cholesky.solve(translations.system().rhs());
  require(t.allFinite(), "graph", "chordal initialisation is not finite (information too large?)");
  for (int v = 0; v < n; ++v)
    if (!held[v]) graph.vertex(v).value.translation = t.segment<3>(translations.system().offset(v));
  std::vector<char> placed(n, 1);  // every pose is placed now; the free points are not
  for (int v = 0; v < n; ++v)
    if (is_point(graph, v) && !held_or_fixed[v]) placed[v] = 0;
  graph_detail::place_points(graph, placed, place_point);
  target.assign_values(graph.values());
}

IncrementalReport optimize_incremental(PoseGraph3D& target, const IncrementalOptions& options) {
  return graph_detail::optimize_incremental_graph(target, options, propagate, place_point, part_of);
}

}  // namespace probslam
