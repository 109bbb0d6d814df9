#pragma once
// Readers and a writer for 2-D pose/landmark graph files: g2o, TORO and iSAM text.
#include <istream>
#include <ostream>
#include <string>

#include "probslam/graph/pose_graph_2d.hpp"

namespace probslam {

enum class PoseGraphFormat {
  kAuto,  ///< from the first record: g2o tags, TORO VERTEX2, or iSAM ODOMETRY / LANDMARK / EDGE2
  kG2o,   ///< VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY (information, upper triangle), FIX
  kToro,  ///< VERTEX2, EDGE2 with information in TORO order (xx xy yy tt xt yt)
  kIsam,  ///< ODOMETRY / EDGE2 / LANDMARK with square-root information, upper triangle
};

/// Parses a graph; `source` names it in errors, which are std::invalid_argument
/// "source:LINE: ..." for a malformed line, an unknown tag, an unknown vertex id, or a bad
/// information matrix. Vertices a file does not list (iSAM files list none) are initialised
/// by composing the edges in file order from the first pose, placed at the origin: the
/// dead-reckoning guess.
PoseGraph2D parse_pose_graph(std::istream& in, PoseGraphFormat format = PoseGraphFormat::kAuto,
                             const std::string& source = "<stream>");
PoseGraph2D read_pose_graph(const std::string& path,
                            PoseGraphFormat format = PoseGraphFormat::kAuto);

/// Writes g2o text that reads back to the same graph, bit for bit (17 significant digits).
void write_g2o(std::ostream& out, const PoseGraph2D& graph);
void write_g2o(const std::string& path, const PoseGraph2D& graph);

}  // namespace probslam
