#pragma once
// The measurement likelihood p(z | x, m) of grid-based FastSLAM: the likelihood field model
// (Thrun et al. ch. 6.4) with the distance to the nearest occupied cell found by a local search
// around each end point, on the particle's own (changing) map. A particle's map changes with
// every scan, so a distance transform per particle per step (the correlative matcher's
// LikelihoodField) would cost more than the whole update; the search visits only the few cells
// within search_radius of each end point, nearest first.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "probslam/core/types.hpp"
#include "probslam/fastslam/tiled_grid_2d.hpp"

namespace probslam {

struct EndpointLikelihoodOptions {
  double sigma = 0.05;          ///< std of a hit around the nearest obstacle, m
  double p_rand = 0.05;         ///< uniform part: bounds a stray point's cost
  /// Obstacles farther than this count as none (p = p_rand), m. At 0.15 (3 sigma) the score
  /// jumps by log(0.06 / 0.05) per point where an end point crosses it; at 6 sigma the Gaussian
  /// term is 1e-8 there and the score is continuous. On ACES (30 particles, seeds 0, 1, 2) 0.3
  /// gave 0.046, 0.050, 0.046 m relations error against 0.057, 0.053, 0.047 m with 0.15, and
  /// FR079 and Intel agree with their corrected logs as well or better (0.059, 0.054 m).
  double search_radius = 0.3;
  double occupied_threshold = 0.5;  ///< cells above this probability are obstacles
  void validate() const;
  template <class V>
  static void describe(V& v) {
    using O = EndpointLikelihoodOptions;
    v("sigma", &O::sigma, "m", "std of a hit around the nearest obstacle");
    v("p_rand", &O::p_rand, "", "weight of the uniform part, in (0, 1): bounds a stray point's cost");
    v("search_radius", &O::search_radius, "m", "obstacles farther than this count as none");
    v("occupied_threshold", &O::occupied_threshold, "", "cells above this probability are obstacles");
  }
};

/// log p(z | x, m) = sum over the end points of log((1 - p_rand) exp(-d^2 / 2 sigma^2) + p_rand),
/// d the distance (m) from the end point to the nearest occupied cell's centre, if that is within
/// search_radius (otherwise the p_rand term alone). Cells outside the grid are free. d is
/// continuous in the pose (an end point is not snapped to its cell), so the score has no
/// one-cell plateaus for the proposal's hill climbing and its Gaussian fit to resolve.
class EndpointLikelihood {
 public:
  /// For grids of this resolution (m). std::invalid_argument naming the option on bad options;
  /// the search window is bounded (kMaxSearchCells).
  EndpointLikelihood(const EndpointLikelihoodOptions& options, double resolution);

  /// Search windows of more cells than this are refused (search_radius / resolution too large).
  static constexpr int kMaxSearchCells = 1 << 16;

  const EndpointLikelihoodOptions& options() const { return options_; }
  double resolution() const { return res_; }

  /// points: (N, 2) end points in the sensor frame (m); pose (x, y, theta) of the sensor in
  /// the map. `quality` (if given): the mean of exp(-d^2 / 2 sigma^2) over the points, 0..1.
  /// The grid must have this resolution; the pose and points must be finite (unchecked: the
  /// filter's inner loop; the bindings check).
  double log_likelihood(const TiledGrid2D& grid, const Eigen::Vector3d& pose, const Eigen::Ref<const Points2>& points,
                        double* quality = nullptr) const;

  /// The search's result per cell, for many evaluations on one grid that does not change
  /// meanwhile (a proposal's climb and fit: about a hundred poses, each end point's cell visited
  /// again and again). For each cell an end point fell in, it keeps the occupied cells of the
  /// search in its order, up to where the search stops for any point of that cell; an end point
  /// in a known cell then walks that short list (none at all far from obstacles) instead of the
  /// window. The value is the search's, bit for bit: the same cells in the same order, the same
  /// stopping rule. Not shared between threads; tied to one likelihood and grid.
  class Memo {
   public:
    Memo() = default;

   private:
    friend class EndpointLikelihood;
    struct Occupied {
      int drow, dcol;
      double bound;  // the search's lower bound on the distance to it: centre distance - half diagonal
    };
    struct Entry {
      std::int64_t key;  // row << 32 | col (as unsigned)
      std::uint32_t begin, end;  // its cells in `occupied`
    };
    const TiledGrid2D* grid = nullptr;
    std::vector<std::int32_t> slots;  // open addressing: index into `entries`, -1 free
    std::vector<Entry> entries;
    std::vector<Occupied> occupied;
  };
  /// log_likelihood with the searches remembered in `memo` (cleared when it last saw another grid).
  /// The grid must not change while the memo is used with it.
  double log_likelihood(const TiledGrid2D& grid, const Eigen::Vector3d& pose, const Eigen::Ref<const Points2>& points,
                        Memo& memo, double* quality = nullptr) const;

  /// The derivatives of log p(z | x, m) in the pose (x, y, theta), with each end point's nearest
  /// occupied cell held where it is (the derivative wherever that cell is unique): `gradient`
  /// exactly, and `information` the Gauss-Newton (iteratively reweighted least squares)
  /// approximation of minus the Hessian, sum of w / sigma^2 J^T J over the points within
  /// search_radius, J = d(end point)/d(pose) and w = (1 - p_rand) h / ((1 - p_rand) h + p_rand),
  /// h = exp(-d^2 / 2 sigma^2), the point's probability of being a hit.
  struct Derivatives {
    Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
    Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  };
  /// log_likelihood with the memo, and its derivatives (the same value, bit for bit).
  double log_likelihood(const TiledGrid2D& grid, const Eigen::Vector3d& pose, const Eigen::Ref<const Points2>& points,
                        Memo& memo, Derivatives& derivatives, double* quality = nullptr) const;

 private:
  struct Offset {
    int drow, dcol;
    double centre_distance;  // between the two cells' centres, m
  };
  /// The sum and quality with best2(row, col, ex, ey, tx, ty) giving the squared distance to the
  /// nearest occupied cell the search finds (infinity for none), and (if it sets them) (tx, ty)
  /// from the point to that cell's centre; on_hit(rx, ry, tx, ty, hit) is called for each point
  /// within search_radius, (rx, ry) the point relative to the pose's position.
  template <class Nearest, class OnHit>
  double sum(const TiledGrid2D& grid, const Eigen::Vector3d& pose, const Eigen::Ref<const Points2>& points,
             double* quality, const Nearest& best2, const OnHit& on_hit) const;
  /// The memo's walk for a point (ex, ey) off the centre of cell (row, col); (tx, ty) as in sum.
  double remembered_nearest(const TiledGrid2D& grid, int row, int col, double ex, double ey, Memo& memo, double& tx,
                            double& ty) const;
  /// Resets the memo when it last saw another grid.
  static void attach(const TiledGrid2D& grid, Memo& memo);
  /// memo's entry for cell (row, col), made on first use.
  const Memo::Entry& remembered(const TiledGrid2D& grid, int row, int col, Memo& memo) const;
  EndpointLikelihoodOptions options_;
  double res_;
  std::vector<Offset> offsets_;  // cells that may lie within search_radius, nearest first
  double half_diagonal_ = 0.0, log_p_none_ = 0.0;
  double occupied_log_odds_ = 0.0;  // logit(occupied_threshold)
};

}  // namespace probslam
