#include "probslam/graph/pose_graph_3d.hpp"

#include <cmath>
#include <string>

#include "probslam/core/check.hpp"

namespace probslam {
namespace {

// Information matrices come from text files with about six significant digits; asymmetry below
// this (relative to the largest entry) is rounding in the file, larger is a wrong matrix.
constexpr double kSymmetryTolerance = 1e-6;

// A finite pose with a unit quaternion, returned with the quaternion normalised.
Pose3 checked_pose(const Pose3& pose, const char* name) {
  require_all_finite(pose.translation, name);
  require_all_finite(pose.rotation.coeffs(), name);
  const double norm = pose.rotation.norm();
  if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance))
    throw_invalid_argument(name, "quaternion must have norm 1 (within " +
                                     std::to_string(kQuaternionNormTolerance) + "), got norm " +
                                     std::to_string(norm));
  Pose3 out = pose;
  out.rotation.normalize();
  return out;
}

}  // namespace

// The callers have refused a repeated id first (before checking the value, as the error order
// of add_pose has always been).
int PoseGraph3D::add_vertex(int id, const Pose3& value, VertexKind kind) {
  const int index = num_vertices();
  index_.emplace(id, index);
  try {
    vertices_.push_back({id, value, false, kind});
  } catch (...) {  // out of memory: the graph stays as it was
    index_.erase(id);
    throw;
  }
  return index;
}

void PoseGraph3D::add_pose(int id, const Pose3& pose) {
  if (has_vertex(id)) throw_invalid_argument("id", "is already used: " + std::to_string(id));
  add_vertex(id, checked_pose(pose, "pose"), VertexKind::kPose);
}

void PoseGraph3D::add_point(int id, const Eigen::Vector3d& point) {
  if (has_vertex(id)) throw_invalid_argument("id", "is already used: " + std::to_string(id));
  require_all_finite(point, "point");
  add_vertex(id, {Eigen::Quaterniond::Identity(), point}, VertexKind::kPoint);
  ++num_points_;
}

int PoseGraph3D::require_vertex(int id, VertexKind kind, const char* argument) const {
  const auto it = index_.find(id);
  if (it == index_.end()) throw_invalid_argument(argument, "unknown vertex id " + std::to_string(id));
  if (vertices_[it->second].kind != kind)
    throw_invalid_argument(argument, "vertex " + std::to_string(id) + " is a " +
                                         (kind == VertexKind::kPose ? "point, not a pose" : "pose, not a point"));
  return it->second;
}

int PoseGraph3D::index_of(int id) const {
  const auto it = index_.find(id);
  if (it == index_.end()) throw_invalid_argument("id", "unknown vertex id " + std::to_string(id));
  return it->second;
}

void PoseGraph3D::add_pose_edge(int from_id, int to_id, const Pose3& measurement, const Matrix6d& information) {
  const int from = require_vertex(from_id, VertexKind::kPose, "from");
  const int to = require_vertex(to_id, VertexKind::kPose, "to");
  require(from_id != to_id, "to", "must differ from the edge's first vertex");
  const Pose3 z = checked_pose(measurement, "measurement");
  require_symmetric_positive_definite(information, "information", kSymmetryTolerance);
  edges_.push_back({from, to, z, 0.5 * (information + information.transpose())});
}

void PoseGraph3D::add_point_edge(int pose_id, int point_id, const Eigen::Vector3d& measurement,
                                 const Eigen::Matrix3d& information, const Pose3& offset) {
  const int pose = require_vertex(pose_id, VertexKind::kPose, "pose_id");
  const int point = require_vertex(point_id, VertexKind::kPoint, "point_id");
  require_all_finite(measurement, "measurement");
  const Pose3 sensor = checked_pose(offset, "offset");
  require_symmetric_positive_definite(information, "information", kSymmetryTolerance);
  point_edges_.push_back({pose, point, measurement, 0.5 * (information + information.transpose()), sensor});
}

void PoseGraph3D::add_pose_prior(int id, const Pose3& measurement, const Matrix6d& information) {
  const int vertex = require_vertex(id, VertexKind::kPose, "id");
  const Pose3 z = checked_pose(measurement, "measurement");
  require_symmetric_positive_definite(information, "information", kSymmetryTolerance);
  priors_.push_back({vertex, z, 0.5 * (information + information.transpose())});
}

