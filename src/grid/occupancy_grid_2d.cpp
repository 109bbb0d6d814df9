#include "probslam/grid/occupancy_grid_2d.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "probslam/core/check.hpp"
#include "probslam/grid/scan_update.hpp"

namespace probslam {
namespace {

// A ray longer than this many times the grid's reach from the sensor (its farthest corner) is
// cut to that length before its end point is computed: it leaves the grid either way, and its
// end stays finite (a range of 1e308 would overflow). Rays up to it are walked exactly as given.
constexpr double kRayCutSlack = 1024.0;

// Refuses a grid of w x h cells (as doubles: they may come from arbitrary bounds) beyond kMaxCells.
void check_cell_count(double w, double h, const char* name) {
  if (w * h <= static_cast<double>(OccupancyGrid2D::kMaxCells)) return;
  char text[96];
  std::snprintf(text, sizeof text, "asks for %.6g x %.6g cells, more than OccupancyGrid2D.max_cells = ", w, h);
  throw_invalid_argument(name, text + std::to_string(OccupancyGrid2D::kMaxCells));
}

// The lattice must map coordinates to cells and back without overflow or coinciding borders.
void check_lattice(double resolution, int width, int height, const Eigen::Vector2d& origin) {
  require_positive(resolution, "resolution");
  require(std::isfinite(1.0 / resolution), "resolution", "must have a finite inverse");
  require_all_finite(origin, "origin");
  const double x1 = origin.x() + width * resolution, y1 = origin.y() + height * resolution;
  require(std::isfinite(x1) && std::isfinite(y1), "resolution", "* width (height) + origin must be finite");
  const double magnitude = std::max({1.0, std::fabs(origin.x()), std::fabs(origin.y()), std::fabs(x1), std::fabs(y1)});
  require(resolution >= OccupancyGrid2D::kMinRelativeResolution * magnitude, "resolution",
          "must be at least 1e-9 of the grid's largest coordinate (and 1e-9 m): finer cells would "
          "share borders in double precision");
}

void check_clamp(const LogOddsClamp& clamp) {
  if (!clamp.enabled) return;
  require(std::isfinite(clamp.min) && std::isfinite(clamp.max) && clamp.min < clamp.max, "clamp",
          "must be two probabilities (p_min < p_max) strictly between 0 and 1");
}

void check_bounds(double xmin, double ymin, double xmax, double ymax) {
  require(std::isfinite(xmin) && std::isfinite(xmax) && xmin <= xmax, "xmin", "must be finite and <= xmax");
  require(std::isfinite(ymin) && std::isfinite(ymax) && ymin <= ymax, "ymin", "must be finite and <= ymax");
}

}  // namespace

void check_scan_shape(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                      const Eigen::Ref<const Eigen::VectorXd>& beam_angles) {
  require_all_finite(pose, "pose");
  require(ranges.size() > 0, "ranges", "must not be empty");
  require(ranges.size() == beam_angles.size(), "beam_angles", "must have the same length as ranges");
  require_all_finite(beam_angles, "beam_angles");
}

bool laser_segments(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose,
                    const Eigen::Ref<const Eigen::VectorXd>& ranges, const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                    double max_range, LaserSegments2D& out) {
  out.origin[0] = pose.x();
  out.origin[1] = pose.y();
  out.ends.clear();
  out.is_hit.clear();
  // A scan farther than max_range from the grid cannot touch it.
  const double x1 = lattice.x0 + width * lattice.res, y1 = lattice.y0 + height * lattice.res;
  const double gap_x = std::max({lattice.x0 - pose.x(), pose.x() - x1, 0.0});
  const double gap_y = std::max({lattice.y0 - pose.y(), pose.y() - y1, 0.0});
  if (std::hypot(gap_x, gap_y) > max_range) return false;
  const double reach = std::hypot(std::max(std::fabs(pose.x() - lattice.x0), std::fabs(pose.x() - x1)),
                                  std::max(std::fabs(pose.y() - lattice.y0), std::fabs(pose.y() - y1))) +
                       2.0 * lattice.res;
  const double cut = std::isfinite(kRayCutSlack * reach) ? kRayCutSlack * reach : reach;

  const Eigen::Index n = ranges.size();
  out.ends.reserve(2 * n);
  out.is_hit.reserve(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double r = ranges[i];
    if (!(std::isfinite(r) && r >= 0.0)) continue;  // invalid reading: skipped
    const bool hit = r < max_range;
    const double length = std::min(hit ? r : max_range, cut);  // a cut end lies outside: no hit
    const double a = pose[2] + beam_angles[i];
    out.ends.push_back(pose.x() + length * std::cos(a));
    out.ends.push_back(pose.y() + length * std::sin(a));
    out.is_hit.push_back(hit);
  }
  return true;
}

/// The grid as apply_scan sees it: a bounded store whose cells change once per scan.
class GridScanStore {
 public:
  explicit GridScanStore(OccupancyGrid2D& grid)
      : grid_(grid),
        hit_delta_(logit(grid.beam_.p_hit) - grid.l0_),
        miss_delta_(logit(grid.beam_.p_miss) - grid.l0_) {
    if (++grid_.scan_counter_ == 0) {  // wrapped after 2^32 scans: forget old stamps
      std::fill(grid_.stamp_.begin(), grid_.stamp_.end(), 0u);
      grid_.scan_counter_ = 1;
    }
  }
  bool contains(const CellKey<2>& key) const { return grid_.contains(key[1], key[0]); }
  KeyBox<2> box() const { return {{0, 0}, {grid_.width_, grid_.height_}}; }
  bool update_once(const CellKey<2>& key, bool hit) {
    const std::size_t index = static_cast<std::size_t>(key[1]) * grid_.width_ + key[0];
    if (grid_.stamp_[index] == grid_.scan_counter_) return false;
    grid_.stamp_[index] = grid_.scan_counter_;
    grid_.update_cell(index, hit ? hit_delta_ : miss_delta_);
    return true;
  }

