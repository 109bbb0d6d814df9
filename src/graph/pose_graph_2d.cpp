#include "probslam/graph/pose_graph_2d.hpp"

#include <cmath>
#include <string>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"

namespace probslam {
namespace {

// Information matrices come from text files with about six significant digits; asymmetry below
// this (relative to the largest entry) is rounding in the file, larger is a wrong matrix.
constexpr double kSymmetryTolerance = 1e-6;

// d(R(theta)^T)/d theta.
Eigen::Matrix2d rotation_transpose_derivative(double theta) {
  const double c = std::cos(theta), s = std::sin(theta);
  Eigen::Matrix2d d;
  d << -s, c, -c, -s;
  return d;
}

}  // namespace

int PoseGraph2D::add_vertex(int id, VertexKind kind, const Eigen::Vector3d& value) {
  if (has_vertex(id)) throw_invalid_argument("id", "is already used: " + std::to_string(id));
  require_all_finite(value, kind == VertexKind::kPose ? "pose" : "point");
  const int index = num_vertices();
  index_.emplace(id, index);
  try {
    vertices_.push_back({id, kind, value, false, id});
  } catch (...) {  // out of memory: the graph stays as it was
    index_.erase(id);
    throw;
  }
  return index;
}

void PoseGraph2D::add_pose(int id, const Eigen::Vector3d& pose) {
  Eigen::Vector3d value = pose;
  if (std::isfinite(value[2])) value[2] = wrap_angle(value[2]);
  add_vertex(id, VertexKind::kPose, value);
}

void PoseGraph2D::add_point(int id, const Eigen::Vector2d& point) {
  add_vertex(id, VertexKind::kPoint, {point.x(), point.y(), 0.0});
}

void PoseGraph2D::add_point(int id, const Eigen::Vector2d& point, int landmark_id) {
  vertices_[add_vertex(id, VertexKind::kPoint, {point.x(), point.y(), 0.0})].landmark_id = landmark_id;
}

int PoseGraph2D::index_of(int id) const {
  const auto it = index_.find(id);
  if (it == index_.end()) throw_invalid_argument("id", "unknown vertex id " + std::to_string(id));
  return it->second;
}

int PoseGraph2D::require_vertex(int id, VertexKind kind, const char* argument) const {
  const auto it = index_.find(id);
  if (it == index_.end())
    throw_invalid_argument(argument, "unknown vertex id " + std::to_string(id));
  if (vertices_[it->second].kind != kind)
    throw_invalid_argument(argument, "vertex " + std::to_string(id) + " is a " +
                                         (kind == VertexKind::kPose ? "point, not a pose"
                                                                    : "pose, not a point"));
  return it->second;
}

void PoseGraph2D::add_pose_edge(int from_id, int to_id, const Eigen::Vector3d& measurement,
                                const Eigen::Matrix3d& information) {
  const int from = require_vertex(from_id, VertexKind::kPose, "from");
  const int to = require_vertex(to_id, VertexKind::kPose, "to");
  require(from != to, "to", "must differ from the edge's first vertex");
  require_all_finite(measurement, "measurement");
  require_symmetric_positive_definite(information, "information", kSymmetryTolerance);
  pose_edges_.push_back({from, to, measurement, 0.5 * (information + information.transpose())});
}

void PoseGraph2D::add_point_edge(int pose_id, int point_id, const Eigen::Vector2d& measurement,
                                 const Eigen::Matrix2d& information) {
  const int pose = require_vertex(pose_id, VertexKind::kPose, "pose");
  const int point = require_vertex(point_id, VertexKind::kPoint, "point");
  require_all_finite(measurement, "measurement");
  require_symmetric_positive_definite(information, "information", kSymmetryTolerance);
  point_edges_.push_back({pose, point, measurement, 0.5 * (information + information.transpose())});
}

void PoseGraph2D::set_fixed(int id, bool fixed) { vertices_[index_of(id)].fixed = fixed; }

void PoseGraph2D::set_value(int id, const Eigen::Vector3d& value) {
  GraphVertex& v = vertices_[index_of(id)];
  require_all_finite(value, "value");
  v.value = value;
  if (v.kind == VertexKind::kPose)
    v.value[2] = wrap_angle(value[2]);
  else
    v.value[2] = 0.0;
}

void PoseGraph2D::set_values(const std::vector<int>& ids, const std::vector<Eigen::Vector3d>& values,
                             VertexKind kind) {
  require(ids.size() == values.size(), "values", "must have one row per id");
  const char* name = kind == VertexKind::kPose ? "poses" : "points";
  for (size_t k = 0; k < ids.size(); ++k) {  // everything checked before anything is written
    require_vertex(ids[k], kind, "ids");
    require_all_finite(values[k], name);
  }
  for (size_t k = 0; k < ids.size(); ++k) set_value(ids[k], values[k]);
}

void PoseGraph2D::assign_values(const std::vector<Eigen::Vector3d>& values) {
  require(values.size() == vertices_.size(), "values", "must have one entry per vertex");
  for (const Eigen::Vector3d& v : values)
    require(v.allFinite(), "graph", "result is not finite (values or information too large?)");
  for (size_t k = 0; k < values.size(); ++k) vertices_[k].value = values[k];
}

std::vector<Eigen::Vector3d> PoseGraph2D::values() const {
  std::vector<Eigen::Vector3d> out;
  out.reserve(vertices_.size());
  for (const GraphVertex& v : vertices_) out.push_back(v.value);
  return out;
}

Eigen::VectorXd PoseGraph2D::edge_chi2() const {
  Eigen::VectorXd out(pose_edges_.size() + point_edges_.size());
  Eigen::Index k = 0;
  for (const PoseEdge& e : pose_edges_) {
    const Eigen::Vector3d r =
        linearize_pose_edge(vertices_[e.from].value, vertices_[e.to].value, e.measurement).error;
    out[k++] = r.dot(e.information * r);
  }
  for (const PointEdge& e : point_edges_) {
    const Eigen::Vector2d r = linearize_point_edge(vertices_[e.pose].value,
                                                   vertices_[e.point].value.head<2>(),
                                                   e.measurement)
                                  .error;
    out[k++] = r.dot(e.information * r);
  }
  return out;
}

double PoseGraph2D::chi2() const {
  double sum = 0.0;
  for (const double s : edge_chi2()) sum += s;
  require(std::isfinite(sum), "graph", "chi2 is not finite at the current values (values or information too large?)");
  return sum;
}

PoseEdgeLinearization linearize_pose_edge(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                          const Eigen::Vector3d& measurement) {
  const Eigen::Matrix2d rz_t = rotation_matrix(measurement[2]).transpose();
  const Eigen::Matrix2d ri_t = rotation_matrix(from[2]).transpose();
  const Eigen::Vector2d delta = to.head<2>() - from.head<2>();
  PoseEdgeLinearization out;
  out.error.head<2>() = rz_t * (ri_t * delta - measurement.head<2>());
  out.error[2] = wrap_angle(to[2] - from[2] - measurement[2]);
  out.d_from.setZero();
  out.d_from.topLeftCorner<2, 2>() = -rz_t * ri_t;
  out.d_from.block<2, 1>(0, 2) = rz_t * rotation_transpose_derivative(from[2]) * delta;
  out.d_from(2, 2) = -1.0;
  out.d_to.setZero();
  out.d_to.topLeftCorner<2, 2>() = rz_t * ri_t;
  out.d_to(2, 2) = 1.0;
  return out;
}

PointEdgeLinearization linearize_point_edge(const Eigen::Vector3d& pose,
                                            const Eigen::Vector2d& point,
                                            const Eigen::Vector2d& measurement) {
  const Eigen::Matrix2d ri_t = rotation_matrix(pose[2]).transpose();
  const Eigen::Vector2d delta = point - pose.head<2>();
  PointEdgeLinearization out;
  out.error = ri_t * delta - measurement;
  out.d_pose.leftCols<2>() = -ri_t;
  out.d_pose.col(2) = rotation_transpose_derivative(pose[2]) * delta;
  out.d_point = ri_t;
  return out;
}

}  // namespace probslam
