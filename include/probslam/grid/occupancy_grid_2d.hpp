#pragma once
// The 2-D occupancy grid of ch. 9.2 (Table 9.1) with a cone (Table 9.2) and a laser-beam
// (exact ray traversal, OctoMap's hit/miss rules) measurement update.
#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/core/types.hpp"
#include "probslam/grid/inverse_range_sensor_model.hpp"
#include "probslam/grid/log_odds.hpp"
#include "probslam/grid/ray_traversal.hpp"
#include "probslam/grid/scan_update.hpp"

namespace probslam {

class StateWriter;
class StateReader;

/// Regular lattice of a 2-D grid: axis 0 is x (columns), axis 1 is y (rows). Cell (i, j)
/// covers [x0 + j res, x0 + (j + 1) res) x [y0 + i res, y0 + (i + 1) res). Keys saturate at
/// +-kKeyBound (outside every grid) rather than overflow.
struct GridLattice2D {
  double x0 = 0.0, y0 = 0.0, res = 1.0, inv_res = 1.0;

  int key(int axis, double coord) const { return saturated_key((coord - (axis == 0 ? x0 : y0)) * inv_res); }
  double key_to_coord(int axis, int key) const { return (axis == 0 ? x0 : y0) + (key + 0.5) * res; }
  double resolution() const { return res; }
};

/// Sensor model of the laser-beam update: hit and miss probabilities (OctoMap's defaults).
struct BeamModel {
  double p_hit = 0.7;
  double p_miss = 0.4;
};

class OccupancyGrid2D {
 public:
  /// Grids of more cells are refused, whatever asks for them (constructor, covering, grown,
  /// OccupancyGrid3D::project_2d): 2^28 cells hold 2 GiB of log-odds and 1 GiB of scan stamps,
  /// a 1.6 km square at 10 cm; a larger request is almost always a bad bound or resolution, and
  /// would otherwise exhaust memory instead of raising.
  static constexpr std::int64_t kMaxCells = std::int64_t{1} << 28;
  /// Cell borders are x0 + k res in double: a cell narrower than this fraction of the grid's
  /// largest coordinate (or of 1 m) would span only a few ulps, and neighbouring cells would
  /// share borders. Finer resolutions are refused.
  static constexpr double kMinRelativeResolution = 1e-9;
  /// cell_index refuses points whose index exceeds this magnitude: beyond 2^53 a double has no
  /// fractional part, so the index is no longer that of one cell.
  static constexpr double kMaxCellIndex = 9007199254740992.0;  // 2^53

  /// Lock it around every call when several threads share this object (core/object_mutex.hpp).
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  /// resolution (m per cell), width x height cells, origin (m) of cell (0, 0)'s lower-left
  /// corner, prior occupancy p_prior (l0 = logit(p_prior)). Clamping defaults to OctoMap's
  /// [0.1192, 0.971]; LogOddsClamp::none() gives the textbook update.
  OccupancyGrid2D(double resolution, int width, int height, const Eigen::Vector2d& origin = {0, 0},
                  double p_prior = 0.5,
                  const LogOddsClamp& clamp = LogOddsClamp::from_probabilities(0.1192, 0.971));

  /// A grid of the given resolution covering [xmin, xmax] x [ymin, ymax] (metres).
  static OccupancyGrid2D covering(double xmin, double ymin, double xmax, double ymax,
                                  double resolution, double p_prior = 0.5,
                                  const LogOddsClamp& clamp = LogOddsClamp::from_probabilities(0.1192, 0.971));

  double resolution() const { return lattice_.res; }
  int width() const { return width_; }
  int height() const { return height_; }
  Eigen::Vector2d origin() const { return {lattice_.x0, lattice_.y0}; }
  double p_prior() const { return p_prior_; }
  double prior_log_odds() const { return l0_; }
  const LogOddsClamp& clamp() const { return clamp_; }
  void set_clamp(const LogOddsClamp& clamp);
  const BeamModel& beam_model() const { return beam_; }
  void set_beam_model(const BeamModel& beam);
  const GridLattice2D& lattice() const { return lattice_; }

  /// Log-odds, row-major (height x width); row i holds cells of increasing x at y-row i.
  double* data() { return log_odds_.data(); }
  const double* data() const { return log_odds_.data(); }
  Eigen::Map<RowMatrixXd> log_odds() { return {log_odds_.data(), height_, width_}; }
  Eigen::Map<const RowMatrixXd> log_odds() const { return {log_odds_.data(), height_, width_}; }
  /// Occupancy probability of every cell, eq. 9.6.
  RowMatrixXd probability() const;

  bool contains(int row, int col) const {
    return static_cast<unsigned>(row) < static_cast<unsigned>(height_) &&
           static_cast<unsigned>(col) < static_cast<unsigned>(width_);
  }
  /// (row, col) of the cell containing (x, y); may lie outside the grid. Indices saturate at
  /// +-kKeyBound (2^30), which is outside every grid: use cell_index for the exact index.
  Eigen::Vector2i cell_of(double x, double y) const { return {lattice_.key(1, y), lattice_.key(0, x)}; }
  /// (row, col) of the cell containing (x, y) as exact 64-bit indices. Throws
  /// std::invalid_argument naming `name` when (x, y) is not finite or an index exceeds
  /// kMaxCellIndex in magnitude.
  Eigen::Matrix<std::int64_t, 2, 1> cell_index(double x, double y, const char* name = "points") const;
  /// Centre of mass (x, y) of cell (row, col).
  Eigen::Vector2d cell_center(int row, int col) const {
    return {lattice_.key_to_coord(0, col), lattice_.key_to_coord(1, row)};
  }

