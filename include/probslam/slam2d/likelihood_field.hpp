#pragma once
// The precomputed lookup table of correlative scan matching (Olson 2009): a blurred likelihood
// field of a local map. Thrun et al. ch. 6.4's likelihood field: a hit at distance d from the
// nearest occupied cell has p(d) = (1 - p_rand) exp(-d^2 / 2 sigma^2) + p_rand.
#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <vector>

#include "probslam/core/options_description.hpp"
#include "probslam/core/uninitialized_vector.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

class StateWriter;
class StateReader;

struct LikelihoodFieldOptions {
  double sigma = 0.05;            ///< std of a hit around the nearest obstacle, m
  double p_rand = 0.05;           ///< weight of the uniform part: bounds a stray point's cost
  double occupied_threshold = 0.5;  ///< cells above this probability are obstacles
  /// Distances are computed (and stored) up to this; beyond it p(d) is p_rand to double
  /// precision anyway when it is a few sigma. <= 0: 6 sigma.
  double max_distance = 0.0;

  /// The range of sigma, m: below it the lookup table's step (2047 / 6 sigma a metre)
  /// overflows a double, above it the 6 sigma truncation does; between, every value is finite.
  static constexpr double kMinSigma = 1e-300, kMaxSigma = 1e300;

  void validate() const;
  double truncation() const { return max_distance > 0.0 ? max_distance : 6.0 * sigma; }

  template <class V>
  static void describe(V& v) {
    using O = LikelihoodFieldOptions;
    v("sigma", &O::sigma, "m", "std of a hit around the nearest obstacle");
    v("p_rand", &O::p_rand, "", "weight of the uniform part, in (0, 1): bounds a stray point's cost");
    v("occupied_threshold", &O::occupied_threshold, "", "cells above this probability are obstacles");
    v("max_distance", &O::max_distance, "m", "distances are computed up to this (<= 0: 6 sigma)");
  }
};

/// What a likelihood field is built from: which cells of a window of a grid's lattice hold an
/// obstacle (1 byte a cell, against the grid's 12). SubmapSlam2D keeps this of each finished
/// submap instead of its grid, and builds the loop-closure field from it when needed.
struct ObstacleCells {
  double x0 = 0.0, y0 = 0.0, resolution = 1.0;  ///< lower-left corner of cell (0, 0), cell side (m)
  int width = 0, height = 0;
  std::vector<std::uint8_t> cells;  ///< row-major (height x width), 1 = obstacle
  std::size_t bytes() const { return cells.capacity() + sizeof(*this); }
};

class LikelihoodField {
 public:
  /// The field of `grid` restricted to [xmin, xmax] x [ymin, ymax] (metres; clipped to the
  /// grid; the whole grid by default), on the grid's lattice. Distances come from an exact
  /// Euclidean distance transform (Felzenszwalb & Huttenlocher 2012) of the occupied cells.
  static LikelihoodField from_grid(const OccupancyGrid2D& grid, const LikelihoodFieldOptions& options = {});
  static LikelihoodField from_grid(const OccupancyGrid2D& grid, const Eigen::Vector4d& region,
                                   const LikelihoodFieldOptions& options = {});
  /// The cells of `grid` that meet `region` (clipped to the grid), marked where their occupancy
  /// exceeds occupied_threshold: from_obstacles of it is from_grid(grid, region, options),
  /// value for value (from_grid is built that way).
  static ObstacleCells obstacles_of(const OccupancyGrid2D& grid, const Eigen::Vector4d& region,
                                    double occupied_threshold);
  static LikelihoodField from_obstacles(const ObstacleCells& obstacles, const LikelihoodFieldOptions& options = {});

  double resolution() const { return res_; }
  Eigen::Vector2d origin() const { return {x0_, y0_}; }
  int width() const { return width_; }
  int height() const { return height_; }
  const LikelihoodFieldOptions& options() const { return options_; }
  int num_occupied() const { return num_occupied_; }

  /// Distance (m) from each cell centre to the nearest occupied cell, truncated; (H, W). An
  /// occupied cell stands for an obstacle somewhere inside it, so the distance is measured to
  /// the cell, not its centre: the centre distance less half a cell (0 in the cell itself).
  Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> distance() const {
    return {distance_.data(), height_, width_};
  }
  /// log p(d) of each cell, (H, W): the table the correlative search sums.
  Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> log_likelihood() const {
    return {log_likelihood_.data(), height_, width_};
  }
  /// log p of a point outside the table (no obstacle known near it): log(p_rand).
  float floor_value() const { return floor_; }

  /// log p(d) for a distance d (m).
  double log_likelihood_of_distance(double d) const;
  /// log p(d) and exp(-d^2 / 2 sigma^2) from a table (linear interpolation, error below 1e-6):
  /// the inner loop of the refinement and the response surface, without exp and log.
  void tabulated(double d, double* log_p, double* hit) const {
    const double u = std::min(d, truncation_) * table_scale_;
    const std::size_t i = std::min(static_cast<std::size_t>(u), kTableSize - 1);
    const double f = u - static_cast<double>(i);
    *log_p = log_table_[i] + f * (log_table_[i + 1] - log_table_[i]);
    *hit = hit_table_[i] + f * (hit_table_[i + 1] - hit_table_[i]);
  }
  /// The largest log_p tabulated() returns for any distance: a bound on every point's term.
  double max_tabulated_log_p() const { return max_log_p_; }
  /// The table value of cell (row, col), floor_value() outside.
  float cell_value(int row, int col) const {
    return static_cast<unsigned>(row) < static_cast<unsigned>(height_) &&
                   static_cast<unsigned>(col) < static_cast<unsigned>(width_)
               ? log_likelihood_[static_cast<std::size_t>(row) * width_ + col]
               : floor_;
  }
  /// Bilinear interpolation of the distance between cell centres at (x, y) metres, with its
  /// gradient (d/dx, d/dy); outside the table the truncation distance and a zero gradient.
  double interpolate_distance(double x, double y, Eigen::Vector2d* gradient = nullptr) const;
  /// Integer cell (col, row) of a point, saturating (see GridLattice2D).
  int col_of(double x) const;
  int row_of(double y) const;

  /// Every value of the field (its lookup tables are rebuilt from the options on reading).
  void write_state(StateWriter& w) const;
  static LikelihoodField read_state(StateReader& r);

 private:
  LikelihoodField() = default;
  void build_tables();
  /// Entries of the log p(d) table over [0, truncation]; at 6 sigma a step of 0.003 sigma.
  static constexpr std::size_t kTableSize = 2048;
  double truncation_ = 0, table_scale_ = 0;
  std::vector<double> log_table_, hit_table_;
  double max_log_p_ = 0.0;
  double x0_ = 0, y0_ = 0, res_ = 1, inv_res_ = 1;
  int width_ = 0, height_ = 0, num_occupied_ = 0;
  LikelihoodFieldOptions options_;
  float floor_ = 0;
  UninitializedVector<float> distance_;  // written whole where built
  UninitializedVector<float> log_likelihood_;
};

}  // namespace probslam
