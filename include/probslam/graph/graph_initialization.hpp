#pragma once
// Starting points for the batch optimiser (ch. 11.3): a graph whose landmarks close loops far
// from where dead reckoning puts them (Victoria Park) has wrong local minima that Gauss-Newton
// and Levenberg-Marquardt started from odometry fall into. Two remedies live here: re-seeding
// from the edges alone (dead reckoning), and growing the graph pose by pose so that each
// optimisation starts near its optimum. (Seeding from an EKF SLAM run is done in Python, where
// the filter is driven; see probslam.graph.initialize.)
#include <functional>
#include <vector>

#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/graph/pose_graph_2d.hpp"

namespace probslam {

/// Dead reckoning: every free vertex reachable from the held ones (the fixed vertices, or the
/// first pose when none is fixed) gets the value of composing pose edges outward along a
/// breadth-first spanning tree, edges taken in the order they were added; a point is placed by
/// its first edge from a reached pose. For a chain of odometry edges this is the integrated
/// odometry. Unreached vertices keep their values.
void initialize_odometry(PoseGraph2D& graph);

struct IncrementalOptions {
  /// Poses added (in the order they were added to the graph) between two optimisations.
  int poses_per_step = 100;
  /// Each step's optimisation of the graph so far (default_step()).
  OptimizerOptions step = default_step();
  /// Called before each step and after each of its iterations; a caller that wants to stop a
  /// long run (the bindings, on Ctrl-C) makes it throw, and the exception leaves the call with
  /// the graph unchanged. Empty: never called.
  std::function<void()> interrupt;

  /// From a warm start (the last step's result) few iterations and a loose tolerance suffice:
  /// 10 iterations at most, stop below a relative decrease of 1e-6.
  static OptimizerOptions default_step();
  /// std::invalid_argument naming the first bad field by its path: poses_per_step >= 1, then
  /// step's fields as optimize() checks them ("step.max_iterations must be >= 0").
  void validate() const;
  template <class V>
  static void describe(V& v) {
    v("poses_per_step", &IncrementalOptions::poses_per_step, "", "poses added between two optimisations, >= 1");
    v("step", &IncrementalOptions::step, "", "each step's optimisation of the graph so far");
  }
};

struct IncrementalReport {
  int steps = 0;
  int iterations = 0;            ///< summed over the steps
  double chi2 = 0.0;             ///< of the whole graph at the end
  std::vector<double> step_chi2; ///< of the optimised part after each step

  /// Counts one step's optimisation.
  void add_step(const OptimizationReport& step) {
    ++steps;
    iterations += step.iterations;
    step_chi2.push_back(step.chi2);
  }
};

/// Incremental batch optimisation: poses join in the order they were added, each new pose
/// composed from its first edge to an earlier pose at that pose's current estimate, each point
/// from its first observation; after every `poses_per_step` poses the part of the graph seen
/// so far (the vertices that joined and the edges between them) is optimised from where the
/// last step left it. The last step optimises the whole graph, so the result is a local
/// minimum of the full problem reached along a path that keeps every step in its basin.
/// Throws std::invalid_argument for a bad option or an optimisation that fails (a part of the
/// graph not connected to the held vertices).
IncrementalReport optimize_incremental(PoseGraph2D& graph, const IncrementalOptions& options = {});

}  // namespace probslam
