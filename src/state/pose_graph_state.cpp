// PoseGraph2D's state (docs/file_format.md).
#include "graph_state.hpp"
#include "probslam/core/check.hpp"
#include "probslam/graph/pose_graph_2d.hpp"

namespace probslam {

using state_detail::read_vertex_index;

namespace {

/// A 2-D edge's measurement and information as stored.
template <typename Edge>
void read_measurement(StateReader& r, Edge& e) {
  e.measurement = r.matrix<decltype(e.measurement)>();
  e.information = r.matrix<decltype(e.information)>();
}

/// Checks them as add_pose_edge and add_point_edge do (a finite measurement, an SPD
/// information); `what` names the edge in the error.
template <typename Edge>
void check_measurement(const StateReader& r, const char* what, const Edge& e) {
  validated(r, what, [&] { require_all_finite(e.measurement, "measurement"); });
  state_detail::check_information(r, what, e.information);
}

}  // namespace

void PoseGraph2D::write_state(StateWriter& w) const {
  w.count(vertices_.size());
  for (const GraphVertex& v : vertices_) {
    w.i32(v.id);
    state_detail::write_vertex_kind(w, v.kind);
    w.matrix(v.value);
    w.boolean(v.fixed);
    w.i32(v.landmark_id);
  }
  w.count(pose_edges_.size());
  for (const PoseEdge& e : pose_edges_) {
    w.i32(e.from);
    w.i32(e.to);
    w.matrix(e.measurement);
    w.matrix(e.information);
  }
  w.count(point_edges_.size());
  for (const PointEdge& e : point_edges_) {
    w.i32(e.pose);
    w.i32(e.point);
    w.matrix(e.measurement);
    w.matrix(e.information);
  }
}

PoseGraph2D PoseGraph2D::read_state(StateReader& r) {
  PoseGraph2D g;
  const std::size_t nv = r.count(4 + 1 + 16 + 24 + 1 + 4);
  g.vertices_.reserve(nv);
  for (std::size_t k = 0; k < nv; ++k) {
    GraphVertex v{};
    v.id = r.i32();
    v.kind = state_detail::read_vertex_kind(r);
    v.value = r.matrix<Eigen::Vector3d>();
    v.fixed = r.boolean();
    v.landmark_id = r.i32();
    if (!v.value.allFinite()) r.fail("vertex " + std::to_string(v.id) + " has a value that is not finite");
    state_detail::index_vertex_id(r, g.index_, v.id, k);
    g.vertices_.push_back(v);
  }
  const auto vertex = [&](VertexKind kind, const char* what) { return read_vertex_index(r, g.vertices_, kind, what); };
  const std::size_t npe = r.count(8 + 16 + 24 + 16 + 72);
  g.pose_edges_.reserve(npe);
  for (std::size_t k = 0; k < npe; ++k) {
    PoseEdge e{};
    e.from = vertex(VertexKind::kPose, "pose");
    e.to = vertex(VertexKind::kPose, "pose");
    read_measurement(r, e);
    if (e.from == e.to) r.fail("a pose edge joins a vertex to itself");
    check_measurement(r, "pose edge", e);
    g.pose_edges_.push_back(e);
  }
  const std::size_t nqe = r.count(8 + 16 + 16 + 16 + 32);
  g.point_edges_.reserve(nqe);
  for (std::size_t k = 0; k < nqe; ++k) {
    PointEdge e{};
    e.pose = vertex(VertexKind::kPose, "pose");
    e.point = vertex(VertexKind::kPoint, "point");
    read_measurement(r, e);
    check_measurement(r, "point edge", e);
    g.point_edges_.push_back(e);
  }
  return g;
}

void PoseGraph2D::save(const std::string& path) const { save_state(*this, path); }
PoseGraph2D PoseGraph2D::load(const std::string& path) { return load_state<PoseGraph2D>(path); }

}  // namespace probslam
