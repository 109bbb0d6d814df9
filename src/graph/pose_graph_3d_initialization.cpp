#include "probslam/graph/pose_graph_3d_initialization.hpp"

#include <deque>

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

// The vertices held when nothing else is: the fixed ones, or the first when none is fixed.
std::vector<char> held_vertices(const PoseGraph3D& graph) {
  std::vector<char> held(graph.num_vertices(), 0);
  bool any = false;
  for (int v = 0; v < graph.num_vertices(); ++v) any = (held[v] = graph.vertex(v).fixed) || any;
  if (!any && graph.num_vertices() > 0) held[0] = 1;
  return held;
}

// Solves the normal equations of `assembler` (a linear least-squares problem posed at zero for
// the free variables, so that its Gauss-Newton step is the solution).
Eigen::VectorXd solve_linear(const PoseGraph3D& graph, graph_detail::EdgeAssembler& assembler,
                             const SparseCholeskyOptions& linear_solver) {
  SparseCholesky cholesky(linear_solver);
  graph_detail::factorize(cholesky, graph, assembler.system());
  const Eigen::VectorXd x = cholesky.solve(assembler.system().rhs());
  require(x.allFinite(), "graph", "chordal initialisation is not finite (information too large?)");
  return x;
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
      graph.vertex(other).value = other == e.to ? compose(graph.vertex(v).value, e.measurement)
                                                : compose(graph.vertex(v).value, inverse(e.measurement));
      queue.push_back(other);
    }
  }
  target.assign_values(graph.values());
}

void initialize_chordal(PoseGraph3D& target, const SparseCholeskyOptions& linear_solver) {
  using graph_detail::EdgeAssembler;
  using graph_detail::Objective;
  require(target.num_vertices() > 0, "graph", "has no vertices");
  require(!target.pose_edges().empty(), "graph", "has no edges");
  graph_detail::require_anchored(target);
  PoseGraph3D graph = target;  // committed only when every value is finite
  const int n = graph.num_vertices();
  const std::vector<char> held = held_vertices(graph);
  const auto& edges = graph.pose_edges();
  std::vector<std::pair<int, int>> couplings;
  for (const Pose3Edge& e : edges) couplings.emplace_back(e.from, e.to);
  auto sizes = [&](int size) {
    std::vector<int> out(n);
    for (int v = 0; v < n; ++v) out[v] = held[v] ? 0 : size;
    return out;
  };
  Objective unused;

  // 1. Rotations. With r = vec(R) (column-major), vec(R_from R_z) = (R_z^T kron I3) r_from: the
  // residual r_to - (R_z^T kron I3) r_from is linear. It is posed at r = 0 for the free vertices
  // (their stored rotations are not used), so that the Gauss-Newton step is the solution.
  EdgeAssembler rotations(sizes(9), couplings);
  using Vector9d = Eigen::Matrix<double, 9, 1>;
  using Matrix9d = Eigen::Matrix<double, 9, 9>;
  auto vec = [&](int v) -> Vector9d {
    if (!held[v]) return Vector9d::Zero();
    const Eigen::Matrix3d r = graph.vertex(v).value.rotation.toRotationMatrix();
    return Eigen::Map<const Vector9d>(r.data());
  };
  for (const Pose3Edge& e : edges) {
    const Eigen::Matrix3d rz = e.measurement.rotation.toRotationMatrix();
    Matrix9d d_from = Matrix9d::Zero();
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) d_from.block<3, 3>(3 * c, 3 * k) = -rz(k, c) * Eigen::Matrix3d::Identity();
    const Matrix9d d_to = Matrix9d::Identity();
    const Vector9d residual = d_from * vec(e.from) + d_to * vec(e.to);
    const double kappa = e.information.bottomRightCorner<3, 3>().trace() / 3.0;
    rotations.add_edge(rotations.handles(e.from, e.to), e.from, e.to, residual, d_from, d_to,
                       Matrix9d(kappa * Matrix9d::Identity()), RobustKernel::kNone, 1.0, unused);
  }
  const Eigen::VectorXd r = solve_linear(graph, rotations, linear_solver);
  for (int v = 0; v < n; ++v) {
    if (held[v]) continue;
    const Eigen::Matrix3d m = Eigen::Map<const Eigen::Matrix3d>(r.data() + rotations.system().offset(v));
    graph.vertex(v).value.rotation = Eigen::Quaterniond(project_to_rotation(m)).normalized();
  }

  // 2. Translations, rotations fixed: e_t = R_z^T (R_from^T (t_to - t_from) - t_z) is linear in
  // the translations; posed at t = 0 for the free vertices as above.
  EdgeAssembler translations(sizes(3), couplings);
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
  const Eigen::VectorXd t = solve_linear(graph, translations, linear_solver);
  for (int v = 0; v < n; ++v)
    if (!held[v]) graph.vertex(v).value.translation = t.segment<3>(translations.system().offset(v));
  target.assign_values(graph.values());
}

}  // namespace probslam
