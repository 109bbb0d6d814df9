#pragma once
// A 3-D pose graph file straight to the optimiser's PoseGraph3D and back: the bridge between the
// neutral PoseGraph3DData of pose_graph_file_3d.hpp and the graph, in C++ so that a file of
// 10^5 edges is not walked element by element in Python.
#include <string>

#include "probslam/graph/pose_graph_3d.hpp"
#include "probslam/io/pose_graph_file_3d.hpp"

namespace probslam {

/// The graph of a file's data: vertices in data order, then points (FIX flags kept), edges, point
/// edges, and priors as
/// PoseGraph3D priors (g2o's EDGE_SE3_PRIOR, read with the graph's rotation-vector convention as
/// its edges are). Throws std::invalid_argument (nothing built) for data a reader would refuse:
/// a repeated vertex id, an edge or prior naming an unknown vertex, a non-unit quaternion,
/// information that is not symmetric positive definite.
PoseGraph3D pose_graph_3d_from_data(const PoseGraph3DData& data);

/// The data of a graph at its current values (for write_g2o_3d): poses and points each in index
/// order with their fixed flags, edges, priors and point edges with their ends' ids.
PoseGraph3DData pose_graph_3d_data(const PoseGraph3D& graph);

struct PoseGraph3DFileRead {
  PoseGraph3D graph;
  PoseGraphReadReport report;
};

/// read_pose_graph_3d (formats, options and errors as there) and pose_graph_3d_from_data.
PoseGraph3DFileRead read_pose_graph_3d_graph(const std::string& path, const PoseGraphReadOptions& options = {});

/// Writes the graph at its current values as g2o text (write_g2o_3d of pose_graph_3d_data).
void write_g2o_3d(const std::string& path, const PoseGraph3D& graph);

}  // namespace probslam
