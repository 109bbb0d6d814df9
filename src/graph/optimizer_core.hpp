#pragma once
// Private to src/graph: the graph optimiser's iterations, gauge checks and marginals written
// once for every graph type (PoseGraph2D, PoseGraph3D). A graph type plugs in through
// GraphTraits<Graph>, specialised beside its linearisation:
//   Equations            normal equations built once per graph: system(), assemble(graph, kernel,
//                        width) -> Objective, apply(graph, dx) (the manifold update)
//   couplings(graph)     pairs of vertex indices sharing an edge
//   holdable(graph, v)   whether v may hold the gauge when nothing is fixed (a pose)
//   anchors(graph)       vertices a unary term (a prior) holds in place: they anchor their part of
//                        the graph as a fixed vertex does, and with any of them the first pose is
//                        not held (the prior, not the first pose, sets the gauge)
//   term_chi2(graph)     e^T Omega e of every term of the objective (edges and priors)
//   tangent_size(graph, v)
//   has_edges(graph)
// Vertices expose .id, .fixed and .value; graphs num_vertices(), vertex(v), vertices(),
// values() and assign_values().
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "probslam/core/check.hpp"
#include "probslam/graph/block_system.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/sparse_cholesky.hpp"

namespace probslam::graph_detail {

template <typename Graph>
struct GraphTraits;

// Levenberg-Marquardt's first damping: lambda0 = tau (Marquardt, D = diag(H)) or tau times H's
// largest diagonal entry (Levenberg, D = I), Madsen, Nielsen and Tingleff's tau. After a step
// with gain ratio rho > 0 (actual over predicted decrease) lambda *= max(1/3, 1 - (2 rho - 1)^3)
// and nu = 2; after a rejected one lambda *= nu, nu *= 2 (Nielsen's rule). A tiny tau lets the
// pose-graph steps, which Gauss-Newton takes well, through undamped: measured with Marquardt
// damping on Intel / M3500 / manhattanOlson3500, tau = 1e-8 takes 5 / 7 / 7 iterations (as
// Gauss-Newton), 1e-5 takes 9 / 14 / 14 and 1e-3 13 / 40 / 40. Rejected steps allowed in a row
// before giving up:
constexpr double kInitialDampingFactor = 1e-8;
constexpr double kMinDampingDecrease = 1.0 / 3.0;
constexpr double kInitialDampingIncrease = 2.0;
constexpr int kMaxRejectedSteps = 10;

struct RobustValue {
  double rho, weight;  // rho(s) and rho'(s)
};

inline RobustValue robust(double s, RobustKernel kernel, double width) {
  const double w2 = width * width;
  switch (kernel) {
    case RobustKernel::kHuber:
      if (s <= w2) return {s, 1.0};
      return {2.0 * width * std::sqrt(s) - w2, width / std::sqrt(s)};
    case RobustKernel::kCauchy:
      return {w2 * std::log1p(s / w2), 1.0 / (1.0 + s / w2)};
    case RobustKernel::kNone:
      break;
  }
  return {s, 1.0};
}

struct Objective {
  double robust = 0.0, chi2 = 0.0;
};

// Variable sizes for the solver: the tangent size per vertex, 0 for a fixed vertex (and for the
// first holdable vertex when nothing is fixed and nothing is anchored by a prior: the gauge).
template <typename Graph>
std::vector<int> variable_sizes(const Graph& graph) {
  using Traits = GraphTraits<Graph>;
  std::vector<int> sizes(graph.num_vertices());
  bool any_held = !Traits::anchors(graph).empty();  // a prior holds the gauge
  int first_pose = -1;
  for (int v = 0; v < graph.num_vertices(); ++v) {
    const bool fixed = graph.vertex(v).fixed;
    sizes[v] = fixed ? 0 : Traits::tangent_size(graph, v);
    any_held = any_held || fixed;
    if (first_pose < 0 && Traits::holdable(graph, v)) first_pose = v;
  }
  if (!any_held && first_pose >= 0) sizes[first_pose] = 0;
  return sizes;
}

// The shared half of every graph's normal equations: the block system and the addition of one
// edge's weighted J^T Omega J and J^T Omega e.
class EdgeAssembler {
 public:
  EdgeAssembler(std::vector<int> sizes, const std::vector<std::pair<int, int>>& couplings)
      : system_(std::move(sizes), couplings) {}
  BlockSystem& system() { return system_; }
  const BlockSystem& system() const { return system_; }

