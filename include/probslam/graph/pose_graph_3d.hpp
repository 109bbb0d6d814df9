#pragma once
// A 3-D pose graph (SE(3) vertices, relative-pose edges with 6x6 information, and optional 3-D
// point landmarks seen from the poses): the data of sphere2500, parking-garage, torus3D and
// GTSAM's pose3example as g2o EDGE_SE3:QUAT holds it, and g2o's VERTEX_TRACKXYZ /
// EDGE_SE3_TRACKXYZ. Poses and points share one vertex list and one id space, as in PoseGraph2D.
// Optimised by graph_optimizer.hpp on the same sparse path as PoseGraph2D.
//
// Tangent convention (used by the error, the information, the Jacobians and the optimiser's
// step): a 6-vector [v; w], translation first and rotation second as in g2o's EDGE_SE3:QUAT, with
// the pose perturbed on the right, x (+) [v; w] = (R Exp(w), t + R v): v in metres in the pose's
// own frame, w a rotation vector in radians (g2o's quaternion-vector update, with the rotation
// vector in place of g2o's quaternion vector part). A point's tangent is 3-D and additive,
// p (+) d = p + d, in world metres.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <unordered_map>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/core/so3.hpp"
#include "probslam/graph/vertex_kind.hpp"

namespace probslam {

class StateWriter;
class StateReader;

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// A rigid transform: rotation (unit quaternion) and translation (m).
struct Pose3 {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
};

/// A pose, or a point landmark whose position is `value.translation` (its rotation is the
/// identity and unused).
struct Pose3Vertex {
  int id;
  Pose3 value;
  bool fixed = false;
  VertexKind kind = VertexKind::kPose;
};

/// x_to measured in the frame of x_from (g2o EDGE_SE3:QUAT). Error, in the tangent convention
/// above: with (R_e, t_e) = z^-1 x_from^-1 x_to, e = [t_e; Log(R_e)] (Log the rotation vector of
/// angle in [0, pi]); chi2 = e^T information e.
struct Pose3Edge {
  int from, to;  ///< vertex indices (not ids)
  Pose3 measurement;
  Matrix6d information;
};

/// A unary measurement z of a pose itself (g2o's EDGE_SE3_PRIOR with the identity offset):
/// e = [t_e; Log(R_e)] of z^-1 x, the error of a Pose3Edge from the world origin, in the same
/// units as the edge's (the rotation vector where g2o's own EdgeSE3Prior takes the quaternion's
/// vector part, as GTSAM's PriorFactor<Pose3> and Pose3Edge do: one convention in the graph).
struct Pose3Prior {
  int vertex;  ///< vertex index (not id)
  Pose3 measurement;
  Matrix6d information;
};

/// A point measured in the frame of a sensor on a pose (g2o EDGE_SE3_TRACKXYZ, the sensor at
/// `offset` in the pose's frame, the identity when it is the pose itself):
/// e = (x_pose * offset)^-1 p - z (m); chi2 = e^T information e.
struct Point3Edge {
  int pose, point;  ///< vertex indices (not ids)
  Eigen::Vector3d measurement;
  Eigen::Matrix3d information;
  Pose3 offset;
};

class PoseGraph3D {
 public:
  /// Lock it around every call when several threads share this object (core/object_mutex.hpp).
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  /// Adds pose vertex `id`. Throws std::invalid_argument for a repeated id, a non-finite value or
  /// a quaternion whose norm is not 1 within kQuaternionNormTolerance (core/so3.hpp; it is stored normalised);
  /// the graph is then unchanged.
  void add_pose(int id, const Pose3& pose);
  /// Adds point vertex `id` at `point` (m); the same id space as the poses. Throws
  /// std::invalid_argument for a repeated id or a non-finite point; graph unchanged.
  void add_point(int id, const Eigen::Vector3d& point);
  /// Throws std::invalid_argument for an unknown id, from == to, a non-finite or non-unit
  /// measurement, or information that is not symmetric positive definite; graph unchanged.
  void add_pose_edge(int from_id, int to_id, const Pose3& measurement, const Matrix6d& information);
  /// Adds a pose-to-point edge (see Point3Edge). Throws std::invalid_argument for an unknown id,
  /// a pose_id that names a point or a point_id that names a pose, a non-finite measurement, a
  /// non-finite or non-unit offset, or information that is not symmetric positive definite;
  /// graph unchanged.
  void add_point_edge(int pose_id, int point_id, const Eigen::Vector3d& measurement,
                      const Eigen::Matrix3d& information, const Pose3& offset = Pose3{});
  /// Adds a prior on vertex `id` (see Pose3Prior). A vertex with a prior holds its part of the
  /// graph in place, as a fixed vertex does, but softly. Throws std::invalid_argument as
  /// add_pose_edge does; graph unchanged.
  void add_pose_prior(int id, const Pose3& measurement, const Matrix6d& information);
  /// A fixed vertex keeps its value (the gauge); with none fixed and no prior, optimisers fix the
  /// first pose.
  void set_fixed(int id, bool fixed = true);
  /// Replaces the values of several pose vertices, all or nothing (checked as add_pose checks;
  /// an id naming a point is refused).
  void set_poses(const std::vector<int>& ids, const std::vector<Pose3>& poses);
  /// Replaces the values of several point vertices, all or nothing (finite; an id naming a pose
  /// is refused).
  void set_points(const std::vector<int>& ids, const std::vector<Eigen::Vector3d>& points);
  /// Replaces every vertex's value (optimisers commit their result this way); one entry per
  /// vertex in index order, finite with unit quaternions, or std::invalid_argument and no change.
  void assign_values(const std::vector<Pose3>& values);
  std::vector<Pose3> values() const;

