#pragma once
// The row policy of the pose graph readers (2-D and 3-D) at work: a record's error is rethrown
// (RowPolicy::kStrict) or counted and listed in the report (kSkipAndCount); and the record loop
// both readers run under it.
#include <cstddef>
#include <istream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "probslam/io/pose_graph_file.hpp"
#include "noise_information.hpp"
#include "text_fields.hpp"

namespace probslam::io_detail {

// The row policy at work: a record's LineParseError is rethrown (strict) or counted, listed
// and remembered for the fatal message when there are too many (skip and count).
class RowLog {
 public:
  RowLog(RowPolicy policy, PoseGraphReadReport& report) : policy_(policy), report_(report) {}

  // Runs read(); false when it failed and the record was skipped.
  template <class Read>
  bool row(Read&& read) {
    try {
      read();
      return true;
    } catch (const LineParseError& e) {
      if (policy_ == RowPolicy::kStrict) throw;
      ++report_.skipped_rows;
      list_skipped_line(report_.skipped_lines, kPoseGraphMaxReportedLines, e.line(), e.reason());
      if (first_line_ == 0 || e.line() < first_line_) {
        first_line_ = e.line();
        first_what_ = e.what();
      }
      return false;
    }
  }

  // A record read after the information-repair policy changed its matrix (noise_information.hpp).
  void repaired(long line, double smallest_eigenvalue) {
    ++report_.repaired_rows;
    std::ostringstream reason;
    reason << "information not positive definite (smallest eigenvalue " << smallest_eigenvalue
           << "): eigenvalues raised to " << kInformationEigenvalueFloor << " of the largest";
    list_skipped_line(report_.repaired_lines, kPoseGraphMaxReportedLines, line, reason.str());
  }

  // The information the file gave, or its repair (counted) when it is not positive definite.
  template <int N>
  Eigen::Matrix<double, N, N> repair(const Eigen::Matrix<double, N, N>& information, long line) {
    const auto fixed = repaired_information<N>(information);
    if (!fixed) return information;
    repaired(line, fixed->smallest_eigenvalue);
    return fixed->information;
  }

  void require_few_skipped() const {
    if (static_cast<double>(report_.skipped_rows) <= kMaxBadRowFraction * static_cast<double>(report_.rows)) return;
    std::ostringstream what;
    what << first_what_ << " (" << report_.skipped_rows << " of " << report_.rows
         << " rows unreadable, more than kMaxBadRowFraction = " << kMaxBadRowFraction << ")";
    throw std::invalid_argument(what.str());
  }

 private:
  RowPolicy policy_;
  PoseGraphReadReport& report_;
  long first_line_ = 0;  // the first bad line in the file (build-time errors come after parse-time ones)
  std::string first_what_;
};

// The longest line read: a g2o / TORO / iSAM record is a few hundred bytes (a FIX line listing
// ids may be longer); a longer line is a corrupt or foreign file, refused before it is buffered.
constexpr std::size_t kPoseGraphMaxLineBytes = std::size_t{1} << 20;

// The record loop of both pose-graph readers: every record counted and read by
// Whether a reader's records hold point vertices apart from its vertices (the 3-D reader's do).
template <class Records, class = void>
struct has_points : std::false_type {};
template <class Records>
struct has_points<Records, std::void_t<decltype(std::declval<Records>().points)>> : std::true_type {};

// parse(fields, tag, format, line, err) under the row policy, the format detected from the first
// tag when it is kAuto. A record of the other dimension (is_other(tag)) is fatal under both
// policies, since no line of the file can be read: the message says "this is a <other> graph
// (TAG): <use>". Afterwards: too many bad rows, or records without vertices and edges, throw.
// Returns the format.
template <class Records, class IsOther, class Detect, class Parse>
PoseGraphFormat read_graph_records(std::istream& in, const std::string& source, PoseGraphFormat format,
                                   PoseGraphReadReport& report, RowLog& rows, const Records& records,
                                   const char* other, const char* use, IsOther&& is_other, Detect&& detect,
                                   Parse&& parse) {
  for_each_record(
      in, source,
      [&](const Fields& fields, const LineError& err, long line) {
        ++report.rows;
        const std::string tag(fields.token(0));
        if (is_other(tag))
          throw std::invalid_argument(source + ":" + std::to_string(line) + ": this is a " + other + " graph (" +
                                      tag + "): " + use);
        if (format == PoseGraphFormat::kAuto) format = detect(tag);
        rows.row([&] { parse(fields, tag, format, line, err); });
      },
      kPoseGraphMaxLineBytes);
  rows.require_few_skipped();
  // A file without records is an empty graph (what the writers write for one); records that
  // give neither a vertex nor an edge are not a graph.
  bool none = records.edges.empty() && records.vertices.empty();
  if constexpr (has_points<Records>::value) none = none && records.points.empty();
  if (report.rows > 0 && none)
    throw std::invalid_argument(source + ": no vertices or edges");
  return format;
}

}  // namespace probslam::io_detail