  std::array<BlockHandle, 3> handles(int a, int b) const {
    return {system_.block(a, a), system_.block(b, b), system_.block(a, b)};
  }

  // One edge between variables a and b (error e, Jacobians ja and jb, information omega) added
  // to H and b with its robust weight; the edge's chi2 and kernel value added to `total`.
  template <int E, int A, int B>
  void add_edge(const std::array<BlockHandle, 3>& h, int a, int b, const Eigen::Matrix<double, E, 1>& error,
                const Eigen::Matrix<double, E, A>& ja, const Eigen::Matrix<double, E, B>& jb,
                const Eigen::Matrix<double, E, E>& information, RobustKernel kernel, double width,
                Objective& total) {
    const Eigen::Matrix<double, E, 1> we = information * error;
    const double s = error.dot(we);
    const RobustValue r = robust(s, kernel, width);
    total.robust += r.rho;
    total.chi2 += s;
    const Eigen::Matrix<double, E, E> omega = r.weight * information;
    const Eigen::Matrix<double, A, E> a_t_omega = ja.transpose() * omega;
    // Evaluated into fixed-size blocks first: a product expression bound to add()'s Ref would be
    // evaluated into a heap-allocated temporary, three per edge and iteration.
    const Eigen::Matrix<double, A, A> haa = a_t_omega * ja;
    const Eigen::Matrix<double, B, B> hbb = jb.transpose() * omega * jb;
    const Eigen::Matrix<double, A, B> hab = a_t_omega * jb;
    system_.add(h[0], haa);
    system_.add(h[1], hbb);
    system_.add(h[2], hab);
    const Eigen::Matrix<double, A, 1> ba = -r.weight * (ja.transpose() * we);
    const Eigen::Matrix<double, B, 1> bb = -r.weight * (jb.transpose() * we);
    system_.add_rhs(a, ba);
    system_.add_rhs(b, bb);
  }

  // A unary term (a prior) on variable a, as add_edge with one end; `h` is block(a, a).
  template <int E, int A>
  void add_unary(BlockHandle h, int a, const Eigen::Matrix<double, E, 1>& error, const Eigen::Matrix<double, E, A>& ja,
                 const Eigen::Matrix<double, E, E>& information, RobustKernel kernel, double width, Objective& total) {
    const Eigen::Matrix<double, E, 1> we = information * error;
    const double s = error.dot(we);
    const RobustValue r = robust(s, kernel, width);
    total.robust += r.rho;
    total.chi2 += s;
    const Eigen::Matrix<double, A, E> a_t_omega = r.weight * (ja.transpose() * information);
    const Eigen::Matrix<double, A, A> haa = a_t_omega * ja;  // fixed-size, as in add_edge
    const Eigen::Matrix<double, A, 1> ba = -r.weight * (ja.transpose() * we);
    system_.add(h, haa);
    system_.add_rhs(a, ba);
  }

