#pragma once
// Opening a file named by an argument, shared by the state files (core) and the readers (io):
// the path must name an existing regular file, checked before it is opened.
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

#include "probslam/core/check.hpp"

namespace probslam::core_detail {

/// Who names a file: the caller (a missing one is FileNotFound) or a file being read (a missing
/// one makes that file wrong: std::invalid_argument, as any other bad field).
enum class NamedBy { kCaller, kFile };

/// Throws unless `path` names an existing regular file (or a link to one): "ARG: cannot open
/// '<path>' (no such file)" when nothing is there, "ARG: cannot open '<path>' (reason)" when it
/// cannot be examined, "ARG: '<path>' is not a regular file" otherwise. Checked before opening: opening a fifo blocks until a writer comes, and a device
/// such as /dev/zero never ends.
inline void require_regular_file(const std::string& path, const char* arg, NamedBy named_by = NamedBy::kCaller) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (st.type() == std::filesystem::file_type::not_found) {
    const std::string what = std::string(arg) + ": cannot open '" + path + "' (no such file)";
    if (named_by == NamedBy::kCaller) throw FileNotFound(what);
    throw std::invalid_argument(what);
  }
  if (ec)  // there, but not reachable (a directory on the way without permission): not "missing"
    throw std::invalid_argument(std::string(arg) + ": cannot open '" + path + "' (" + ec.message() + ")");
  if (!std::filesystem::is_regular_file(st))
    throw std::invalid_argument(std::string(arg) + ": '" + path + "' is not a regular file");
}

/// The regular file `path` opened for reading (binary: the readers count bytes and lines
/// themselves), after require_regular_file(path, arg); "ARG: cannot open '<path>'" when it
/// cannot be opened all the same (no permission).
inline std::ifstream open_regular_file(const std::string& path, const char* arg) {
  require_regular_file(path, arg);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument(std::string(arg) + ": cannot open '" + path + "'");
  return in;
}

}  // namespace probslam::core_detail
