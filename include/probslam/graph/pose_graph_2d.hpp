#pragma once
// A planar pose/landmark graph: the data of the full SLAM problem as g2o, TORO and iSAM files
// hold it. Optimised by graph_optimizer.hpp.
#include <Eigen/Core>
#include <string>
#include <unordered_map>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/graph/vertex_kind.hpp"

namespace probslam {

class StateWriter;
class StateReader;

/// A pose (x, y, theta) or a point (x, y, unused 0); ids are the user's, in one id space (g2o's).
/// iSAM files number landmarks apart from poses: a point keeps that number as `landmark_id`,
/// which equals `id` unless a reader had to renumber the point to keep the ids unique.
struct GraphVertex {
  int id;
  VertexKind kind;
  Eigen::Vector3d value;
  bool fixed = false;
  int landmark_id = 0;
};

/// x_to measured in the frame of x_from (g2o EDGE_SE2): error t2v(z^-1 x_from^-1 x_to).
struct PoseEdge {
  int from, to;  ///< vertex indices (not ids)
  Eigen::Vector3d measurement;
  Eigen::Matrix3d information;
};

/// A point measured in the frame of a pose (g2o EDGE_SE2_XY): error x_pose^-1 * point - z.
struct PointEdge {
  int pose, point;  ///< vertex indices (not ids)
  Eigen::Vector2d measurement;
  Eigen::Matrix2d information;
};

class PoseGraph2D {
 public:
  /// Lock it around every call when several threads share this object (core/object_mutex.hpp).
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  /// Each add_* throws std::invalid_argument for a repeated or unknown id, a non-finite value,
  /// or an information matrix that is not symmetric positive definite; the graph is unchanged.
  void add_pose(int id, const Eigen::Vector3d& pose);
  void add_point(int id, const Eigen::Vector2d& point);
  /// A point whose id in the landmark id space (iSAM's LANDMARK records) differs from `id`.
  void add_point(int id, const Eigen::Vector2d& point, int landmark_id);
  void add_pose_edge(int from_id, int to_id, const Eigen::Vector3d& measurement,
                     const Eigen::Matrix3d& information);
  void add_point_edge(int pose_id, int point_id, const Eigen::Vector2d& measurement,
                      const Eigen::Matrix2d& information);
  /// A fixed vertex keeps its value (the gauge); with none fixed, optimisers fix the first pose.
  void set_fixed(int id, bool fixed = true);
  /// Replaces a vertex's value (an initial guess); a point uses value[0..1].
  void set_value(int id, const Eigen::Vector3d& value);
  /// Replaces the values of several vertices of one kind, all or nothing: every id must name a
  /// vertex of that kind and every value be finite, or std::invalid_argument and no change.
  void set_values(const std::vector<int>& ids, const std::vector<Eigen::Vector3d>& values,
                  VertexKind kind);
  /// Replaces every vertex's value (optimisers commit their result this way); `values` has one
  /// entry per vertex, in index order, all finite, or std::invalid_argument and no change.
  void assign_values(const std::vector<Eigen::Vector3d>& values);
  std::vector<Eigen::Vector3d> values() const;

  int num_vertices() const { return static_cast<int>(vertices_.size()); }
  bool has_vertex(int id) const { return index_.count(id) != 0; }
  /// The index of a vertex id; throws std::invalid_argument for an unknown id.
  int index_of(int id) const;
  const GraphVertex& vertex(int index) const { return vertices_[index]; }
  /// Unchecked write access for the optimisers, which work on a copy and commit through
  /// assign_values(); a caller writing through it owns the finiteness of what it writes.
  GraphVertex& vertex(int index) { return vertices_[index]; }
  const std::vector<GraphVertex>& vertices() const { return vertices_; }
  const std::vector<PoseEdge>& pose_edges() const { return pose_edges_; }
  const std::vector<PointEdge>& point_edges() const { return point_edges_; }

  /// e^T Omega e of every edge at the current values: pose edges, then point edges.
  Eigen::VectorXd edge_chi2() const;
  /// Their sum (g2o's chi2); throws std::invalid_argument when it is not finite (values or
  /// information so large that the squares overflow).
  double chi2() const;

  /// Saves every vertex (id, kind, value, fixed, landmark id) and edge, bit for bit
  /// (docs/file_format.md); load refuses anything but a complete, undamaged, consistent graph.
  static constexpr const char* kStateTag = "PoseGraph2D";
  void save(const std::string& path) const;
  static PoseGraph2D load(const std::string& path);
  void write_state(StateWriter& w) const;
  static PoseGraph2D read_state(StateReader& r);

 private:
  int add_vertex(int id, VertexKind kind, const Eigen::Vector3d& value);
  int require_vertex(int id, VertexKind kind, const char* argument) const;

  std::vector<GraphVertex> vertices_;
  std::unordered_map<int, int> index_;
  std::vector<PoseEdge> pose_edges_;
  std::vector<PointEdge> point_edges_;
  ObjectMutex mutex_;
};

/// The error of a pose edge and its Jacobians with respect to (x, y, theta) of both ends, the
/// angles moving additively (as g2o's VertexSE2 does).
struct PoseEdgeLinearization {
  Eigen::Vector3d error;
  Eigen::Matrix3d d_from, d_to;
};
PoseEdgeLinearization linearize_pose_edge(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                          const Eigen::Vector3d& measurement);

struct PointEdgeLinearization {
  Eigen::Vector2d error;
  Eigen::Matrix<double, 2, 3> d_pose;
  Eigen::Matrix2d d_point;
};
PointEdgeLinearization linearize_point_edge(const Eigen::Vector3d& pose,
                                            const Eigen::Vector2d& point,
                                            const Eigen::Vector2d& measurement);

}  // namespace probslam