 private:
  BlockSystem system_;
};

template <typename Graph>
Objective evaluate(const Graph& graph, RobustKernel kernel, double width) {
  Objective total;
  for (const double s : GraphTraits<Graph>::term_chi2(graph)) {
    total.robust += robust(s, kernel, width).rho;
    total.chi2 += s;
  }
  return total;
}

template <typename Graph>
void validate(const Graph& graph, const OptimizerOptions& options) {
  require(graph.num_vertices() > 0, "graph", "has no vertices");
  require(GraphTraits<Graph>::has_edges(graph), "graph", "has no edges");
  options.check_ranges();
}

// Floating vertices listed by name in the error; the rest are counted.
constexpr size_t kListedVertices = 20;

inline int find_root(std::vector<int>& parent, int v) {
  while (parent[v] != v) v = parent[v] = parent[parent[v]];
  return v;
}

// Gauge freedom is a property of the graph's structure, decided before any number is computed:
// every connected component must hold a fixed vertex (or, when none is fixed anywhere, the first
// pose, which the optimiser holds). A component that holds none can move rigidly without
// changing the objective: its information is singular whatever the numbers, so it is refused by
// name, for Gauss-Newton and Levenberg-Marquardt alike (damping would hide it).
template <typename Graph>
void require_anchored(const Graph& graph) {
  using Traits = GraphTraits<Graph>;
  const int n = graph.num_vertices();
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  for (const auto& [a, b] : Traits::couplings(graph)) parent[find_root(parent, a)] = find_root(parent, b);
  std::vector<char> anchored(n, 0);
  bool any_fixed = false;
  for (int v = 0; v < n; ++v)
    if (graph.vertex(v).fixed) anchored[find_root(parent, v)] = any_fixed = true;
  for (const int v : Traits::anchors(graph)) anchored[find_root(parent, v)] = any_fixed = true;
  for (int v = 0; v < n && !any_fixed; ++v)
    if (Traits::holdable(graph, v)) {
      anchored[find_root(parent, v)] = any_fixed = true;
    }
  int floating_root = -1, others = 0;
  std::vector<int> ids;
  std::vector<char> counted(n, 0);
  for (int v = 0; v < n; ++v) {
    const int root = find_root(parent, v);
    if (anchored[root]) continue;
    if (floating_root < 0) floating_root = root;
    if (root == floating_root) {
      ids.push_back(graph.vertex(v).id);
    } else if (!counted[root]) {
      counted[root] = 1;
      ++others;
    }
  }
  if (floating_root < 0) return;
  std::string names;
  for (size_t k = 0; k < ids.size() && k < kListedVertices; ++k) names += (k ? ", " : "") + std::to_string(ids[k]);
  if (ids.size() > kListedVertices) names += " and " + std::to_string(ids.size() - kListedVertices) + " more";
  throw_invalid_argument(
      "graph", "vertices " + names + " form a part of the graph not connected to a fixed vertex or a prior " +
                   "(nor to the first pose, held when there are none): its information matrix is singular; fix one " +
                   "of its vertices or connect it" +
                   (others ? " (" + std::to_string(others) + " more such parts)" : ""));
}

// Rethrows a failed factorisation naming the vertex whose variable it failed at.
template <typename Graph>
[[noreturn]] void throw_singular(const Graph& graph, const BlockSystem& system, const SparseCholesky& chol,
                                 const std::invalid_argument& error) {
  const int column = chol.singular_column();
  for (int v = 0; column >= 0 && v < graph.num_vertices(); ++v)
    if (system.size(v) > 0 && column >= system.offset(v) && column < system.offset(v) + system.size(v))
      throw_invalid_argument("graph", "information matrix is singular to working precision at vertex " +
                                          std::to_string(graph.vertex(v).id) +
                                          " (constrained in fewer directions than it has, or tied so " +
                                          "rigidly to another that their common motion is lost in rounding)");
  throw error;
}

template <typename Graph>
void factorize(SparseCholesky& chol, const Graph& graph, const BlockSystem& system) {
  try {
    chol.factorize(system.upper());
  } catch (const std::invalid_argument& error) {
    throw_singular(graph, system, chol, error);
  }
}

inline void require_finite_objective(const Objective& o, const char* when) {
  if (!std::isfinite(o.chi2) || !std::isfinite(o.robust))
    throw_invalid_argument("graph", std::string("chi2 is not finite ") + when +
                                        " (values or information too large?)");
}

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The iterations, on a graph the caller may throw away (optimize_graph() passes a copy).
template <typename Graph>
OptimizationReport optimize_in_place(Graph& graph, const OptimizerOptions& options,
                                     const IterationCallback& on_iteration) {
  typename GraphTraits<Graph>::Equations equations(graph);
  OptimizationReport report;
  if (equations.system().dim() == 0) {
    const Objective fixed = evaluate(graph, options.kernel, options.kernel_width);
    report.initial_chi2 = report.chi2 = fixed.chi2;
    report.objective = fixed.robust;
    report.converged = true;
    report.stop_reason = "nothing to optimise: every vertex is fixed";
    return report;
  }
  SparseCholesky cholesky(options.linear_solver.resolved(GraphTraits<Graph>::kDefaultOrdering));
  const RobustKernel kernel = options.kernel;
  const double width = options.kernel_width;
  Objective current = equations.assemble(graph, kernel, width);
  require_finite_objective(current, "at the initial values");
  report.initial_chi2 = current.chi2;
  report.stop_reason = "maximum iterations reached";
  const bool levenberg = options.algorithm == OptimizerAlgorithm::kLevenbergMarquardt;
  const bool marquardt = options.damping == Damping::kMarquardt;
  double lambda = kInitialDampingFactor, nu = kInitialDampingIncrease;
  if (levenberg && !marquardt) lambda *= equations.system().diagonal().maxCoeff();

  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const auto start = Clock::now();
    BlockSystem& system = equations.system();
    Eigen::VectorXd dx;
    Objective next;
    if (!levenberg) {
      factorize(cholesky, graph, system);
      dx = cholesky.solve(system.rhs());
      require(dx.allFinite(), "graph", "Gauss-Newton step is not finite (values or information too large?)");
      equations.apply(graph, dx);
      next = equations.assemble(graph, kernel, width);
      require_finite_objective(next, "after a Gauss-Newton step");
    } else {
      const auto saved = graph.vertices();
      bool accepted = false;
      for (int attempt = 0; attempt < kMaxRejectedSteps && !accepted; ++attempt) {
        const Eigen::VectorXd scale =
            marquardt ? system.diagonal() : Eigen::VectorXd::Ones(system.dim());
        const Eigen::VectorXd damping = lambda * scale;
        system.add_to_diagonal(damping);
        try {
          factorize(cholesky, graph, system);
        } catch (...) {
          system.add_to_diagonal(-damping);
          throw;
        }
        system.add_to_diagonal(-damping);
        dx = cholesky.solve(system.rhs());
        equations.apply(graph, dx);
        next = evaluate(graph, kernel, width);
        // The quadratic model's decrease 2 b^T dx - dx^T H dx, with (H + lambda D) dx = b.
        const double predicted = system.rhs().dot(dx) + dx.dot(damping.cwiseProduct(dx));
        const double rho = (current.robust - next.robust) / predicted;
        if (predicted > 0.0 && rho > 0.0 && dx.allFinite()) {
          accepted = true;
          lambda *= std::max(kMinDampingDecrease, 1.0 - std::pow(2.0 * rho - 1.0, 3));
          nu = kInitialDampingIncrease;
        } else {
          for (int v = 0; v < graph.num_vertices(); ++v) graph.vertex(v).value = saved[v].value;
          lambda *= nu;
          nu *= 2.0;
        }
      }
      if (!accepted) {
        report.converged = true;  // no step lowers the objective: a minimum to working precision
        report.stop_reason = "no step lowers the objective";
        break;
      }
      next = equations.assemble(graph, kernel, width);
      require_finite_objective(next, "after a Levenberg-Marquardt step");
    }
    report.iteration_seconds.push_back(seconds_since(start));
    report.chi2_history.push_back(next.chi2);
    report.iterations = iteration + 1;
    const double decrease = current.robust - next.robust;
    current = next;
    if (on_iteration && !on_iteration(report.iterations, current.chi2)) {
      report.stop_reason = "stopped by the callback";
      break;
    }
    if (dx.lpNorm<Eigen::Infinity>() < options.step_tolerance) {
      report.converged = true;
      report.stop_reason = "step below step_tolerance";
      break;
    }
    if (std::abs(decrease) <= options.relative_tolerance * current.robust) {
      report.converged = true;
      report.stop_reason = "objective change below relative_tolerance";
      break;
    }
  }
  report.chi2 = current.chi2;
  report.objective = current.robust;
  report.factor_nonzeros = cholesky.factor_nonzeros();
  return report;
}

