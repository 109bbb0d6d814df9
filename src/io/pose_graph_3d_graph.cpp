#include "probslam/io/pose_graph_3d_graph.hpp"

#include <utility>

namespace probslam {

PoseGraph3D pose_graph_3d_from_data(const PoseGraph3DData& data) {
  PoseGraph3D graph;  // a local: on a throw the caller gets nothing, all or nothing for free
  for (const Vertex3D& v : data.vertices) {
    graph.add_pose(v.id, {v.q, v.t});
    if (v.fixed) graph.set_fixed(v.id);
  }
  for (const Point3D& p : data.points) {
    graph.add_point(p.id, p.p);
    if (p.fixed) graph.set_fixed(p.id);
  }
  for (const Edge3D& e : data.edges) graph.add_pose_edge(e.from_id, e.to_id, {e.q, e.t}, e.information);
  for (const Prior3D& p : data.priors) graph.add_pose_prior(p.id, {p.q, p.t}, p.information);
  for (const PointEdge3D& e : data.point_edges)
    graph.add_point_edge(e.pose_id, e.point_id, e.z, e.information, {e.offset_q, e.offset_t});
  return graph;
}

PoseGraph3DData pose_graph_3d_data(const PoseGraph3D& graph) {
  PoseGraph3DData data;
  data.vertices.reserve(graph.vertices().size());
  for (const Pose3Vertex& v : graph.vertices()) {
    if (v.kind == VertexKind::kPoint) {
      data.points.push_back({v.id, v.value.translation, v.fixed});
      continue;
    }
    data.vertices.push_back({v.id, v.value.rotation, v.value.translation, v.fixed});
  }
  // Each record as its struct lists its fields: the converse of pose_graph_3d_from_data.
  const auto id = [&](int index) { return graph.vertex(index).id; };
  data.edges.reserve(graph.pose_edges().size());
  for (const Pose3Edge& e : graph.pose_edges())
    data.edges.push_back({id(e.from), id(e.to), e.measurement.rotation, e.measurement.translation, e.information});
  for (const Pose3Prior& p : graph.pose_priors())
    data.priors.push_back({id(p.vertex), p.measurement.rotation, p.measurement.translation, p.information});
  for (const Point3Edge& e : graph.point_edges())
    data.point_edges.push_back(
        {id(e.pose), id(e.point), e.measurement, e.information, e.offset.rotation, e.offset.translation});
  return data;
}

PoseGraph3DFileRead read_pose_graph_3d_graph(const std::string& path, const PoseGraphReadOptions& options) {
  PoseGraph3DRead read = read_pose_graph_3d(path, options);
  return {pose_graph_3d_from_data(read.graph), std::move(read.report)};
}

void write_g2o_3d(const std::string& path, const PoseGraph3D& graph) { write_g2o_3d(path, pose_graph_3d_data(graph)); }

}  // namespace probslam