void PoseGraph3D::set_fixed(int id, bool fixed) { vertices_[index_of(id)].fixed = fixed; }

void PoseGraph3D::set_poses(const std::vector<int>& ids, const std::vector<Pose3>& poses) {
  require(ids.size() == poses.size(), "poses", "must have one entry per id");
  std::vector<Pose3> checked;
  checked.reserve(poses.size());
  for (size_t k = 0; k < ids.size(); ++k) {  // everything checked before anything is written
    require_vertex(ids[k], VertexKind::kPose, "ids");
    checked.push_back(checked_pose(poses[k], "poses"));
  }
  for (size_t k = 0; k < ids.size(); ++k) vertices_[index_of(ids[k])].value = checked[k];
}

void PoseGraph3D::set_points(const std::vector<int>& ids, const std::vector<Eigen::Vector3d>& points) {
  require(ids.size() == points.size(), "points", "must have one entry per id");
  for (size_t k = 0; k < ids.size(); ++k) {  // everything checked before anything is written
    require_vertex(ids[k], VertexKind::kPoint, "ids");
    require_all_finite(points[k], "points");
  }
  for (size_t k = 0; k < ids.size(); ++k) vertices_[index_of(ids[k])].value.translation = points[k];
}

void PoseGraph3D::assign_values(const std::vector<Pose3>& values) {
  require(values.size() == vertices_.size(), "values", "must have one entry per vertex");
  for (const Pose3& v : values)
    require(v.translation.allFinite() && v.rotation.coeffs().allFinite() &&
                std::abs(v.rotation.norm() - 1.0) <= kQuaternionNormTolerance,
            "graph", "result is not finite (values or information too large?)");
  for (size_t k = 0; k < values.size(); ++k) {
    vertices_[k].value = values[k];
    vertices_[k].value.rotation.normalize();
  }
}

std::vector<Pose3> PoseGraph3D::values() const {
  std::vector<Pose3> out;
  out.reserve(vertices_.size());
  for (const Pose3Vertex& v : vertices_) out.push_back(v.value);
  return out;
}

Eigen::VectorXd PoseGraph3D::edge_chi2() const {
  Eigen::VectorXd out(edges_.size() + point_edges_.size());
  for (size_t k = 0; k < edges_.size(); ++k) {
    const Pose3Edge& e = edges_[k];
    const Vector6d r = linearize_pose3_edge(vertices_[e.from].value, vertices_[e.to].value, e.measurement).error;
    out[static_cast<Eigen::Index>(k)] = r.dot(e.information * r);
  }
  for (size_t k = 0; k < point_edges_.size(); ++k) {
    const Point3Edge& e = point_edges_[k];
    const Eigen::Vector3d r =
        linearize_point3_edge(vertices_[e.pose].value, vertices_[e.point].value.translation, e.measurement, e.offset)
            .error;
    out[static_cast<Eigen::Index>(edges_.size() + k)] = r.dot(e.information * r);
  }
  return out;
}

Eigen::VectorXd PoseGraph3D::prior_chi2() const {
  Eigen::VectorXd out(priors_.size());
  for (size_t k = 0; k < priors_.size(); ++k) {
    const Pose3Prior& p = priors_[k];
    const Vector6d r = linearize_pose3_prior(vertices_[p.vertex].value, p.measurement).error;
    out[static_cast<Eigen::Index>(k)] = r.dot(p.information * r);
  }
  return out;
}

double PoseGraph3D::chi2() const {
  const double sum = edge_chi2().sum() + prior_chi2().sum();
  require(std::isfinite(sum), "graph", "chi2 is not finite at the current values (values or information too large?)");
  return sum;
}

Pose3 retract(const Pose3& x, const Vector6d& delta) {
  Pose3 out;
  out.translation = x.translation + x.rotation * delta.head<3>();
  out.rotation = (x.rotation * so3_exp(delta.tail<3>())).normalized();
  return out;
}