// optimize() for any graph: checks, then iterations on a copy committed only when finite.
template <typename Graph>
OptimizationReport optimize_graph(Graph& graph, const OptimizerOptions& options,
                                  const IterationCallback& on_iteration) {
  validate(graph, options);
  require_anchored(graph);
  Graph work = graph;  // the graph changes only when a finite result is committed
  OptimizationReport report;
  if (!on_iteration) {
    report = optimize_in_place(work, options, on_iteration);
  } else {
    // The callback sees the graph at the iteration just completed (its values are finite): a
    // progress plot may read it. An exception from the callback keeps those values, as a callback
    // returning false does; any other failure (singular system, non-finite step) comes before the
    // callback is reached and puts the values back as they were before the call.
    const auto before = graph.values();
    bool in_callback = false;
    const IterationCallback guarded = [&](int iteration, double chi2) {
      graph.assign_values(work.values());
      in_callback = true;
      const bool go_on = on_iteration(iteration, chi2);
      in_callback = false;
      return go_on;
    };
    try {
      report = optimize_in_place(work, options, guarded);
    } catch (...) {
      if (!in_callback) graph.assign_values(before);
      throw;
    }
  }
  require(std::isfinite(report.chi2) && std::isfinite(report.objective), "graph",
          "chi2 is not finite at the result (values or information too large?)");
  graph.assign_values(work.values());
  return report;
}

