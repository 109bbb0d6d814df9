#include "probslam/fastslam/endpoint_likelihood.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "probslam/core/check.hpp"
#include "probslam/grid/log_odds.hpp"

namespace probslam {
namespace {

/// A memo's first table size (a power of two): a proposal visits a few hundred to a few
/// thousand cells; the table doubles when half full.
constexpr std::size_t kMemoFirstSlots = 4096;
/// Extra reach (m) of a memo entry beyond where the search provably stops, against rounding in
/// that bound (distances of metres, rounding of 1e-16 m): a longer list only costs a few steps.
constexpr double kMemoSlack = 1e-6;

}  // namespace

void EndpointLikelihoodOptions::validate() const {
  require_positive(sigma, "sigma");
  require(std::isfinite(p_rand) && p_rand > 0.0 && p_rand < 1.0, "p_rand", "must lie in (0, 1)");
  require(std::isfinite(search_radius) && search_radius >= 0.0, "search_radius", "must be finite and >= 0");
  require_probability(occupied_threshold, "occupied_threshold");
}

EndpointLikelihood::EndpointLikelihood(const EndpointLikelihoodOptions& options, double resolution)
    : options_(options), res_(resolution) {
  options.validate();
  require_positive(resolution, "resolution");
  // An end point lies up to half a cell diagonal from its cell's centre: cells whose centres
  // are that much farther than search_radius from it may still be within search_radius.
  const double reach = options.search_radius + resolution * std::sqrt(0.5);
  const double cells = std::ceil(reach / resolution);
  require(cells <= 0.5 * std::sqrt(static_cast<double>(kMaxSearchCells)), "search_radius",
          "spans too many cells at this resolution (window of more than 65536 cells)");
  const int r = static_cast<int>(cells);
  for (int dr = -r; dr <= r; ++dr)
    for (int dc = -r; dc <= r; ++dc) {
      const double centre_distance = std::hypot(dr, dc) * resolution;
      if (centre_distance <= reach) offsets_.push_back({dr, dc, centre_distance});
    }
  // Nearest first; ties in a fixed order so that every build searches alike.
  std::sort(offsets_.begin(), offsets_.end(), [](const Offset& a, const Offset& b) {
    const int da = a.drow * a.drow + a.dcol * a.dcol, db = b.drow * b.drow + b.dcol * b.dcol;
    return da != db ? da < db : (a.drow != b.drow ? a.drow < b.drow : a.dcol < b.dcol);
  });
  half_diagonal_ = resolution * std::sqrt(0.5);
  log_p_none_ = std::log(options.p_rand);
  occupied_log_odds_ = logit(options.occupied_threshold);
}

template <class Nearest, class OnHit>
double EndpointLikelihood::sum(const TiledGrid2D& grid, const Eigen::Vector3d& pose,
                               const Eigen::Ref<const Points2>& points, double* quality, const Nearest& best2_of,
                               const OnHit& on_hit) const {
  const double c = std::cos(pose.z()), s = std::sin(pose.z());
  const GridLattice2D& lattice = grid.lattice();
  const double radius2 = options_.search_radius * options_.search_radius;
  const double two_var = 2.0 * options_.sigma * options_.sigma;
  double sum = 0.0, hits = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const double x = pose.x() + c * points(i, 0) - s * points(i, 1);
    const double y = pose.y() + s * points(i, 0) + c * points(i, 1);
    const int row = lattice.key(1, y), col = lattice.key(0, x);
    // Offset of the point from its cell's centre.
    const double ex = x - lattice.key_to_coord(0, col), ey = y - lattice.key_to_coord(1, row);
    double tx = 0.0, ty = 0.0;
    const double best2 = best2_of(row, col, ex, ey, tx, ty);
    if (best2 <= radius2) {
      const double hit = std::exp(-best2 / two_var);
      sum += std::log((1.0 - options_.p_rand) * hit + options_.p_rand);
      hits += hit;
      on_hit(x - pose.x(), y - pose.y(), tx, ty, hit);
    } else {
      sum += log_p_none_;
    }
  }
  if (quality) *quality = points.rows() > 0 ? hits / static_cast<double>(points.rows()) : 0.0;
  return sum;
}