// With d = R_i^T (t_j - t_i), R_e = R_z^T R_i^T R_j and J = Jr^-1(Log R_e), perturbing
// x_j = (R_j Exp(w_j), t_j + R_j v_j) and x_i likewise gives to first order
//   e_t = R_z^T (d - t_z):  de_t/dv_j = R_z^T R_i^T R_j,  de_t/dv_i = -R_z^T,
//                           de_t/dw_i = R_z^T [d]x  (R_i^T -> Exp(-w_i) R_i^T),
//   e_r = Log(R_e):         de_r/dw_j = J,  de_r/dw_i = -J R_e^T R_z^T
// (R_z^T Exp(-w_i) R_i^T R_j = R_e Exp(-R_e^T R_z^T w_i)); the other blocks are zero.
Pose3EdgeLinearization linearize_pose3_edge(const Pose3& from, const Pose3& to, const Pose3& measurement) {
  const Eigen::Matrix3d ri_t = from.rotation.toRotationMatrix().transpose();
  const Eigen::Matrix3d rz_t = measurement.rotation.toRotationMatrix().transpose();
  const Eigen::Vector3d d = ri_t * (to.translation - from.translation);
  const Eigen::Quaterniond qe = measurement.rotation.conjugate() * from.rotation.conjugate() * to.rotation;
  const Eigen::Matrix3d re = qe.toRotationMatrix();
  Pose3EdgeLinearization out;
  out.error.head<3>() = rz_t * (d - measurement.translation);
  out.error.tail<3>() = so3_log(qe);
  const Eigen::Matrix3d j = so3_right_jacobian_inverse(out.error.tail<3>());
  out.d_from.setZero();
  out.d_from.topLeftCorner<3, 3>() = -rz_t;
  out.d_from.topRightCorner<3, 3>() = rz_t * skew(d);
  out.d_from.bottomRightCorner<3, 3>() = -j * re.transpose() * rz_t;
  out.d_to.setZero();
  out.d_to.topLeftCorner<3, 3>() = rz_t * ri_t * to.rotation.toRotationMatrix();
  out.d_to.bottomRightCorner<3, 3>() = j;
  return out;
}

// The prior is the edge from the world origin (R_i = I, t_i = 0) to the pose: its error and
// d_to above with R_i = I, d = t.
Pose3PriorLinearization linearize_pose3_prior(const Pose3& pose, const Pose3& measurement) {
  const Eigen::Matrix3d rz_t = measurement.rotation.toRotationMatrix().transpose();
  const Eigen::Quaterniond qe = measurement.rotation.conjugate() * pose.rotation;
  Pose3PriorLinearization out;
  out.error.head<3>() = rz_t * (pose.translation - measurement.translation);
  out.error.tail<3>() = so3_log(qe);
  out.d_pose.setZero();
  out.d_pose.topLeftCorner<3, 3>() = rz_t * pose.rotation.toRotationMatrix();
  out.d_pose.bottomRightCorner<3, 3>() = so3_right_jacobian_inverse(out.error.tail<3>());
  return out;
}

// With the sensor s = x * offset (R_s = R_x R_o, t_s = t_x + R_x t_o) and q = R_x^T (p - t_x),
// e = R_s^T (p - t_s) - z = R_o^T (q - t_o) - z. Perturbing x = (R_x Exp(w), t_x + R_x v):
// q -> Exp(-w) (q - v) = q - v + [q]x w to first order, so de/dv = -R_o^T, de/dw = R_o^T [q]x;
// the point moves additively: de/dp = R_o^T R_x^T.
Point3EdgeLinearization linearize_point3_edge(const Pose3& pose, const Eigen::Vector3d& point,
                                              const Eigen::Vector3d& measurement, const Pose3& offset) {
  const Eigen::Matrix3d rx_t = pose.rotation.toRotationMatrix().transpose();
  const Eigen::Matrix3d ro_t = offset.rotation.toRotationMatrix().transpose();
  const Eigen::Vector3d q = rx_t * (point - pose.translation);
  Point3EdgeLinearization out;
  out.error = ro_t * (q - offset.translation) - measurement;
  out.d_pose.leftCols<3>() = -ro_t;
  out.d_pose.rightCols<3>() = ro_t * skew(q);
  out.d_point = ro_t * rx_t;
  return out;
}

}  // namespace probslam