  /// Table 9.1 with the cone model of Table 9.2: l += ism - l0 for every cell in the
  /// perceptual field (ism != l0); only cells within z_max of the pose are visited. Returns
  /// the number of cells changed. Invalid readings (NaN, inf, < 0) are left out.
  std::size_t insert_cone_scan(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                               const Eigen::Ref<const Eigen::VectorXd>& beam_angles, double z_max,
                               double alpha, double beta, double l_occ, double l_free);

  /// Laser-beam update (see apply_scan): readings < max_range hit their end cell and clear
  /// the cells before it; readings >= max_range clear up to max_range and mark nothing;
  /// NaN, infinite and negative readings are skipped. Each ray is clipped to the grid before it
  /// is walked, so it costs what its part inside the grid costs, whatever max_range is (a ray
  /// that never enters the grid costs O(1)). Returns the number of cells updated.
  std::size_t insert_rays(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                          const Eigen::Ref<const Eigen::VectorXd>& beam_angles, double max_range);

  /// insert_rays for each scan: poses (S x 3), ranges (S x B), beam_angles (B) or (S x B).
  /// Every row is validated before the first is applied.
  std::size_t insert_scans(const Eigen::Ref<const Poses2>& poses, const Eigen::Ref<const RowMatrixXd>& ranges,
                           const Eigen::Ref<const RowMatrixXd>& beam_angles, double max_range);

  /// The robot's footprint (cells whose centre lies within radius of the pose) is free
  /// space: l += l_free - l0 there (ch. 9.2). Returns the number of cells changed.
  std::size_t clear_footprint(const Eigen::Vector3d& pose, double radius, double l_free);

  /// Table 9.1 line 4 with an inverse sensor model evaluated elsewhere (e.g. a learned one,
  /// ch. 9.3): l_i += deltas[k] for the cell of flat index cells[k] (row * width + col), clamped
  /// as every update. Every index and delta is checked before any cell changes. Returns the
  /// number of cells updated.
  std::size_t add_log_odds(const std::vector<long>& cells, const Eigen::Ref<const Eigen::VectorXd>& deltas);

  /// A copy enlarged, on the same lattice, to cover [xmin, xmax] x [ymin, ymax]; new cells
  /// hold the prior. The grid never shrinks.
  OccupancyGrid2D grown_to_include(double xmin, double ymin, double xmax, double ymax) const;

  bool same_geometry(const OccupancyGrid2D& other) const;

  /// Saves every parameter and cell, bit for bit (docs/file_format.md); load refuses anything
  /// but a complete, undamaged OccupancyGrid2D state (std::invalid_argument naming the path).
  /// The laser-beam update's per-scan cell stamps are not saved: they only keep one scan from
  /// updating a cell twice, and a loaded grid starts a fresh count with the same effect.
  static constexpr const char* kStateTag = "OccupancyGrid2D";
  void save(const std::string& path) const;
  static OccupancyGrid2D load(const std::string& path);
  void write_state(StateWriter& w) const;
  static OccupancyGrid2D read_state(StateReader& r);

 private:
  friend class GridScanStore;
  /// insert_rays after its arguments have been checked.
  std::size_t insert_rays_checked(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                  const Eigen::Ref<const Eigen::VectorXd>& beam_angles, double max_range);
  void update_cell(std::size_t index, double delta) {
    log_odds_[index] = clamp_.apply(log_odds_[index] + delta);
  }

  GridLattice2D lattice_;
  int width_ = 0, height_ = 0;
  double p_prior_ = 0.5, l0_ = 0.0;
  LogOddsClamp clamp_;
  BeamModel beam_;
  std::vector<double> log_odds_;
  std::vector<std::uint32_t> stamp_;  // scan counter of each cell's last laser-beam update
  std::uint32_t scan_counter_ = 0;
  ObjectMutex mutex_;
};

/// A laser scan's rays as the segments apply_scan walks (grid/scan_update.hpp).
struct LaserSegments2D {
  double origin[2] = {0.0, 0.0};
  std::vector<double> ends;           // x, y of each ray's end
  std::vector<std::uint8_t> is_hit;   // 1 where the ray ends in an obstacle
  ScanSegments<2, double> view() const { return {origin, ends.data(), is_hit.data(), is_hit.size()}; }
};

/// std::invalid_argument unless pose and beam_angles are finite and ranges is non-empty and as
/// long as beam_angles (ranges themselves may hold invalid readings: they are skipped).
void check_scan_shape(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                      const Eigen::Ref<const Eigen::VectorXd>& beam_angles);

/// insert_rays' rays for a grid of this lattice and size: readings < max_range hit their end,
/// readings >= max_range clear up to max_range, NaN / inf / negative readings are left out, and
/// a ray far longer than the grid's reach is cut (its end then lies outside, no hit). Returns
/// false (out left empty) when the scan lies farther than max_range from the grid. Arguments
/// must have passed check_scan_shape and max_range > 0.
bool laser_segments(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose,
                    const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                    double max_range, LaserSegments2D& out);

/// Eq. 9.9: the most pessimistic map (cell-wise maximum occupancy) of grids of equal geometry.
OccupancyGrid2D fuse_max(const std::vector<const OccupancyGrid2D*>& grids);
/// One step of fuse_max: fused becomes the cell-wise maximum of fused and other (same geometry).
void fuse_max_into(OccupancyGrid2D& fused, const OccupancyGrid2D& other);

}  // namespace probslam
