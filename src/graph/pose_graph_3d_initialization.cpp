#include "probslam/graph/pose_graph_3d_initialization.hpp"

#include <algorithm>
#include <deque>

#include "probslam/core/check.hpp"
#include "probslam/graph/graph_optimizer.hpp"

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

// Places every free point not yet placed (placed[v] == 0) through its first edge, in the order
// added, from a pose already placed: p = x * offset * z.
void place_points(PoseGraph3D& graph, std::vector<char>& placed) {
  for (const Point3Edge& e : graph.point_edges()) {
    if (placed[e.point] || !placed[e.pose] || graph.vertex(e.point).fixed) continue;
    const Pose3& x = graph.vertex(e.pose).value;
    graph.vertex(e.point).value.translation =
        x.translation + x.rotation * (e.offset.translation + e.offset.rotation * e.measurement);
    placed[e.point] = 1;
  }
}

// The value of `other`, an end of edge e, composed from its other end's value.
Pose3 propagate(const PoseGraph3D& graph, const Pose3Edge& e, int other) {
  return other == e.to ? compose(graph.vertex(e.from).value, e.measurement)
                       : compose(graph.vertex(e.to).value, inverse(e.measurement));
}

// The first `count` vertices (indices kept) with the edges and priors among them.
PoseGraph3D prefix_of(const PoseGraph3D& graph, int count) {
  PoseGraph3D part;
  for (int v = 0; v < count; ++v) {
    part.add_pose(graph.vertex(v).id, graph.vertex(v).value);
    if (graph.vertex(v).fixed) part.set_fixed(graph.vertex(v).id);
  }
  for (const Pose3Edge& e : graph.pose_edges())
    if (e.from < count && e.to < count)
      part.add_pose_edge(graph.vertex(e.from).id, graph.vertex(e.to).id, e.measurement, e.information);
  for (const Pose3Prior& p : graph.pose_priors())
    if (p.vertex < count) part.add_pose_prior(graph.vertex(p.vertex).id, p.measurement, p.information);
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
  std::vector<std::vector<int>> incident(n);
  for (int k = 0; k < static_cast<int>(graph.pose_edges().size()); ++k) {
    incident[graph.pose_edges()[k].from].push_back(k);
    incident[graph.pose_edges()[k].to].push_back(k);
  }
  while (!queue.empty()) {
    const int v = queue.front();
    queue.pop_front();
    for (const int k : incident[v]) {
      const Pose3Edge& e = graph.pose_edges()[k];
      const int other = e.from == v ? e.to : e.from;
      if (reached[other]) continue;
      reached[other] = 1;
      graph.vertex(other).value = propagate(graph, e, other);
      queue.push_back(other);
    }
  }
  place_points(graph, reached);
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
  SparseCholesky cholesky(linear_solver);
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
  place_points(graph, placed);
  target.assign_values(graph.values());
}

IncrementalReport optimize_incremental(PoseGraph3D& target, const IncrementalOptions& options) {
  require(options.poses_per_step >= 1, "poses_per_step", "must be >= 1");
  require(target.num_vertices() > 0, "graph", "has no poses");
  require(target.num_points() == 0, "graph",
          "has point landmarks: incremental optimisation of a 3-D graph supports poses only; use optimize "
          "(after initialize_odometry or initialize_chordal)");
  PoseGraph3D graph = target;  // committed only when every step succeeded
  const int n = graph.num_vertices();
  // Each pose's seed: its first edge (in the order added) to an earlier pose.
  std::vector<int> parent(n, -1);
  for (int k = 0; k < static_cast<int>(graph.pose_edges().size()); ++k) {
    const Pose3Edge& e = graph.pose_edges()[k];
    const int later = std::max(e.from, e.to);
    if (parent[later] < 0) parent[later] = k;
  }
  IncrementalReport report;
  for (int start = 0; start < n; start += options.poses_per_step) {
    const int end = std::min(n, start + options.poses_per_step);
    for (int v = start; v < end; ++v)
      if (!graph.vertex(v).fixed && parent[v] >= 0)
        graph.vertex(v).value = propagate(graph, graph.pose_edges()[parent[v]], v);
    PoseGraph3D part = prefix_of(graph, end);
    if (part.pose_edges().empty() && part.pose_priors().empty()) continue;  // a lone first pose
    report.add_step(optimize(part, options.step));
    for (int v = 0; v < end; ++v) graph.vertex(v).value = part.vertex(v).value;
  }
  report.chi2 = graph.chi2();
  target.assign_values(graph.values());
  return report;
}

}  // namespace probslam