double EndpointLikelihood::log_likelihood(const TiledGrid2D& grid, const Eigen::Vector3d& pose,
                                          const Eigen::Ref<const Points2>& points, double* quality) const {
  const double threshold = occupied_log_odds_;
  const auto best2_of = [&](int row, int col, double ex, double ey, double&, double&) {
    // A cell at centre distance D from the point's cell's centre lies at least D - half_diagonal_
    // from the point, so the search stops once that exceeds the best distance found.
    double best2 = std::numeric_limits<double>::infinity();
    for (const Offset& o : offsets_) {
      const double bound = o.centre_distance - half_diagonal_;
      if (bound > 0.0 && bound * bound > best2) break;
      // Saturated keys (far outside) plus a bounded offset stay far from int overflow.
      const int rr = row + o.drow, cc = col + o.dcol;
      if (!grid.contains(rr, cc) || !(grid.log_odds(rr, cc) > threshold)) continue;
      const double dx = o.dcol * res_ - ex, dy = o.drow * res_ - ey;
      best2 = std::min(best2, dx * dx + dy * dy);
    }
    return best2;
  };
  return sum(grid, pose, points, quality, best2_of, [](double, double, double, double, double) {});
}

void EndpointLikelihood::attach(const TiledGrid2D& grid, Memo& memo) {
  if (memo.grid == &grid) return;
  memo.grid = &grid;
  memo.slots.assign(kMemoFirstSlots, -1);
  memo.entries.clear();
  memo.occupied.clear();
}

double EndpointLikelihood::remembered_nearest(const TiledGrid2D& grid, int row, int col, double ex, double ey,
                                              Memo& memo, double& tx, double& ty) const {
  // The search's loop over the occupied cells alone: the bound grows along the search's order
  // and best2 changes only at occupied cells, so the search stops at an unoccupied cell only
  // where it would stop at the next occupied one.
  const Memo::Entry& e = remembered(grid, row, col, memo);
  double best2 = std::numeric_limits<double>::infinity();
  for (std::uint32_t k = e.begin; k < e.end; ++k) {
    const Memo::Occupied& o = memo.occupied[k];
    if (o.bound > 0.0 && o.bound * o.bound > best2) break;
    const double dx = o.dcol * res_ - ex, dy = o.drow * res_ - ey;
    const double d2 = dx * dx + dy * dy;
    if (d2 < best2) {  // the search's min, and where it is
      best2 = d2;
      tx = dx;
      ty = dy;
    }
  }
  return best2;
}

double EndpointLikelihood::log_likelihood(const TiledGrid2D& grid, const Eigen::Vector3d& pose,
                                          const Eigen::Ref<const Points2>& points, Memo& memo, double* quality) const {
  attach(grid, memo);
  return sum(
      grid, pose, points, quality,
      [&](int row, int col, double ex, double ey, double& tx, double& ty) {
        return remembered_nearest(grid, row, col, ex, ey, memo, tx, ty);
      },
      [](double, double, double, double, double) {});
}

