#pragma once
// Readers and a writer for 3-D pose graph files (g2o SE3, iSAM / GTSAM EDGE3, TORO 3-D), into a
// neutral structure: the optimiser (PoseGraph3D) is built from it, not the other way round.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include "probslam/core/so3.hpp"  // kQuaternionNormTolerance
#include "probslam/io/pose_graph_file.hpp"  // PoseGraphReadOptions, PoseGraphReadReport, RowPolicy

namespace probslam {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// A pose x = (q, t): world <- body, p_world = q * p_body + t. q is unit (normalised on reading).
struct Vertex3D {
  int id = 0;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  bool fixed = false;  ///< named by a g2o FIX record
};

/// A relative-pose measurement z = (q, t) of x_from^-1 * x_to, with the information of the error
/// in g2o's tangent order [translation (3), rotation (3)] for every format.
///
/// The rotation block weights a small rotation about x, y, z. The formats agree on the order
/// but not on the unit: g2o's own EdgeSE3 applies it to the vector part of the error quaternion
/// (half the angle), GTSAM's readG2o and SE-Sync to the rotation vector (the whole angle), iSAM
/// and TORO to roll/pitch/yaw differences (to first order the rotation vector). The numbers are
/// kept as the file gives them; the optimiser's error says which reading it uses.
struct Edge3D {
  int from_id = 0;
  int to_id = 0;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Matrix6d information = Matrix6d::Identity();
};

/// g2o's EDGE_SE3_PRIOR: a unary measurement z = (q, t) of the pose itself, information as for
/// Edge3D. Kept as a prior, not turned into a fixed vertex: its information says how firmly the
/// pose is held, which fixing would throw away (a caller who wants it fixed can fix it).
struct Prior3D {
  int id = 0;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Matrix6d information = Matrix6d::Identity();
};

/// A 3-D point landmark (g2o VERTEX_TRACKXYZ), in the poses' id space.
struct Point3D {
  int id = 0;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  bool fixed = false;  ///< named by a g2o FIX record
};

/// g2o's EDGE_SE3_TRACKXYZ: point `point_id` measured at z (m) in the frame of a sensor at
/// (offset_q, offset_t) in the frame of pose `pose_id` (the file's PARAMS_SE3OFFSET):
/// error (x_pose * offset)^-1 p - z, information 3x3 over [x y z] (g2o's convention: the file's 6
/// upper-triangle entries are the information, whatever the NoiseFormat of the pose records).
struct PointEdge3D {
  int pose_id = 0;
  int point_id = 0;
  Eigen::Vector3d z = Eigen::Vector3d::Zero();
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();
  Eigen::Quaterniond offset_q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d offset_t = Eigen::Vector3d::Zero();
};

/// A 3-D pose graph as a file holds it: vertices in file order (or, for a file that lists
/// none, in the order dead reckoning placed them), edges and priors in file order; points and
/// their edges in file order.
struct PoseGraph3DData {
  std::vector<Vertex3D> vertices;
  std::vector<Edge3D> edges;
  std::vector<Prior3D> priors;
  std::vector<Point3D> points;
  std::vector<PointEdge3D> point_edges;
};

struct PoseGraph3DRead {
  PoseGraph3DData graph;
  PoseGraphReadReport report;
};

/// Parses a 3-D graph; `source` names it in errors, std::invalid_argument "source:LINE: reason".
///
/// Formats (options.format; kAuto decides from the first record: VERTEX3 is TORO, EDGE3 iSAM,
/// anything else g2o):
/// - kG2o: `VERTEX_SE3:QUAT id x y z qx qy qz qw`, `EDGE_SE3:QUAT i j x y z qx qy qz qw` + the 21
///   upper-triangle (row-major) entries of the 6x6 information over [x y z, rotation],
///   `EDGE_SE3_PRIOR id param x y z qx qy qz qw` + 21 (param: a `PARAMS_SE3OFFSET param x y z qx
///   qy qz qw` record, which must be the identity: an offset sensor is not supported), `FIX ids`;
///   3-D points: `VERTEX_TRACKXYZ id x y z` (the poses' id space) and `EDGE_SE3_TRACKXYZ pose
///   point param x y z` + the 6 upper-triangle (row-major) entries of the 3x3 information (param:
///   a PARAMS_SE3OFFSET, the sensor's pose in the pose's frame; any offset). An edge whose ends
///   are of the wrong kind (a point as a pose or the reverse) is an error naming the line.
/// - kIsam (iSAM, and GTSAM's load3D): `EDGE3 i j x y z roll pitch yaw` + 21 upper-triangle
///   entries, by default square-root information (iSAM's convention; GTSAM's load3D reads the
///   same numbers as information: pass NoiseFormat::kInformation to match it), over
///   [x y z roll pitch yaw]; `VERTEX3 id x y z roll pitch yaw` (GTSAM's) optional.
///   R = Rz(yaw) Ry(pitch) Rx(roll).
/// - kToro (TORO 3-D / HOG-Man): `VERTEX3` and `EDGE3` as iSAM's, the 21 entries information.
///
/// Quaternions: NaN or a norm further than kQuaternionNormTolerance from 1 is refused; within
/// it, the quaternion is normalised (one already unit to rounding is kept bit for bit, so a
/// written graph reads back exactly). Information must be finite, symmetric by construction, and
/// positive definite. A vertex id given twice, an edge from a vertex to itself, and (in a file
/// that lists vertices) an edge or FIX naming an unknown vertex are errors. A file that lists no
/// vertex (iSAM) is dead-reckoned: the first edge's first pose at the origin, then each edge
/// composed in file order.
///
/// options.rows: under kSkipAndCount a record that cannot be read is skipped, counted and
/// listed in the report (a truncated last line among them, reported by its line); more than
/// kMaxBadRowFraction of the records skipped is fatal, naming the first. A 2-D record (VERTEX_SE2,
/// EDGE2, ODOMETRY, ...) is fatal under both policies: "this is a 2-D graph".
PoseGraph3DRead parse_pose_graph_3d(std::istream& in, const PoseGraphReadOptions& options,
                                    const std::string& source = "<stream>");
/// As parse_pose_graph_3d; `path` must name a regular file (FileNotFound when nothing is there).
PoseGraph3DRead read_pose_graph_3d(const std::string& path, const PoseGraphReadOptions& options = {});

/// Writes g2o text (VERTEX_SE3:QUAT, VERTEX_TRACKXYZ, FIX, EDGE_SE3:QUAT, one PARAMS_SE3OFFSET
/// per distinct offset (0 the identity), EDGE_SE3_PRIOR and EDGE_SE3_TRACKXYZ) with 17
/// significant digits: it reads back to the same graph bit for bit. Vertex ids are checked unique and edge ends known first; std::invalid_argument
/// (and nothing written) otherwise.
void write_g2o_3d(std::ostream& out, const PoseGraph3DData& graph);
void write_g2o_3d(const std::string& path, const PoseGraph3DData& graph);

}  // namespace probslam
