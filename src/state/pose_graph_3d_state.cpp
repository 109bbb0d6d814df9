// PoseGraph3D's state (docs/file_format.md): the vertices, edges, priors and point edges as they
// are held (quaternions already normalised, information already symmetrised), read back checked
// as add_pose / add_pose_edge / add_pose_prior / add_point_edge check them.
#include <cmath>
#include <string>

#include "graph_state.hpp"
#include "probslam/core/check.hpp"
#include "probslam/graph/pose_graph_3d.hpp"

namespace probslam {
namespace {

using state_detail::read_vertex_index;

// Bytes of one stored pose (quaternion x, y, z, w and translation) and one matrix header.
constexpr std::size_t kPoseBytes = 7 * 8;
constexpr std::size_t kMatrixHeader = 16;

void write_pose(StateWriter& w, const Pose3& p) {
  for (int k = 0; k < 4; ++k) w.f64(p.rotation.coeffs()[k]);
  for (int k = 0; k < 3; ++k) w.f64(p.translation[k]);
}

Pose3 read_pose(StateReader& r, const std::string& what) {
  Pose3 p;
  for (int k = 0; k < 4; ++k) p.rotation.coeffs()[k] = r.f64();
  for (int k = 0; k < 3; ++k) p.translation[k] = r.f64();
  if (!p.rotation.coeffs().allFinite() || !p.translation.allFinite() ||
      !(std::abs(p.rotation.norm() - 1.0) <= kQuaternionNormTolerance))
    r.fail(what + " is not a finite pose with a unit quaternion");
  return p;
}

template <typename Matrix>
Matrix read_information(StateReader& r, const char* what) {
  const Matrix information = r.matrix<Matrix>();
  state_detail::check_information(r, what, information);
  return information;
}

}  // namespace

void PoseGraph3D::write_state(StateWriter& w) const {
  w.count(vertices_.size());
  for (const Pose3Vertex& v : vertices_) {
    w.i32(v.id);
    state_detail::write_vertex_kind(w, v.kind);
    w.boolean(v.fixed);
    write_pose(w, v.value);
  }
  w.count(edges_.size());
  for (const Pose3Edge& e : edges_) {
    w.i32(e.from);
    w.i32(e.to);
    write_pose(w, e.measurement);
    w.matrix(e.information);
  }
  w.count(priors_.size());
  for (const Pose3Prior& p : priors_) {
    w.i32(p.vertex);
    write_pose(w, p.measurement);
    w.matrix(p.information);
  }
  w.count(point_edges_.size());
  for (const Point3Edge& e : point_edges_) {
    w.i32(e.pose);
    w.i32(e.point);
    w.matrix(e.measurement);
    w.matrix(e.information);
    write_pose(w, e.offset);
  }
}

PoseGraph3D PoseGraph3D::read_state(StateReader& r) {
  PoseGraph3D g;
  const std::size_t nv = r.count(4 + 1 + 1 + kPoseBytes);
  g.vertices_.reserve(nv);
  for (std::size_t k = 0; k < nv; ++k) {
    Pose3Vertex v{};
    v.id = r.i32();
    v.kind = state_detail::read_vertex_kind(r);
    v.fixed = r.boolean();
    v.value = read_pose(r, "vertex " + std::to_string(v.id));
    state_detail::index_vertex_id(r, g.index_, v.id, k);
    g.num_points_ += v.kind == VertexKind::kPoint;
    g.vertices_.push_back(v);
  }
  const auto vertex = [&](VertexKind kind, const char* what) { return read_vertex_index(r, g.vertices_, kind, what); };
  const std::size_t ne = r.count(8 + kPoseBytes + kMatrixHeader + 36 * 8);
  g.edges_.reserve(ne);
  for (std::size_t k = 0; k < ne; ++k) {
    Pose3Edge e{};
    e.from = vertex(VertexKind::kPose, "pose");
    e.to = vertex(VertexKind::kPose, "pose");
    if (e.from == e.to) r.fail("a pose edge joins a vertex to itself");
    e.measurement = read_pose(r, "a pose edge's measurement");
    e.information = read_information<Matrix6d>(r, "pose edge");
    g.edges_.push_back(e);
  }
  const std::size_t np = r.count(4 + kPoseBytes + kMatrixHeader + 36 * 8);
  g.priors_.reserve(np);
  for (std::size_t k = 0; k < np; ++k) {
    Pose3Prior p{};
    p.vertex = vertex(VertexKind::kPose, "pose");
    p.measurement = read_pose(r, "a prior's measurement");
    p.information = read_information<Matrix6d>(r, "prior");
    g.priors_.push_back(p);
  }
  const std::size_t nq = r.count(8 + kMatrixHeader + 24 + kMatrixHeader + 72 + kPoseBytes);
  g.point_edges_.reserve(nq);
  for (std::size_t k = 0; k < nq; ++k) {
    Point3Edge e{};
    e.pose = vertex(VertexKind::kPose, "pose");
    e.point = vertex(VertexKind::kPoint, "point");
    e.measurement = r.matrix<Eigen::Vector3d>();
    if (!e.measurement.allFinite()) r.fail("a point edge's measurement is not finite");
    e.information = read_information<Eigen::Matrix3d>(r, "point edge");
    e.offset = read_pose(r, "a point edge's sensor offset");
    g.point_edges_.push_back(e);
  }
  return g;
}

void PoseGraph3D::save(const std::string& path) const { save_state(*this, path); }
PoseGraph3D PoseGraph3D::load(const std::string& path) { return load_state<PoseGraph3D>(path); }

}  // namespace probslam