// joint_marginal_covariances() for any graph.
template <typename Graph>
std::vector<Eigen::MatrixXd> joint_marginals(const Graph& graph, const std::vector<std::vector<int>>& groups,
                                             const SparseCholeskyOptions& linear_solver) {
  using Traits = GraphTraits<Graph>;
  for (size_t g = 0; g < groups.size(); ++g) {  // unknown or repeated ids first, before any work
    for (size_t a = 0; a < groups[g].size(); ++a) {
      graph.index_of(groups[g][a]);
      for (size_t b = 0; b < a; ++b)
        if (groups[g][b] == groups[g][a])
          throw_invalid_argument("groups", "group " + std::to_string(g) + " names vertex " +
                                               std::to_string(groups[g][a]) + " twice");
    }
  }
  validate(graph, {});
  require_anchored(graph);
  typename Traits::Equations equations(graph);
  require_finite_objective(equations.assemble(graph, RobustKernel::kNone, 1.0), "at the current values");
  const BlockSystem& system = equations.system();
  // One request per pair of free members (upper blocks only: the inverse is symmetric).
  std::vector<InverseBlock> requests;
  for (const std::vector<int>& group : groups)
    for (size_t a = 0; a < group.size(); ++a)
      for (size_t b = a; b < group.size(); ++b) {
        const int va = graph.index_of(group[a]), vb = graph.index_of(group[b]);
        if (system.size(va) > 0 && system.size(vb) > 0)
          requests.push_back({system.offset(va), system.size(va), system.offset(vb), system.size(vb)});
      }
  std::vector<Eigen::MatrixXd> blocks;
  if (!requests.empty()) {
    SparseCholesky cholesky(linear_solver.resolved(GraphTraits<Graph>::kDefaultOrdering));
    factorize(cholesky, graph, system);
    blocks = cholesky.inverse_blocks(requests);
  }
  for (const Eigen::MatrixXd& b : blocks)
    require(b.allFinite(), "graph", "marginal covariances are not finite (information too small or too large?)");
  std::vector<Eigen::MatrixXd> out;
  out.reserve(groups.size());
  size_t next = 0;
  for (const std::vector<int>& group : groups) {
    std::vector<int> start(group.size() + 1, 0);  // each member's first row in the group's matrix
    for (size_t a = 0; a < group.size(); ++a)
      start[a + 1] = start[a] + Traits::tangent_size(graph, graph.index_of(group[a]));
    Eigen::MatrixXd joint = Eigen::MatrixXd::Zero(start.back(), start.back());
    for (size_t a = 0; a < group.size(); ++a)
      for (size_t b = a; b < group.size(); ++b) {
        if (system.size(graph.index_of(group[a])) == 0 || system.size(graph.index_of(group[b])) == 0) continue;
        const Eigen::MatrixXd& block = blocks[next++];
        joint.block(start[a], start[b], block.rows(), block.cols()) = block;
        if (b != a) joint.block(start[b], start[a], block.cols(), block.rows()) = block.transpose();
      }
    out.push_back(std::move(joint));
  }
  return out;
}

template <typename Graph>
std::vector<Eigen::MatrixXd> marginals(const Graph& graph, const std::vector<int>& ids,
                                       const SparseCholeskyOptions& linear_solver) {
  std::vector<std::vector<int>> groups;
  groups.reserve(ids.size());
  for (const int id : ids) groups.push_back({id});
  return joint_marginals(graph, groups, linear_solver);
}

}  // namespace probslam::graph_detail
