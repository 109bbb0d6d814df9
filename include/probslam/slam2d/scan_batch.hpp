#pragma once
// add_scans of the laser SLAM classes: every row is checked with the class's own check_scan
// before the first row is added; a row refused on the object's state (a map limit, a memory
// bound) restores the snapshot taken before the batch, so a batch is applied whole or not at all.
#include <Eigen/Core>
#include <string>
#include <utility>

#include "probslam/core/check.hpp"
#include "probslam/core/types.hpp"

namespace probslam {

/// f(); should it throw, `mapper` is put back as it was before (its snapshot() and
/// restore(snapshot)) and the exception passed on: all or nothing.
template <typename Mapper, typename F>
void all_or_nothing(Mapper& mapper, F&& f) {
  auto before = mapper.snapshot();
  try {
    f();
  } catch (...) {
    mapper.restore(std::move(before));
    throw;
  }
}

/// ranges (S, B), beam_angles (1, B) shared by every scan or (S, B), odometry (S, 3),
/// timestamps (S,). Mapper has check_scan(ranges, angles, odometry, timestamp, row),
/// add_scan(ranges, angles, odometry, timestamp), snapshot() and restore(snapshot).
template <typename Mapper>
void add_scan_rows(Mapper& mapper, const Eigen::Ref<const RowMatrixXd>& ranges,
                   const Eigen::Ref<const RowMatrixXd>& beam_angles, const Eigen::Ref<const RowMatrixXd>& odometry,
                   const Eigen::Ref<const Eigen::VectorXd>& timestamps) {
  const Eigen::Index S = ranges.rows();
  require(odometry.rows() == S && odometry.cols() == 3, "odometry", "must have shape (S, 3), one row per scan");
  require(timestamps.size() == S, "timestamps", "must have one value per scan");
  require((beam_angles.rows() == 1 || beam_angles.rows() == S) && beam_angles.cols() == ranges.cols(), "beam_angles",
          "must have shape (B,) or (S, B)");
  auto angles = [&](Eigen::Index k) { return beam_angles.row(beam_angles.rows() == 1 ? 0 : k).transpose(); };
  for (Eigen::Index k = 0; k < S; ++k)
    mapper.check_scan(ranges.row(k).transpose(), angles(k), odometry.row(k).transpose(), timestamps[k],
                      static_cast<long>(k));
  if (S == 0) return;
  if (S == 1) {  // add_scan alone is all or nothing: no snapshot needed
    mapper.add_scan(ranges.row(0).transpose(), angles(0), odometry.row(0).transpose(), timestamps[0]);
    return;
  }
  all_or_nothing(mapper, [&] {  // rule: all or nothing, for the whole batch
    for (Eigen::Index k = 0; k < S; ++k)
      mapper.add_scan(ranges.row(k).transpose(), angles(k), odometry.row(k).transpose(), timestamps[k]);
  });
}

}  // namespace probslam
