#pragma once
// Reader for CARMEN robot logs (.log / .clf): FLASER, ROBOTLASER1, ODOM and PARAM lines.
#include <Eigen/Core>
#include <istream>
#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "probslam/io/skipped_line.hpp"

namespace probslam {

/// Laser scans of a log, one row per scan. Rows with fewer beams than the widest scan are
/// padded with NaN (which the grid updates skip). The padding is bounded: scans so much wider
/// than the rest that padding to them would exceed 4x the beams read (plus 2^20 cells) are
/// skipped and counted in CarmenLog::skipped_wide_scans.
struct LaserScans {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> ranges;  // (S, B), metres
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> laser_poses;          // (S, 3)
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> robot_poses;          // (S, 3)
  Eigen::VectorXd start_angles;        // (S,) bearing of beam 0 relative to the laser, rad
  Eigen::VectorXd angular_resolutions;  // (S,) rad between beams
  Eigen::VectorXd max_ranges;           // (S,) sensor maximum, NaN where the log does not say
  Eigen::VectorXi num_beams;            // (S,)
  Eigen::VectorXd timestamps;           // (S,) logger timestamp (see CarmenLog), NaN where absent
  Eigen::VectorXd ipc_timestamps;       // (S,) ipc timestamp, NaN where absent
};

struct Odometry {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> poses;  // (M, 3)
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> velocities;  // (M, 2): tv m/s, rv rad/s
  Eigen::VectorXd timestamps;      // (M,) logger timestamp, as LaserScans
  Eigen::VectorXd ipc_timestamps;  // (M,) ipc timestamp
};

/// How many skipped lines a CarmenLog lists (all are counted); as eval.MAX_REPORTED_LINES.
constexpr std::size_t kCarmenMaxReportedLines = 20;

struct CarmenLog {
  LaserScans scans;
  Odometry odometry;
  std::map<std::string, std::string> params;
  std::size_t skipped_wide_scans = 0;  // scans dropped to bound the padding (see LaserScans)
  /// Malformed lines skipped (see parse_carmen_log), and the first kCarmenMaxReportedLines of them.
  std::size_t skipped_rows = 0;
  std::vector<SkippedLine> skipped_lines;
};

/// Parses a log from a stream; `source` names it in error messages.
/// Row-level (skipped, counted in skipped_rows, the first listed in skipped_lines): a FLASER,
/// ROBOTLASER1, ODOM or PARAM line that does not parse (too few fields, a beam count larger than
/// the fields present as in a line cut off mid-write, a field that is not a number), and a line
/// whose first field is not a message name (upper-case letters, digits, '_' or '-', starting
/// with a letter); scans far wider than the rest (counted in skipped_wide_scans, see LaserScans).
/// Fatal: a log with no valid scan at all (std::invalid_argument "source: no laser scan ...",
/// with the number of lines skipped and the first of them as "source:LINE: reason"), and a read
/// error (std::runtime_error).
/// Times: every record ends `ipc_timestamp ipc_hostname logger_timestamp`; a record's time
/// (`timestamps`) is the logger stamp, the one clock of the whole log (monotone from the start of
/// logging; the corrected Radish logs carry their raw log's logger stamps), read from the end of
/// the line. The ipc stamp (the sending host's clock, which the Freiburg relations files use) is
/// kept in `ipc_timestamps`; a record that ends before its logger stamp has its ipc stamp as its
/// time, and NaN for both when it has no stamp.
/// Other message types are ignored (RAWLASER1 too: it carries no pose). FLASER beams start at -90 degrees and step by
/// PARAM laser_front_laser_resolution (degrees) when the log gives it, else by 180 degrees /
/// n for even n and 180 degrees / (n - 1) for odd n (so 181 and 361 beams include both ends).
CarmenLog parse_carmen_log(std::istream& in, const std::string& source = "<stream>");
/// Reads a plain-text log file (decompress .gz / .bz2 first). `path` must be a regular file
/// (std::invalid_argument otherwise, as for a missing file).
CarmenLog read_carmen_log(const std::string& path);

}  // namespace probslam
