#pragma once
// The laser SLAM classes' option structs as state (docs/file_format.md): one writer and reader
// per struct, shared by every class that holds one. Readers return the values as saved; the
// owner's constructor validates them.
#include "probslam/core/state_file.hpp"
#include "probslam/graph/graph_optimizer.hpp"
#include "probslam/slam2d/incremental_scan_matcher.hpp"

namespace probslam::state_detail {

void write(StateWriter& w, const ScanFilter& o);
void read(StateReader& r, ScanFilter& o);
void write(StateWriter& w, const LikelihoodFieldOptions& o);
void read(StateReader& r, LikelihoodFieldOptions& o);
void write(StateWriter& w, const MatchOptions& o);
void read(StateReader& r, MatchOptions& o);
void write(StateWriter& w, const OdometryNoise& o);
void read(StateReader& r, OdometryNoise& o);
void write(StateWriter& w, const IncrementalScanMatcherOptions& o);
void read(StateReader& r, IncrementalScanMatcherOptions& o);
void write(StateWriter& w, const OptimizerOptions& o);
void read(StateReader& r, OptimizerOptions& o);

/// An enum stored as one byte, refused beyond `last`.
template <typename E>
void write_enum(StateWriter& w, E e) {
  w.u8(static_cast<std::uint8_t>(e));
}
template <typename E>
E read_enum(StateReader& r, E last, const char* what) {
  const std::uint8_t v = r.u8();
  if (v > static_cast<std::uint8_t>(last)) r.fail(std::string(what) + " holds an unknown value " + std::to_string(v));
  return static_cast<E>(v);
}

}  // namespace probslam::state_detail
