#include "probslam/io/carmen_log.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "probslam/core/angle.hpp"
#include "text_fields.hpp"

namespace probslam {
namespace {

using io_detail::Fields;
using io_detail::LineError;
using io_detail::LineParseError;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kDegree = kPi / 180.0;

// The scans are returned padded to the widest one kept. A log mixing widths (a front laser of
// 181 and a rear one of 361 beams) pads by less than 2x; padding beyond this factor of the beams
// read, plus kPaddingAllowance cells so that small logs always load, comes from a few scans far
// wider than the rest. Those are skipped and counted: without the bound 255 kB of text (one
// 60000-beam scan among thousands of empty ones) asked for 1.9 GB.
constexpr double kMaxPaddingFactor = 4.0;
constexpr double kPaddingAllowance = double(1 << 20);  // cells: 8 MiB of doubles

/// A CARMEN message name: an upper-case letter, then upper-case letters, digits, '_' or '-'
/// (ODOM, FLASER, ROBOTLASER1, RAWLASER1, NMEAGGA, ...). A line starting with anything else is
/// not a message (a corrupt line), unlike a message type this reader does not use.
bool is_message_name(std::string_view token) {
  if (token.empty() || !(token[0] >= 'A' && token[0] <= 'Z')) return false;
  return std::all_of(token.begin(), token.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
}

/// A record's times from its trailer `ipc_timestamp ipc_hostname logger_timestamp`, read from
/// the end of the line when the record has its own `fields` and the three after them (older
/// ROBOTLASER1 lines omit some of their own trailing fields). The record's time is the logger
/// stamp: the clock of every record of the log (the corrected Radish logs carry it, their ipc
/// stamps copied from it), where the ipc stamp is the sending host's; a record that ends before
/// the logger stamp keeps its ipc stamp (NaN both when it has neither).
struct Stamps {
  double time, ipc;
};
Stamps record_stamps(const Fields& f, std::size_t fields) {
  if (f.size() >= fields + 3) return {f.number(f.size() - 1), f.number(f.size() - 3)};
  const double ipc = f.optional_number(fields);
  return {ipc, ipc};
}

struct ScanRow {
  std::vector<double> ranges;
  double laser[3], robot[3];
  double start, step, max_range;
  Stamps stamps;
};

constexpr int kOdomWidth = 7;  // an ODOM row: x y theta tv rv time ipc_time

struct Builder {
  std::vector<ScanRow> scans;
  std::vector<double> odom;  // x y theta tv rv t ipc_t
  std::map<std::string, std::string> params;
  std::size_t skipped_rows = 0;
  std::vector<SkippedLine> skipped_lines;

  void skip(long line, const std::string& reason) {
    ++skipped_rows;
    list_skipped_line(skipped_lines, kCarmenMaxReportedLines, line, reason);
  }

  double flaser_step(long n) const {
    const auto it = params.find("laser_front_laser_resolution");
    if (it != params.end()) {
      try {
        const double deg = std::stod(it->second);
        if (deg > 0 && std::isfinite(deg)) return deg * kDegree;
      } catch (const std::exception&) {
      }  // fall through to the beam-count rule
    }
    const long intervals = (n % 2 == 0) ? n : n - 1;
    return intervals > 0 ? kPi / intervals : 0.0;
  }

  // FLASER n r_1..r_n x y theta odom_x odom_y odom_theta [ipc_ts host logger_ts]
  void flaser(const Fields& f) {
    f.need(2, "beam count");
    const long n = f.count(1);
    f.need(2 + n + 6, "ranges and two poses");
    ScanRow s;
    s.ranges.resize(n);
    for (long i = 0; i < n; ++i) s.ranges[i] = f.number(2 + i);
    for (int k = 0; k < 3; ++k) {
      s.laser[k] = f.number(2 + n + k);
      s.robot[k] = f.number(2 + n + 3 + k);
    }
    s.step = flaser_step(n);
    s.start = -s.step * ((n % 2 == 0) ? n : n - 1) / 2.0;
    s.max_range = kNaN;
    s.stamps = record_stamps(f, 2 + n + 6);
    scans.push_back(std::move(s));
  }

  // ROBOTLASER1 type start fov res max_range accuracy remission_mode n r.. n_rem rem.. laser(3) robot(3) ...
  void robotlaser(const Fields& f) {
    f.need(9, "laser parameters and beam count");
    const long n = f.count(8);
    f.need(9 + n + 1, "ranges and remission count");
    const long n_rem = f.count(9 + n);
    const std::size_t pose_at = 10 + n + n_rem;
    f.need(pose_at + 6, "remissions and two poses");
    ScanRow s;
    s.ranges.resize(n);
    for (long i = 0; i < n; ++i) s.ranges[i] = f.number(9 + i);
    for (int k = 0; k < 3; ++k) {
      s.laser[k] = f.number(pose_at + k);
      s.robot[k] = f.number(pose_at + 3 + k);
    }
    s.start = f.number(2);
    s.step = f.number(4);
    s.max_range = f.number(5);
    s.stamps = record_stamps(f, pose_at + 6);
    scans.push_back(std::move(s));
  }

  // ODOM x y theta tv rv accel [ipc_ts host logger_ts]
  void odometry(const Fields& f) {
    f.need(7, "pose, velocities and acceleration");
    double row[kOdomWidth];  // parsed whole before it is kept: a bad field skips the line, not half of it
    for (int k = 1; k <= 5; ++k) row[k - 1] = f.number(k);
    const Stamps stamps = record_stamps(f, 7);
    row[5] = stamps.time;
    row[6] = stamps.ipc;
    odom.insert(odom.end(), row, row + kOdomWidth);
  }

  /// The widest scan width whose padded matrix stays within the bound above.
  std::size_t padded_width() const {
    std::vector<std::size_t> widths;
    widths.reserve(scans.size());
    for (const ScanRow& s : scans) widths.push_back(s.ranges.size());
    std::sort(widths.begin(), widths.end());
    double beams = 0.0;
    for (std::size_t w : widths) beams += static_cast<double>(w);
    std::size_t kept = widths.size();  // widths[0, kept) are kept
    while (kept > 0) {
      const std::size_t width = widths[kept - 1];
      if (static_cast<double>(kept) * width <= kMaxPaddingFactor * beams + kPaddingAllowance) return width;
      for (; kept > 0 && widths[kept - 1] == width; --kept) beams -= static_cast<double>(width);
    }
    return 0;
  }

  CarmenLog finish() {
    CarmenLog log;
    log.params = std::move(params);
    log.skipped_rows = skipped_rows;
    log.skipped_lines = std::move(skipped_lines);
    const std::size_t width = padded_width();
    const std::size_t before = scans.size();
    scans.erase(std::remove_if(scans.begin(), scans.end(), [&](const ScanRow& s) { return s.ranges.size() > width; }),
                scans.end());
    log.skipped_wide_scans = before - scans.size();
    const Eigen::Index s_count = static_cast<Eigen::Index>(scans.size());
    LaserScans& out = log.scans;
    out.ranges.setConstant(s_count, static_cast<Eigen::Index>(width), kNaN);
    out.laser_poses.resize(s_count, 3);
    out.robot_poses.resize(s_count, 3);
    out.start_angles.resize(s_count);
    out.angular_resolutions.resize(s_count);
    out.max_ranges.resize(s_count);
    out.num_beams.resize(s_count);
    out.timestamps.resize(s_count);
    out.ipc_timestamps.resize(s_count);
    for (Eigen::Index i = 0; i < s_count; ++i) {
      const ScanRow& s = scans[i];
      for (std::size_t b = 0; b < s.ranges.size(); ++b) out.ranges(i, b) = s.ranges[b];
      for (int k = 0; k < 3; ++k) {
        out.laser_poses(i, k) = s.laser[k];
        out.robot_poses(i, k) = s.robot[k];
      }
      out.start_angles[i] = s.start;
      out.angular_resolutions[i] = s.step;
      out.max_ranges[i] = s.max_range;
      out.num_beams[i] = static_cast<int>(s.ranges.size());
      out.timestamps[i] = s.stamps.time;
      out.ipc_timestamps[i] = s.stamps.ipc;
    }
    const Eigen::Index m = static_cast<Eigen::Index>(odom.size() / kOdomWidth);
    log.odometry.poses.resize(m, 3);
    log.odometry.velocities.resize(m, 2);
    log.odometry.timestamps.resize(m);
    log.odometry.ipc_timestamps.resize(m);
    for (Eigen::Index i = 0; i < m; ++i) {
      const double* o = &odom[kOdomWidth * i];
      log.odometry.poses.row(i) << o[0], o[1], o[2];
      log.odometry.velocities.row(i) << o[3], o[4];
      log.odometry.timestamps[i] = o[5];
      log.odometry.ipc_timestamps[i] = o[6];
    }
    return log;
  }
};

}  // namespace

CarmenLog parse_carmen_log(std::istream& in, const std::string& source) {
  Builder builder;
  io_detail::for_each_record(in, source, [&](const Fields& fields, const LineError& err, long) {
    const std::string_view type = fields.token(0);
    try {
      if (type == "FLASER") {
        builder.flaser(fields);
      } else if (type == "ROBOTLASER1") {
        builder.robotlaser(fields);
      } else if (type == "ODOM") {
        builder.odometry(fields);
      } else if (type == "PARAM") {
        fields.need(3, "name and value");
        builder.params[std::string(fields.token(1))] = std::string(fields.token(2));
      } else if (!is_message_name(type)) {
        err.fail("'" + std::string(type.substr(0, 40)) + "' is not a CARMEN message name");
      }
    } catch (const LineParseError& e) {  // row-level: the line is skipped and counted
      builder.skip(e.line(), e.reason());
    }
  });
  if (in.bad()) throw std::runtime_error(source + ": read error");
  if (builder.scans.empty()) {
    std::string what = source + ": no laser scan (FLASER or ROBOTLASER1) could be read";
    if (builder.skipped_rows > 0) {
      const SkippedLine& first = builder.skipped_lines.front();
      what += "; " + std::to_string(builder.skipped_rows) + " malformed line" + (builder.skipped_rows == 1 ? "" : "s") +
              " skipped, the first " + source + ":" + std::to_string(first.line) + ": " + first.reason;
    } else {
      what += " (the log holds none)";
    }
    throw std::invalid_argument(what);
  }
  return builder.finish();
}

CarmenLog read_carmen_log(const std::string& path) {
  std::ifstream in = io_detail::open_regular_file(path, "path");
  return parse_carmen_log(in, path);
}

}  // namespace probslam
