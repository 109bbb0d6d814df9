#pragma once
// Readers and a writer for 2-D pose/landmark graph files: g2o, TORO and iSAM text.
#include <cstddef>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include "probslam/graph/pose_graph_2d.hpp"
#include "probslam/io/skipped_line.hpp"

namespace probslam {

enum class PoseGraphFormat {
  kAuto,  ///< from the first record: g2o tags, TORO VERTEX2, or iSAM ODOMETRY / LANDMARK / EDGE2
  kG2o,   ///< VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY (information, upper triangle), FIX
  kToro,  ///< VERTEX2, EDGE2 with information in TORO order (xx xy yy tt xt yt), EQUIV
  kIsam,  ///< ODOMETRY / EDGE2 / LANDMARK with square-root information, upper triangle
};

/// What an edge's noise entries (the upper triangle, in the format's order) hold; the graph
/// keeps information. GTSAM's NoiseFormat is the model: the same text reads as different noise.
enum class NoiseFormat {
  kDefault,                ///< the format's own: information for g2o and TORO, kSquareRootInformation for iSAM
  kInformation,            ///< the information matrix Omega = C^-1
  kSquareRootInformation,  ///< the upper-triangular R with R^T R = Omega (iSAM's files)
  kCovariance,             ///< the covariance C (GTSAM's copy of Victoria Park); Omega = C^-1 by Cholesky
};

/// What a malformed row does.
enum class RowPolicy {
  kStrict,        ///< the first one is fatal: std::invalid_argument "source:LINE: reason"
  kSkipAndCount,  ///< skipped and counted (real data, docs/reliability.md); too many are fatal
};

/// Under RowPolicy::kSkipAndCount, a file with more than this fraction of its records skipped is
/// not in the format asked for (or is damaged beyond a few cut lines): it is refused, naming its
/// first bad line. Also the MRCLAM reader's limit (Python: probslam.graph.MAX_BAD_ROW_FRACTION).
constexpr double kMaxBadRowFraction = 0.01;
/// The information-repair policy: a record's information matrix that is finite and symmetric but
/// not positive definite gets its eigenvalues raised to at least this fraction of the largest
/// (eigenvectors kept), counted in PoseGraphReadReport::repaired_rows. 1e-6 keeps the doubtful
/// directions' weight six orders below the best-known one (negligible in the solution) while the
/// matrix stays well conditioned for Cholesky (condition number 1e6: ~6 of 16 digits lost).
constexpr double kInformationEigenvalueFloor = 1e-6;
/// How many skipped lines a PoseGraphReadReport lists (all are counted); as eval.MAX_REPORTED_LINES.
constexpr std::size_t kPoseGraphMaxReportedLines = 20;

/// What a TORO `EQUIV i j` record (i and j are one node: TORO's loader collapses them) does.
enum class Equivalences {
  kMerge,   ///< the two ids become one vertex, the smaller id (TORO keeps the lower id); edges
            ///< between them are dropped, the others re-attached to it
  kIgnore,  ///< counted and otherwise ignored (GTSAM's load2D skips the records)
};

struct PoseGraphReadOptions {
  PoseGraphFormat format = PoseGraphFormat::kAuto;
  NoiseFormat noise = NoiseFormat::kDefault;
  RowPolicy rows = RowPolicy::kStrict;
  Equivalences equivalences = Equivalences::kMerge;
};

/// What the reader did with the file's records (lines that are neither blank nor '#' comments).
struct PoseGraphReadReport {
  std::size_t rows = 0;          ///< records read, skipped ones included
  std::size_t skipped_rows = 0;  ///< records skipped (always 0 under RowPolicy::kStrict)
  std::vector<SkippedLine> skipped_lines;  ///< the first kPoseGraphMaxReportedLines of them
  std::size_t equivalences = 0;     ///< TORO EQUIV records read (applied or not: options.equivalences)
  std::size_t merged_vertices = 0;  ///< vertices merged into another by them
  std::size_t collapsed_edges = 0;  ///< edges dropped because both their ends became one vertex
  /// Records whose information matrix was not positive definite and was repaired (eigenvalues
  /// raised to a floor, src/io/noise_information.hpp), and the first kPoseGraphMaxReportedLines.
  std::size_t repaired_rows = 0;
  std::vector<SkippedLine> repaired_lines;
};

struct PoseGraphRead {
  PoseGraph2D graph;
  PoseGraphReadReport report;
};

/// Parses a graph; `source` names it in errors, which are std::invalid_argument
/// "source:LINE: ..." for a malformed line (or one longer than 1 MiB), an unknown tag, an
/// unknown vertex id, a non-finite value, or a bad information matrix. Vertices a file does
/// not list (iSAM files list none) are initialised by composing the edges in file order from
/// the first pose, placed at the origin: the dead-reckoning guess.
///
/// iSAM numbers poses and landmarks in two id spaces (its loader keeps two tables), the graph
/// in one (g2o's): when an iSAM file's landmark numbers meet its pose numbers, every landmark
/// becomes vertex (landmark + max pose id + 1 - min landmark id); its own number stays the
/// point's `landmark_id`. A file whose numbers do not meet (Victoria Park) keeps them as ids.
///
/// TORO `EQUIV i j` (Olson's w100 / w10000): under Equivalences::kMerge every id of a chain of
/// equivalences becomes its smallest one (the others' VERTEX2 values are dropped, their edges
/// re-attached, edges inside a chain dropped), whether or not an edge joins them; an EQUIV naming
/// an id no record uses is an error of its line. kIgnore keeps the graph as the VERTEX2 / EDGE2
/// records alone give it (what GTSAM's loader reads).
///
/// options.noise says what the edges' noise entries are (NoiseFormat). options.rows: under
/// kSkipAndCount a record that cannot be read (too few fields, a field that is not a number or
/// not an id, an unknown tag, a non-finite value, noise that is not positive definite, an
/// unknown vertex, an edge dead reckoning cannot reach because the rows before it were skipped)
/// is skipped and counted in the report; more than kMaxBadRowFraction of the records skipped is
/// fatal, naming the first. A line longer than 1 MiB, a file with no record, and iSAM landmark
/// ids that cannot be moved past the poses' are fatal under both policies.
PoseGraphRead parse_pose_graph(std::istream& in, const PoseGraphReadOptions& options,
                               const std::string& source = "<stream>");
/// Strict, with the format's own noise convention: the graph alone.
PoseGraph2D parse_pose_graph(std::istream& in, PoseGraphFormat format = PoseGraphFormat::kAuto,
                             const std::string& source = "<stream>");
/// As parse_pose_graph; `path` must name a regular file (a directory or a device is refused).
PoseGraphRead read_pose_graph(const std::string& path, const PoseGraphReadOptions& options);
PoseGraph2D read_pose_graph(const std::string& path,
                            PoseGraphFormat format = PoseGraphFormat::kAuto);

/// Writes g2o text that reads back to the same graph, bit for bit (17 significant digits).
/// g2o has one id space: points are written under their vertex ids (an iSAM landmark whose
/// number met a pose's appears under the id the reader gave it; see landmark_id).
void write_g2o(std::ostream& out, const PoseGraph2D& graph);
void write_g2o(const std::string& path, const PoseGraph2D& graph);

/// Writes iSAM text: pose edges (ODOMETRY when the edge introduces its second pose, EDGE2
/// otherwise), then LANDMARK edges under each point's landmark_id, information as its
/// upper-triangular square root. It reads back to the same ids in both id spaces and the same
/// edges (information to rounding, ~1e-16 relative). iSAM text holds no vertex values, no fixed
/// vertices and no vertex without an edge: reading it back dead-reckons the values from the
/// first pose at the origin. Throws std::invalid_argument (and writes nothing) when two points
/// share a landmark_id.
void write_isam(std::ostream& out, const PoseGraph2D& graph);
void write_isam(const std::string& path, const PoseGraph2D& graph);

}  // namespace probslam
