#pragma once
// Line-oriented text parsing shared by the readers in src/io: whitespace tokens, numbers
// parsed strictly, and errors that name the source and line ("file:LINE: ...").
#include <charconv>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <istream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "../core/regular_file.hpp"
#include "probslam/core/check.hpp"

namespace probslam::io_detail {

using core_detail::NamedBy;
using core_detail::open_regular_file;
using core_detail::require_regular_file;

// A count larger than this in one message is corrupt, not data.
constexpr long kMaxCount = 1'000'000;

/// What LineError::fail throws: std::invalid_argument "source:LINE: reason", the line and the
/// reason also kept apart for a reader that skips a bad line (and counts it) rather than fails.
class LineParseError : public std::invalid_argument {
 public:
  LineParseError(const std::string& prefix, long line, const std::string& reason)
      : std::invalid_argument(prefix + reason), line_(line), reason_(reason) {}
  long line() const noexcept { return line_; }
  const std::string& reason() const noexcept { return reason_; }

 private:
  long line_;
  std::string reason_;
};

class LineError {
 public:
  LineError(const std::string& source, long line) : prefix_(source + ":" + std::to_string(line) + ": "), line_(line) {}
  [[noreturn]] void fail(const std::string& what) const { throw LineParseError(prefix_, line_, what); }

 private:
  std::string prefix_;
  long line_;
};

inline std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const std::size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

class Fields {
 public:
  Fields(const std::vector<std::string_view>& tokens, const LineError& err) : t_(tokens), err_(err) {}
  std::size_t size() const { return t_.size(); }
  std::string_view token(std::size_t i) const { return t_[i]; }
  void need(std::size_t n, const char* what) const {
    if (t_.size() < n)
      err_.fail(std::string(t_[0]) + " has " + std::to_string(t_.size()) + " fields, expected at least " +
                std::to_string(n) + " fields (" + what + ")");
  }
  double number(std::size_t i) const {
    double v = 0.0;
    const char* first = t_[i].data();
    const char* last = first + t_[i].size();
    if (*first == '+') ++first;
    const auto [ptr, ec] = std::from_chars(first, last, v);
    if (ec != std::errc() || ptr != last)
      err_.fail("field " + std::to_string(i + 1) + " ('" + std::string(t_[i]) + "') is not a number");
    return v;
  }
  double optional_number(std::size_t i) const {
    return i < t_.size() ? number(i) : std::numeric_limits<double>::quiet_NaN();
  }
  long count(std::size_t i) const {
    const double v = number(i);
    if (!(v >= 0 && v <= kMaxCount && v == std::floor(v)))
      err_.fail("field " + std::to_string(i + 1) + " ('" + std::string(t_[i]) + "') is not a valid count");
    return static_cast<long>(v);
  }
  long integer(std::size_t i) const {
    long v = 0;
    const char* first = t_[i].data();
    const char* last = first + t_[i].size();
    const auto [ptr, ec] = std::from_chars(first, last, v);
    if (ec != std::errc() || ptr != last)
      err_.fail("field " + std::to_string(i + 1) + " ('" + std::string(t_[i]) + "') is not an integer");
    return v;
  }

 private:
  const std::vector<std::string_view>& t_;
  const LineError& err_;
};

/// Reads one line of at most max_bytes into `line` (without its newline); false at the end.
/// A longer line is refused ("source:LINE: line longer than ...") before it is buffered.
inline bool read_bounded_line(std::istream& in, std::string& line, std::size_t max_bytes, const std::string& source,
                              long number) {
  line.clear();
  std::streambuf* buffer = in.rdbuf();
  if (buffer == nullptr) return false;
  bool any = false;
  for (;;) {
    const auto c = buffer->sbumpc();
    if (std::char_traits<char>::eq_int_type(c, std::char_traits<char>::eof())) {
      in.setstate(std::ios::eofbit);
      return any;
    }
    any = true;
    if (c == '\n') return true;
    if (line.size() >= max_bytes)
      LineError(source, number).fail("line longer than " + std::to_string(max_bytes) + " bytes");
    line.push_back(std::char_traits<char>::to_char_type(c));
  }
}

/// The compression whose magic number `head` (the first bytes of a file) starts with, or nullptr.
inline const char* compression_name(std::string_view head) {
  using namespace std::string_view_literals;
  if (head.substr(0, 2) == "\x1f\x8b"sv) return "gzip";
  if (head.size() >= 10 && head.substr(0, 3) == "BZh"sv && head[3] >= '1' && head[3] <= '9' &&
      (head.substr(4, 6) == "1AY&SY"sv || head.substr(4, 6) == "\x17rE8P\x90"sv))
    return "bzip2";
  if (head.substr(0, 6) == "\xfd" "7zXZ\0"sv) return "xz";
  if (head.substr(0, 4) == "\x28\xb5\x2f\xfd"sv) return "zstd";
  if (head.substr(0, 4) == "PK\x03\x04"sv) return "zip";
  return nullptr;
}

/// Throws std::invalid_argument in one line when `first_line` (the input's first line, or as
/// much of it as was read) shows that the input is not text: a compressed file's magic number,
/// or a NUL byte. Without it the reader would quote the binary bytes as a malformed line. Only
/// the first line is judged, so that a text file with a damaged line further on (a log cut off
/// by a crash, padded with NULs) is still read with that line skipped.
inline void reject_binary(std::string_view first_line, const std::string& source) {
  if (const char* compression = compression_name(first_line))
    throw std::invalid_argument(source + ": " + compression +
                                "-compressed data, not text: decompress it first (this reader takes plain text)");
  if (first_line.find('\0') != std::string_view::npos)
    throw std::invalid_argument(source + ": binary data (a NUL byte in the first line), not a text file");
}

/// Calls record(fields, error, line_number) for each line of `in` that is neither blank nor a
/// '#' comment; `error` prefixes messages with "source:LINE: ". With max_line_bytes, a longer
/// line is refused before it is buffered. Binary input (a compressed file, NUL bytes in the first
/// line) is refused in one line (reject_binary) rather than parsed.
template <class Record>
void for_each_record(std::istream& in, const std::string& source, Record&& record,
                     std::optional<std::size_t> max_line_bytes = std::nullopt) {
  std::string line;
  for (long line_number = 1;; ++line_number) {
    bool more = false;
    try {
      more = max_line_bytes ? read_bounded_line(in, line, *max_line_bytes, source, line_number)
                            : static_cast<bool>(std::getline(in, line));
    } catch (const LineParseError&) {  // too long a line: binary data says so first
      if (line_number == 1) reject_binary(line, source);
      throw;
    }
    if (!more) return;
    if (line_number == 1) reject_binary(line, source);
    const std::vector<std::string_view> tokens = split(line);
    if (tokens.empty() || tokens[0][0] == '#') continue;
    const LineError err(source, line_number);
    record(Fields(tokens, err), err, line_number);
  }
}

}  // namespace probslam::io_detail
