#pragma once
// MAP occupancy grid mapping with a forward model (ch. 9.4.2, Table 9.3): hill climbing on
// eq. 9.24, sum_t log p(z_t | x_t, m) + sum_i l0_i m_i, over binary maps.
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "probslam/core/types.hpp"
#include "probslam/grid/beam_sensor_model.hpp"
#include "probslam/grid/binary_map_2d.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

/// How Table 9.3 line 5 scores a candidate flip.
enum class FlipScoring {
  /// Re-scores only the readings whose footprint holds the cell (an index built once), and of
  /// those only the ones whose first occupied cell the flip moves.
  kIncremental,
  /// Re-evaluates eq. 9.24 from scratch, every reading's expected range cast again: the
  /// literal Table 9.3, the baseline of the incremental scorer.
  kFull,
};

struct MapMappingOptions {
  /// Table 9.3 line 3: at most this many sweeps over the perceptual field.
  int max_sweeps = 1000;
  FlipScoring scoring = FlipScoring::kIncremental;
  /// Stop after this many candidate flips have been scored (0: no limit); a stopped run is not
  /// converged. Lets a benchmark time the full scorer on a prefix of the run.
  std::size_t max_evaluations = 0;
  /// Keep the cell and the objective after every flip (MapMappingResult::trace_*).
  bool record_trace = false;
  /// Compute MapMappingResult::sensitivity (Fig. 9.8d) at the end.
  bool sensitivity = true;
  /// Called every few candidate flips (and before each when every flip rescans all readings);
  /// a caller that wants to stop a long run (the bindings, on Ctrl-C) makes it throw, and the
  /// exception leaves the call with nothing changed. Empty: never called.
  std::function<void()> interrupt;
  /// A flip is made only when it raises eq. 9.24 by more than this: the incremental deltas are
  /// sums of up to thousands of terms of magnitude ~10 with rounding ~1e-13 each, so a smaller
  /// "gain" is noise and could make two maps alternate for ever.
  static constexpr double kMinGain = 1e-9;

  /// Throws std::invalid_argument naming the first bad option.
  void validate() const;
};

struct MapMappingResult {
  std::vector<std::uint8_t> occupied;  // height x width, row-major, 1 = occupied
  double objective = 0.0;              // eq. 9.24 of `occupied`
  int sweeps = 0;                      // sweeps started
  bool converged = false;              // a whole sweep flipped nothing
  std::size_t flips = 0;
  std::size_t evaluations = 0;         // candidate flips scored (sensitivity not counted)
  std::size_t readings = 0;            // range readings used
  std::size_t field_cells = 0;         // cells in some reading's footprint: the cells visited
  std::vector<std::int32_t> field;     // those cells (row-major indices, increasing)
  std::size_t index_entries = 0;       // (reading, cell) pairs in the index
  /// Fig. 9.8d: the change of eq. 9.24 when each cell alone is flipped in the result (<= kMinGain
  /// at convergence); -|l0_i| outside the perceptual field. Empty unless options.sensitivity.
  std::vector<double> sensitivity;
  std::vector<std::int32_t> trace_cells;  // flipped cell (row-major index), in order
  std::vector<double> trace_objective;    // eq. 9.24 after that flip (the scorer's running value)
};

/// Table 9.3 on the lattice of `geometry` from the all-free map. poses (T x 3), ranges (T x B)
/// in metres (>= 0, not NaN; +inf or >= max_range: max readings), beam_angles (1 x B) shared or
/// (T x B), radians relative to each pose's heading. prior (height x width): p(m_i = 1), each
/// strictly between 0 and 1. The model's z_rand and z_max weights must be > 0, so every map
/// explains every reading with a finite log-likelihood. Cells in no reading's footprint are
/// never visited: they take the argmax of their prior (occupied iff l0_i > 0).
MapMappingResult map_occupancy_grid_mapping(const OccupancyGrid2D& geometry, const Eigen::Ref<const Poses2>& poses,
                                            const Eigen::Ref<const RowMatrixXd>& ranges,
                                            const Eigen::Ref<const RowMatrixXd>& beam_angles,
                                            const BeamSensorModel& model, const Eigen::Ref<const RowMatrixXd>& prior,
                                            const MapMappingOptions& options = {});

/// Eq. 9.24 of `map`: sum over readings of log p(z | x, m) (every expected range cast from
/// scratch) plus sum_i l0_i over the occupied cells. Arguments as map_occupancy_grid_mapping.
double map_log_posterior(const BinaryMap2D& map, const Eigen::Ref<const Poses2>& poses,
                         const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                         const BeamSensorModel& model, const Eigen::Ref<const RowMatrixXd>& prior);

}  // namespace probslam
