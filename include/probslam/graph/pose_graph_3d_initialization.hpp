#pragma once
// Starting points for optimising a 3-D pose graph. Gauss-Newton from dead reckoning stalls in
// wrong minima on graphs with large rotational drift (sphere2500 with its noise, torus3D); the
// rotations are what makes the problem non-convex, and a convex relaxation of them alone
// (Carlone, Tron, Daniilidis and Dellaert, ICRA 2015, "chordal" initialisation) lands in the
// right basin.
#include "probslam/graph/graph_initialization.hpp"  // IncrementalOptions, IncrementalReport
#include "probslam/graph/pose_graph_3d.hpp"
#include "probslam/graph/sparse_cholesky.hpp"

namespace probslam {

/// Dead reckoning: every vertex reachable from the held ones (the fixed vertices, or the first
/// pose when none is fixed) gets the value of composing edges outward along a breadth-first
/// spanning tree, edges taken in the order they were added; then each free point is placed by its
/// first edge (in the order added) from a reached pose, p = x * offset * z. Unreached vertices
/// keep their values.
void initialize_odometry(PoseGraph3D& graph);

/// Chordal initialisation, in two linear solves on the sparse Cholesky path:
///  1. rotations: minimise sum over edges of kappa ||R_to - R_from R_z||_F^2 over unconstrained
///     3x3 matrices (the held vertices' rotations kept), kappa the mean diagonal entry of the
///     edge's rotational information; the three rows of the matrices are independent problems
///     with one normal matrix (3 unknowns per free vertex each, one factorisation); then each
///     matrix is projected onto SO(3) (nearest rotation, by SVD);
///  2. translations: with those rotations fixed the edges' translation errors are linear in the
///     translations; their information-weighted least squares is solved exactly (on the same
///     pattern, CHOLMOD's analysis reused).
/// Points take no part in the solves: afterwards each free point is placed by its first edge (in
/// the order added) from its pose, p = x * offset * z.
/// Noise-free edges give back the exact poses. Held vertices keep their values. Throws
/// std::invalid_argument, graph unchanged, for a graph with no edges or a part not connected to
/// a held vertex.
void initialize_chordal(PoseGraph3D& graph, const SparseCholeskyOptions& linear_solver = {});

/// Incremental batch optimisation, as for a PoseGraph2D (graph_initialization.hpp): poses join in
/// the order they were added, each composed from its first edge to an earlier pose; each point
/// joins with the earliest pose that sees it, placed by that pose's first edge to it (p = x *
/// offset * z); after every poses_per_step poses the graph of the vertices so far (their edges
/// and priors) is optimised with options.step. Throws std::invalid_argument, graph unchanged, as
/// optimize does.
IncrementalReport optimize_incremental(PoseGraph3D& graph, const IncrementalOptions& options = {});

}  // namespace probslam
