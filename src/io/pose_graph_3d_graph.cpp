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
    Vertex3D out;
    out.id = v.id;
    out.q = v.value.rotation;
    out.t = v.value.translation;
    out.fixed = v.fixed;
    data.vertices.push_back(out);
  }
  data.edges.reserve(graph.pose_edges().size());
  for (const Pose3Edge& e : graph.pose_edges()) {
    Edge3D out;
    out.from_id = graph.vertex(e.from).id;
    out.to_id = graph.vertex(e.to).id;
    out.q = e.measurement.rotation;
    out.t = e.measurement.translation;
    out.information = e.information;
    data.edges.push_back(out);
  }
  for (const Pose3Prior& p : graph.pose_priors()) {
    Prior3D out;
    out.id = graph.vertex(p.vertex).id;
    out.q = p.measurement.rotation;
    out.t = p.measurement.translation;
    out.information = p.information;
    data.priors.push_back(out);
  }
  for (const Point3Edge& e : graph.point_edges()) {
    PointEdge3D out;
    out.pose_id = graph.vertex(e.pose).id;
    out.point_id = graph.vertex(e.point).id;
    out.z = e.measurement;
    out.information = e.information;
    out.offset_q = e.offset.rotation;
    out.offset_t = e.offset.translation;
    data.point_edges.push_back(out);
  }
  return data;
}

PoseGraph3DFileRead read_pose_graph_3d_graph(const std::string& path, const PoseGraphReadOptions& options) {
  PoseGraph3DRead read = read_pose_graph_3d(path, options);
  return {pose_graph_3d_from_data(read.graph), std::move(read.report)};
}

void write_g2o_3d(const std::string& path, const PoseGraph3D& graph) { write_g2o_3d(path, pose_graph_3d_data(graph)); }

}  // namespace probslam