double EndpointLikelihood::log_likelihood(const TiledGrid2D& grid, const Eigen::Vector3d& pose,
                                          const Eigen::Ref<const Points2>& points, Memo& memo, Derivatives& derivatives,
                                          double* quality) const {
  attach(grid, memo);
  // Per point, e = end point - nearest centre = -(tx, ty), d^2 = |e|^2, and the term
  // log((1 - p) h + p) has derivative -w / (2 sigma^2) in d^2, so its gradient is
  // -(w / sigma^2) J^T e, J = [1 0 -ry; 0 1 rx] (the end point's derivative in x, y, theta).
  double g0 = 0.0, g1 = 0.0, g2 = 0.0, h02 = 0.0, h12 = 0.0, h22 = 0.0, h00 = 0.0;
  const double inv_var = 1.0 / (options_.sigma * options_.sigma), p = options_.p_rand;
  const double value = sum(
      grid, pose, points, quality,
      [&](int row, int col, double ex, double ey, double& tx, double& ty) {
        return remembered_nearest(grid, row, col, ex, ey, memo, tx, ty);
      },
      [&](double rx, double ry, double tx, double ty, double hit) {
        const double w = inv_var * (1.0 - p) * hit / ((1.0 - p) * hit + p);
        // J^T e with e = -(tx, ty): (-tx, -ty, ry tx - rx ty).
        g0 += w * tx;
        g1 += w * ty;
        g2 -= w * (ry * tx - rx * ty);
        h00 += w;
        h02 -= w * ry;
        h12 += w * rx;
        h22 += w * (rx * rx + ry * ry);
      });
  derivatives.gradient << g0, g1, g2;
  derivatives.information << h00, 0.0, h02, 0.0, h00, h12, h02, h12, h22;
  return value;
}

const EndpointLikelihood::Memo::Entry& EndpointLikelihood::remembered(const TiledGrid2D& grid, int row, int col,
                                                                      Memo& memo) const {
  const std::int64_t key = static_cast<std::int64_t>((static_cast<std::uint64_t>(static_cast<std::uint32_t>(row)) << 32) |
                                                     static_cast<std::uint32_t>(col));
  auto slot_of = [&](std::int64_t k) {
    const std::size_t mask = memo.slots.size() - 1;
    std::size_t h = static_cast<std::size_t>((static_cast<std::uint64_t>(k) * 0x9E3779B97F4A7C15ull) >> 32) & mask;
    while (memo.slots[h] >= 0 && memo.entries[static_cast<std::size_t>(memo.slots[h])].key != k) h = (h + 1) & mask;
    return h;
  };
  std::size_t h = slot_of(key);
  if (memo.slots[h] >= 0) return memo.entries[static_cast<std::size_t>(memo.slots[h])];
  // A new cell: the search's occupied cells in its order. For any point of the cell (at most
  // half_diagonal_ from its centre) the search has found a cell within D1 + half_diagonal_ once
  // it meets the first occupied one (centre distance D1), and stops before any cell whose bound
  // exceeds that: those are not kept (kMemoSlack keeps a few more, harmless: the walk applies
  // the search's stopping rule itself).
  const double threshold = occupied_log_odds_;
  Memo::Entry e{key, static_cast<std::uint32_t>(memo.occupied.size()), 0};
  double last = std::numeric_limits<double>::infinity();
  for (const Offset& o : offsets_) {
    if (o.centre_distance > last) break;
    const int rr = row + o.drow, cc = col + o.dcol;
    if (!grid.contains(rr, cc) || !(grid.log_odds(rr, cc) > threshold)) continue;
    memo.occupied.push_back({o.drow, o.dcol, o.centre_distance - half_diagonal_});
    if (last == std::numeric_limits<double>::infinity()) last = o.centre_distance + 2.0 * half_diagonal_ + kMemoSlack;
  }
  e.end = static_cast<std::uint32_t>(memo.occupied.size());
  memo.entries.push_back(e);
  if (2 * memo.entries.size() > memo.slots.size()) {  // keep the table at most half full
    memo.slots.assign(2 * memo.slots.size(), -1);
    for (std::size_t k = 0; k < memo.entries.size(); ++k) memo.slots[slot_of(memo.entries[k].key)] = static_cast<std::int32_t>(k);
  } else {
    memo.slots[h] = static_cast<std::int32_t>(memo.entries.size() - 1);
  }
  return memo.entries.back();
}

}  // namespace probslam