  /// Poses plus points.
  int num_vertices() const { return static_cast<int>(vertices_.size()); }
  int num_points() const { return num_points_; }
  bool has_vertex(int id) const { return index_.count(id) != 0; }
  /// The index of a vertex id; throws std::invalid_argument for an unknown id.
  int index_of(int id) const;
  const Pose3Vertex& vertex(int index) const { return vertices_[index]; }
  /// Unchecked write access for the optimisers, which work on a copy and commit through
  /// assign_values().
  Pose3Vertex& vertex(int index) { return vertices_[index]; }
  const std::vector<Pose3Vertex>& vertices() const { return vertices_; }
  const std::vector<Pose3Edge>& pose_edges() const { return edges_; }
  const std::vector<Pose3Prior>& pose_priors() const { return priors_; }
  const std::vector<Point3Edge>& point_edges() const { return point_edges_; }

  /// e^T Omega e of every edge at the current values: pose edges, then point edges.
  Eigen::VectorXd edge_chi2() const;
  /// e^T Omega e of every prior at the current values.
  Eigen::VectorXd prior_chi2() const;
  /// The objective: the sum over edges and priors; throws std::invalid_argument when it is not
  /// finite.
  double chi2() const;

  /// Saves every vertex (id, kind, fixed, value), edge, prior and point edge, bit for bit
  /// (docs/file_format.md); load refuses anything but a complete, undamaged, consistent graph.
  static constexpr const char* kStateTag = "PoseGraph3D";
  void save(const std::string& path) const;
  static PoseGraph3D load(const std::string& path);
  void write_state(StateWriter& w) const;
  static PoseGraph3D read_state(StateReader& r);

 private:
  int add_vertex(int id, const Pose3& value, VertexKind kind);
  // The index of `id`, which must name a vertex of `kind` (std::invalid_argument naming
  // `argument` otherwise).
  int require_vertex(int id, VertexKind kind, const char* argument) const;

  std::vector<Pose3Vertex> vertices_;
  std::unordered_map<int, int> index_;
  std::vector<Pose3Edge> edges_;
  std::vector<Pose3Prior> priors_;
  std::vector<Point3Edge> point_edges_;
  int num_points_ = 0;
  ObjectMutex mutex_;
};

/// x (+) delta in the tangent convention above.
Pose3 retract(const Pose3& x, const Vector6d& delta);

/// The error of an edge and its Jacobians with respect to the tangent perturbations of both
/// ends.
struct Pose3EdgeLinearization {
  Vector6d error;
  Matrix6d d_from, d_to;
};
Pose3EdgeLinearization linearize_pose3_edge(const Pose3& from, const Pose3& to, const Pose3& measurement);

/// The error of a prior and its Jacobian with respect to the pose's tangent perturbation.
struct Pose3PriorLinearization {
  Vector6d error;
  Matrix6d d_pose;
};
Pose3PriorLinearization linearize_pose3_prior(const Pose3& pose, const Pose3& measurement);

/// The error of a point edge and its Jacobians with respect to the pose's tangent perturbation
/// (right, [v; w]) and the point's (additive).
struct Point3EdgeLinearization {
  Eigen::Vector3d error;
  Eigen::Matrix<double, 3, 6> d_pose;
  Eigen::Matrix3d d_point;
};
Point3EdgeLinearization linearize_point3_edge(const Pose3& pose, const Eigen::Vector3d& point,
                                              const Eigen::Vector3d& measurement, const Pose3& offset = Pose3{});

}  // namespace probslam