 private:
  OccupancyGrid2D& grid_;
  double hit_delta_, miss_delta_;
};

OccupancyGrid2D::OccupancyGrid2D(double resolution, int width, int height, const Eigen::Vector2d& origin,
                                 double p_prior, const LogOddsClamp& clamp) {
  require_positive(resolution, "resolution");
  require(width > 0, "width", "must be > 0");
  require(height > 0, "height", "must be > 0");
  check_cell_count(width, height, "width");
  check_lattice(resolution, width, height, origin);
  require_probability(p_prior, "p_prior");
  check_clamp(clamp);
  lattice_ = {origin.x(), origin.y(), resolution, 1.0 / resolution};
  width_ = width;
  height_ = height;
  p_prior_ = p_prior;
  l0_ = logit(p_prior);
  clamp_ = clamp;
  const std::size_t n = static_cast<std::size_t>(width) * height;
  log_odds_.assign(n, l0_);
  stamp_.assign(n, 0u);
}

OccupancyGrid2D OccupancyGrid2D::covering(double xmin, double ymin, double xmax, double ymax,
                                          double resolution, double p_prior, const LogOddsClamp& clamp) {
  check_bounds(xmin, ymin, xmax, ymax);
  require_positive(resolution, "resolution");
  const double w = std::max(1.0, std::ceil((xmax - xmin) / resolution));
  const double h = std::max(1.0, std::ceil((ymax - ymin) / resolution));
  check_cell_count(w, h, "resolution");
  return OccupancyGrid2D(resolution, static_cast<int>(w), static_cast<int>(h), {xmin, ymin}, p_prior, clamp);
}

void OccupancyGrid2D::set_clamp(const LogOddsClamp& clamp) {
  check_clamp(clamp);
  clamp_ = clamp;
}

void OccupancyGrid2D::set_beam_model(const BeamModel& beam) {
  require_probability(beam.p_hit, "p_hit");
  require_probability(beam.p_miss, "p_miss");
  beam_ = beam;
}

RowMatrixXd OccupancyGrid2D::probability() const {
  return log_odds().unaryExpr([](double l) { return probability_from_log_odds(l); });
}

Eigen::Matrix<std::int64_t, 2, 1> OccupancyGrid2D::cell_index(double x, double y, const char* name) const {
  require(std::isfinite(x) && std::isfinite(y), name, "must contain only finite values");
  const double col = std::floor((x - lattice_.x0) * lattice_.inv_res);
  const double row = std::floor((y - lattice_.y0) * lattice_.inv_res);
  require(std::fabs(col) <= kMaxCellIndex && std::fabs(row) <= kMaxCellIndex, name,
          "must lie within 2^53 cells of the grid's origin (the cell index is no longer exact beyond)");
  return {static_cast<std::int64_t>(row), static_cast<std::int64_t>(col)};
}

// Table 9.1 lines 2-8 with the inverse model of Table 9.2.
std::size_t OccupancyGrid2D::insert_cone_scan(const Eigen::Vector3d& pose,
                                              const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                              const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                              double z_max, double alpha, double beta, double l_occ,
                                              double l_free) {
  check_scan_shape(pose, ranges, beam_angles);
  const ConeScan scan(pose, ranges, beam_angles, {z_max, alpha, beta, l0_, l_occ, l_free});
  // Visit a disc one cell wider than the scan's reach; the exact test is the model's own.
  const double reach = scan.reach() + lattice_.res;
  const int row_lo = std::max(0, lattice_.key(1, pose.y() - reach));
  const int row_hi = std::min(height_ - 1, lattice_.key(1, pose.y() + reach));
  std::size_t changed = 0;
  for (int row = row_lo; row <= row_hi; ++row) {
    const double cy = lattice_.key_to_coord(1, row);
    const double dy = cy - pose.y();
    const double half = std::sqrt(std::max(0.0, reach * reach - dy * dy)) + lattice_.res;
    const int col_lo = std::max(0, lattice_.key(0, pose.x() - half));
    const int col_hi = std::min(width_ - 1, lattice_.key(0, pose.x() + half));
    const std::size_t row_start = static_cast<std::size_t>(row) * width_;
    for (int col = col_lo; col <= col_hi; ++col) {
      const double ism = scan(lattice_.key_to_coord(0, col), cy);
      if (ism == l0_) continue;  // outside the perceptual field (Table 9.1 line 6)
      update_cell(row_start + col, ism - l0_);
      ++changed;
    }
  }
  return changed;
}

std::size_t OccupancyGrid2D::insert_rays(const Eigen::Vector3d& pose,
                                         const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                         const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                         double max_range) {
  check_scan_shape(pose, ranges, beam_angles);
  require_positive(max_range, "max_range");
  return insert_rays_checked(pose, ranges, beam_angles, max_range);
}

std::size_t OccupancyGrid2D::insert_rays_checked(const Eigen::Vector3d& pose,
                                                 const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                                 const Eigen::Ref<const Eigen::VectorXd>& beam_angles,
                                                 double max_range) {
  LaserSegments2D segments;
  if (!laser_segments(lattice_, width_, height_, pose, ranges, beam_angles, max_range, segments)) return 0;
  GridScanStore store(*this);
  return apply_scan<2, double>(lattice_, store, segments.view());
}

std::size_t OccupancyGrid2D::insert_scans(const Eigen::Ref<const Poses2>& poses,
                                          const Eigen::Ref<const RowMatrixXd>& ranges,
                                          const Eigen::Ref<const RowMatrixXd>& beam_angles,
                                          double max_range) {
  // All or nothing: every row is checked before the first is applied.
  require(ranges.rows() == poses.rows(), "ranges", "must have one row per pose");
  require(ranges.cols() > 0, "ranges", "must not be empty");
  const bool shared_angles = beam_angles.rows() == 1;
  require(shared_angles || beam_angles.rows() == ranges.rows(), "beam_angles",
          "must have one row, or one row per pose");
  require(beam_angles.cols() == ranges.cols(), "beam_angles", "must have as many columns as ranges");
  require_all_finite(poses, "poses");
  require_all_finite(beam_angles, "beam_angles");
  require_positive(max_range, "max_range");
  std::size_t updated = 0;
  for (Eigen::Index s = 0; s < poses.rows(); ++s) {
    const Eigen::VectorXd angles = beam_angles.row(shared_angles ? 0 : s).transpose();
    updated += insert_rays_checked(poses.row(s).transpose(), ranges.row(s).transpose(), angles, max_range);
  }
  return updated;
}

std::size_t OccupancyGrid2D::add_log_odds(const std::vector<long>& cells, const Eigen::Ref<const Eigen::VectorXd>& deltas) {
  require(static_cast<Eigen::Index>(cells.size()) == deltas.size(), "deltas", "must have one value per cell");
  const long count = static_cast<long>(log_odds_.size());
  for (std::size_t k = 0; k < cells.size(); ++k) {
    require(cells[k] >= 0 && cells[k] < count, "cells", "must be flat cell indices in [0, width * height)");
    require_log_odds(deltas[static_cast<Eigen::Index>(k)], "deltas");
  }
  for (std::size_t k = 0; k < cells.size(); ++k)
    update_cell(static_cast<std::size_t>(cells[k]), deltas[static_cast<Eigen::Index>(k)]);
  return cells.size();
}

std::size_t OccupancyGrid2D::clear_footprint(const Eigen::Vector3d& pose, double radius, double l_free) {
  require_all_finite(pose, "pose");
  require(std::isfinite(radius) && radius >= 0.0, "radius", "must be finite and >= 0");
  require_log_odds(l_free, "l_free");
  const double delta = l_free - l0_;
  const int row_lo = std::max(0, lattice_.key(1, pose.y() - radius));
  const int row_hi = std::min(height_ - 1, lattice_.key(1, pose.y() + radius));
  const int col_lo = std::max(0, lattice_.key(0, pose.x() - radius));
  const int col_hi = std::min(width_ - 1, lattice_.key(0, pose.x() + radius));
  std::size_t changed = 0;
  for (int row = row_lo; row <= row_hi; ++row) {
    for (int col = col_lo; col <= col_hi; ++col) {
      const Eigen::Vector2d c = cell_center(row, col);
      if (std::hypot(c.x() - pose.x(), c.y() - pose.y()) > radius) continue;
      update_cell(static_cast<std::size_t>(row) * width_ + col, delta);
      ++changed;
    }
  }
  return changed;
}

OccupancyGrid2D OccupancyGrid2D::grown_to_include(double xmin, double ymin, double xmax, double ymax) const {
  check_bounds(xmin, ymin, xmax, ymax);
  const double res = lattice_.res;
  const auto cells_beyond = [&](double distance) { return std::max(0.0, std::ceil(distance / res)); };
  const double left = cells_beyond(lattice_.x0 - xmin);
  const double bottom = cells_beyond(lattice_.y0 - ymin);
  const double right = cells_beyond(xmax - (lattice_.x0 + width_ * res));
  const double top = cells_beyond(ymax - (lattice_.y0 + height_ * res));
  const double new_w = width_ + left + right, new_h = height_ + bottom + top;
  check_cell_count(new_w, new_h, "bounds");
  OccupancyGrid2D grown(res, static_cast<int>(new_w), static_cast<int>(new_h),
                        {lattice_.x0 - left * res, lattice_.y0 - bottom * res}, p_prior_, clamp_);
  grown.beam_ = beam_;
  grown.log_odds().block(static_cast<int>(bottom), static_cast<int>(left), height_, width_) = log_odds();
  return grown;
}

bool OccupancyGrid2D::same_geometry(const OccupancyGrid2D& other) const {
  return lattice_.res == other.lattice_.res && lattice_.x0 == other.lattice_.x0 &&
         lattice_.y0 == other.lattice_.y0 && width_ == other.width_ && height_ == other.height_;
}

}  // namespace probslam
