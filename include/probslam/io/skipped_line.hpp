#pragma once
// What the text readers report about lines they skipped under a skip-and-count policy.
#include <cstddef>
#include <string>
#include <vector>

namespace probslam {

/// A line the reader skipped: its number (1-based) and why.
struct SkippedLine {
  long line = 0;
  std::string reason;
};

/// A skipped line's reason quotes the field that failed; a field of a corrupt line can be long,
/// so a reason is cut to this many bytes (and "..." appended) before it is kept.
constexpr std::size_t kMaxSkipReasonBytes = 200;

/// Appends (line, reason) to `lines` unless it already lists `max_lines`: readers count every
/// skipped line but list only the first few, so a file of garbage cannot fill memory with reasons.
inline void list_skipped_line(std::vector<SkippedLine>& lines, std::size_t max_lines, long line,
                              const std::string& reason) {
  if (lines.size() >= max_lines) return;
  const bool whole = reason.size() <= kMaxSkipReasonBytes;
  lines.push_back({line, whole ? reason : reason.substr(0, kMaxSkipReasonBytes) + "..."});
}

}  // namespace probslam
