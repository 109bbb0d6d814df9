#pragma once
// The row policy of the pose graph readers (2-D and 3-D) at work: a record's error is rethrown
// (RowPolicy::kStrict) or counted and listed in the report (kSkipAndCount).
#include <sstream>
#include <stdexcept>
#include <string>

#include "probslam/io/pose_graph_file.hpp"
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

}  // namespace probslam::io_detail
