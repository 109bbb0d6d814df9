#include "probslam/slam2d/likelihood_field.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "probslam/core/check.hpp"
#include "probslam/grid/ray_traversal.hpp"

namespace probslam {

void LikelihoodFieldOptions::validate() const {
  require(sigma >= kMinSigma && sigma <= kMaxSigma, "sigma", "must lie in [1e-300, 1e300] (kMinSigma, kMaxSigma)");
  require(std::isfinite(p_rand) && p_rand > 0.0 && p_rand < 1.0, "p_rand",
          "must be a probability strictly between 0 and 1");
  require_probability(occupied_threshold, "occupied_threshold");
  require(std::isfinite(max_distance), "max_distance", "must be finite (<= 0: 6 sigma)");
}

namespace {

constexpr float kFar = std::numeric_limits<float>::infinity();

/// Squared distance transform of one line (Felzenszwalb & Huttenlocher 2012): out[q] =
/// min_p (q - p)^2 + f[p], read and written with a stride. v, z are scratch of n and n + 1.
void distance_transform_1d(const float* f, float* out, int n, int stride, std::vector<int>& v,
                           std::vector<double>& z) {
  int k = -1;
  for (int q = 0; q < n; ++q) {
    const float fq = f[static_cast<std::size_t>(q) * stride];
    if (fq == kFar) continue;
    double s = -kFar;
    while (k >= 0) {  // parabola intersections in double: q^2 exceeds float's exact range
      const int p = v[k];
      const double fp = f[static_cast<std::size_t>(p) * stride];
      s = ((fq + double(q) * q) - (fp + double(p) * p)) / (2.0 * (q - p));
      if (s > z[k]) break;
      --k;
    }
    ++k;
    v[k] = q;
    z[k] = k == 0 ? -kFar : s;
    z[k + 1] = kFar;
  }
  if (k < 0) {  // no finite value on this line
    for (int q = 0; q < n; ++q) out[static_cast<std::size_t>(q) * stride] = kFar;
    return;
  }
  int j = 0;
  for (int q = 0; q < n; ++q) {
    while (z[j + 1] < q) ++j;
    const float d = float(q - v[j]);
    out[static_cast<std::size_t>(q) * stride] = d * d + f[static_cast<std::size_t>(v[j]) * stride];
  }
}

/// Beyond this many cells of truncation the windowed transform below does more work per cell
/// than the exact transform of the whole lattice (2K + 1 operations a cell against a few dozen).
constexpr int kMaxWindowCells = 32;

/// Squared distance (cells) from each cell to the nearest obstacle cell, exact wherever it is
/// below `distinct`; elsewhere some value >= distinct (the field maps all of those to its
/// truncation). A squared distance below distinct has both offsets within K = ceil(sqrt(distinct))
/// cells, so the minimum over that window is exact there, and at least distinct wherever the
/// true one is: a column sweep (vertical distance to the nearest obstacle, capped at K + 1)
/// and a row pass over 2K + 1 offsets, both over contiguous rows (the separable exact
/// transform walks columns with a stride, cache line by cache line: several times slower).
UninitializedVector<std::int32_t> squared_cell_distances(const ObstacleCells& obstacles, std::size_t distinct) {
  const int W = obstacles.width, H = obstacles.height;
  const std::size_t n = static_cast<std::size_t>(W) * H;
  const int K = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(distinct))));
  UninitializedVector<std::int32_t> out(n);  // every element written below
  if (K > kMaxWindowCells) {  // a long truncation: the exact transform (Felzenszwalb & Huttenlocher)
    std::vector<float> sq(n), tmp(n);
    for (std::size_t i = 0; i < n; ++i) sq[i] = obstacles.cells[i] != 0 ? 0.0f : kFar;
    const int longest = std::max(W, H);
    std::vector<int> v(static_cast<std::size_t>(longest) + 1);
    std::vector<double> z(static_cast<std::size_t>(longest) + 2);
    for (int c = 0; c < W; ++c) distance_transform_1d(sq.data() + c, tmp.data() + c, H, W, v, z);
    for (int r = 0; r < H; ++r) {
      const std::size_t off = static_cast<std::size_t>(r) * W;
      distance_transform_1d(tmp.data() + off, sq.data() + off, W, 1, v, z);
    }
    const double limit = std::min(static_cast<double>(distinct), double(std::numeric_limits<std::int32_t>::max()));
    for (std::size_t i = 0; i < n; ++i)
      out[i] = static_cast<std::int32_t>(std::min(static_cast<double>(sq[i]), limit));  // inf -> limit
    return out;
  }
  // Vertical distance to the nearest obstacle of the column, K + 1 for none within K.
  const std::uint8_t none = static_cast<std::uint8_t>(K + 1);
  UninitializedVector<std::uint8_t> g(n);  // every element written below
  const std::uint8_t* cells = obstacles.cells.data();
  for (int r = 0; r < H; ++r) {
    std::uint8_t* row = g.data() + static_cast<std::size_t>(r) * W;
    const std::uint8_t* occ = cells + static_cast<std::size_t>(r) * W;
    if (r == 0) {
      for (int c = 0; c < W; ++c) row[c] = occ[c] != 0 ? 0 : none;
      continue;
    }
    const std::uint8_t* above = row - W;
    for (int c = 0; c < W; ++c)
      row[c] = occ[c] != 0 ? 0 : std::min<std::uint8_t>(static_cast<std::uint8_t>(above[c] + 1), none);
  }
  for (int r = H - 2; r >= 0; --r) {
    std::uint8_t* row = g.data() + static_cast<std::size_t>(r) * W;
    const std::uint8_t* below = row + W;
    for (int c = 0; c < W; ++c) row[c] = std::min<std::uint8_t>(row[c], static_cast<std::uint8_t>(below[c] + 1));
  }
  // Along each row: min over |dx| <= K of dx^2 + g^2, with `far` standing for no obstacle (far
  // plus any dx^2 stays >= distinct). 16 bits: distinct + K^2 < 2^15 for K <= kMaxWindowCells,
  // and eight cells a vector instruction.
  const std::int16_t far = static_cast<std::int16_t>(distinct);
  std::vector<std::int16_t> padded(static_cast<std::size_t>(W) + 2 * K, far), o(static_cast<std::size_t>(W));
  for (int r = 0; r < H; ++r) {
    const std::uint8_t* row = g.data() + static_cast<std::size_t>(r) * W;
    std::int16_t* gsq = padded.data() + K;
    for (int c = 0; c < W; ++c) gsq[c] = row[c] < none ? static_cast<std::int16_t>(row[c] * row[c]) : far;
    for (int c = 0; c < W; ++c) o[c] = gsq[c];
    for (int dx = 1; dx <= K; ++dx) {
      const std::int16_t d2 = static_cast<std::int16_t>(dx * dx);
      const std::int16_t* left = gsq - dx;
      const std::int16_t* right = gsq + dx;
      for (int c = 0; c < W; ++c)
        o[c] = std::min(o[c], static_cast<std::int16_t>(std::min(left[c], right[c]) + d2));
    }
    std::copy(o.begin(), o.end(), out.begin() + static_cast<std::ptrdiff_t>(r) * W);
  }
  return out;
}

}  // namespace

LikelihoodField LikelihoodField::from_grid(const OccupancyGrid2D& grid, const LikelihoodFieldOptions& options) {
  const Eigen::Vector2d lo = grid.origin();
  const double w = grid.width() * grid.resolution(), h = grid.height() * grid.resolution();
  return from_grid(grid, Eigen::Vector4d(lo.x(), lo.y(), lo.x() + w, lo.y() + h), options);
}

LikelihoodField LikelihoodField::from_grid(const OccupancyGrid2D& grid, const Eigen::Vector4d& region,
                                           const LikelihoodFieldOptions& options) {
  options.validate();
  return from_obstacles(obstacles_of(grid, region, options.occupied_threshold), options);
}

ObstacleCells LikelihoodField::obstacles_of(const OccupancyGrid2D& grid, const Eigen::Vector4d& region,
                                            double occupied_threshold) {
  require_probability(occupied_threshold, "occupied_threshold");
  require_all_finite(region, "region");
  require(region[0] <= region[2] && region[1] <= region[3], "region", "must be (xmin, ymin, xmax, ymax)");
  const GridLattice2D& lat = grid.lattice();
  // Cells [c0, c1) x [r0, r1) of the grid that meet the region.
  const int c0 = std::clamp(lat.key(0, region[0]), 0, grid.width());
  const int c1 = std::clamp(lat.key(0, region[2]) + 1, 0, grid.width());
  const int r0 = std::clamp(lat.key(1, region[1]), 0, grid.height());
  const int r1 = std::clamp(lat.key(1, region[3]) + 1, 0, grid.height());
  ObstacleCells out;
  out.resolution = grid.resolution();
  out.x0 = lat.x0 + c0 * out.resolution;
  out.y0 = lat.y0 + r0 * out.resolution;
  out.width = std::max(0, c1 - c0);
  out.height = std::max(0, r1 - r0);
  out.cells.resize(static_cast<std::size_t>(out.width) * out.height);
  const double occupied = logit(occupied_threshold);
  for (int r = 0; r < out.height; ++r) {
    const double* row = grid.data() + static_cast<std::size_t>(r0 + r) * grid.width() + c0;
    for (int c = 0; c < out.width; ++c) out.cells[static_cast<std::size_t>(r) * out.width + c] = row[c] > occupied;
  }
  return out;
}

LikelihoodField LikelihoodField::from_obstacles(const ObstacleCells& obstacles, const LikelihoodFieldOptions& options) {
  options.validate();
  require(obstacles.width >= 0 && obstacles.height >= 0 &&
              obstacles.cells.size() == static_cast<std::size_t>(obstacles.width) * obstacles.height,
          "obstacles", "must hold width x height cells");
  require_positive(obstacles.resolution, "resolution");
  LikelihoodField field;
  field.options_ = options;
  field.res_ = obstacles.resolution;
  field.inv_res_ = 1.0 / field.res_;
  field.x0_ = obstacles.x0;
  field.y0_ = obstacles.y0;
  field.width_ = obstacles.width;
  field.height_ = obstacles.height;
  field.floor_ = static_cast<float>(std::log(options.p_rand));
  const std::size_t n = static_cast<std::size_t>(field.width_) * field.height_;

  field.num_occupied_ = static_cast<int>(n - static_cast<std::size_t>(std::count(obstacles.cells.begin(),
                                                                                   obstacles.cells.end(), 0)));
  // Squared distances are whole numbers of cells, and every one beyond the truncation maps to
  // it: only the `distinct` values below it need be told apart (see the tables below). No two
  // cells of the lattice lie further apart than its diagonal, so a truncation beyond that
  // (a sigma of metres on a small map, a map of micrometre cells) needs no more values than
  // the diagonal's: the tables stay bounded by the map, whatever the options.
  const double cap = options.truncation();
  const double cap_cells = std::min(cap * field.inv_res_ + 0.5, std::hypot(double(field.width_), double(field.height_)) + 1.0);
  const std::size_t distinct = static_cast<std::size_t>(std::ceil(cap_cells * cap_cells)) + 1;
  const UninitializedVector<std::int32_t> sq = squared_cell_distances(obstacles, distinct);
  auto distance_of = [&](double sq_cells) {
    return std::min(cap, std::max(0.0, (std::sqrt(sq_cells) - 0.5) * field.res_));  // inf -> cap
  };
  const float far_d = static_cast<float>(cap), far_logp = static_cast<float>(field.log_likelihood_of_distance(cap));
  field.distance_.resize(n);
  field.log_likelihood_.resize(n);
  if (distinct > n) {  // more distinct values than cells: each cell's own, memory bounded by the map
    for (std::size_t i = 0; i < n; ++i) {
      const bool near = static_cast<std::size_t>(sq[i]) < distinct;
      const double d = near ? distance_of(static_cast<double>(sq[i])) : cap;
      field.distance_[i] = near ? static_cast<float>(d) : far_d;
      field.log_likelihood_[i] = near ? static_cast<float>(field.log_likelihood_of_distance(d)) : far_logp;
    }
    field.build_tables();
    return field;
  }
  // The distance and log p of each of those are computed once.
  std::vector<float> dist_of(distinct), logp_of(distinct);
  for (std::size_t k = 0; k < distinct; ++k) {
    dist_of[k] = static_cast<float>(distance_of(static_cast<double>(k)));
    logp_of[k] = static_cast<float>(field.log_likelihood_of_distance(distance_of(static_cast<double>(k))));
  }
  for (std::size_t i = 0; i < n; ++i) {
    const bool near = static_cast<std::size_t>(sq[i]) < distinct;
    const std::size_t k = near ? static_cast<std::size_t>(sq[i]) : 0;
    field.distance_[i] = near ? dist_of[k] : far_d;
    field.log_likelihood_[i] = near ? logp_of[k] : far_logp;
  }
  field.build_tables();
  return field;
}

void LikelihoodField::build_tables() {
  truncation_ = options_.truncation();
  table_scale_ = (kTableSize - 1) / truncation_;
  log_table_.resize(kTableSize + 1);
  hit_table_.resize(kTableSize + 1);
  const double s = options_.sigma;
  for (std::size_t i = 0; i <= kTableSize; ++i) {
    const double d = std::min(truncation_, static_cast<double>(i) / table_scale_);
    const double z = d / s;  // not d^2 / s^2: s^2 underflows or overflows for an extreme sigma
    log_table_[i] = log_likelihood_of_distance(d);
    hit_table_[i] = std::exp(-0.5 * z * z);
  }
  // Interpolation between entries stays within them, so the largest entry bounds tabulated().
  max_log_p_ = *std::max_element(log_table_.begin(), log_table_.end());
}

double LikelihoodField::log_likelihood_of_distance(double d) const {
  const double z = d / options_.sigma;  // not d^2 / sigma^2: see build_tables
  return std::log((1.0 - options_.p_rand) * std::exp(-0.5 * z * z) + options_.p_rand);
}


int LikelihoodField::col_of(double x) const { return saturated_key((x - x0_) * inv_res_); }
int LikelihoodField::row_of(double y) const { return saturated_key((y - y0_) * inv_res_); }

double LikelihoodField::interpolate_distance(double x, double y, Eigen::Vector2d* gradient) const {
  const double cap = options_.truncation();
  // Cell centres sit at integer + 0.5 in cell units.
  const double u = (x - x0_) * inv_res_ - 0.5, v = (y - y0_) * inv_res_ - 0.5;
  if (!(u > -1.0 && v > -1.0 && u < width_ && v < height_)) {
    if (gradient) gradient->setZero();
    return cap;
  }
  const int c = static_cast<int>(std::floor(u)), r = static_cast<int>(std::floor(v));
  const double fu = u - c, fv = v - r;
  auto at = [&](int row, int col) -> double {
    if (static_cast<unsigned>(row) >= static_cast<unsigned>(height_) ||
        static_cast<unsigned>(col) >= static_cast<unsigned>(width_))
      return cap;
    return distance_[static_cast<std::size_t>(row) * width_ + col];
  };
  const double d00 = at(r, c), d01 = at(r, c + 1), d10 = at(r + 1, c), d11 = at(r + 1, c + 1);
  const double bottom = d00 + fu * (d01 - d00), top = d10 + fu * (d11 - d10);
  if (gradient) {
    const double ddu = (1.0 - fv) * (d01 - d00) + fv * (d11 - d10);
    const double ddv = top - bottom;
    *gradient = Eigen::Vector2d(ddu, ddv) * inv_res_;
  }
  return bottom + fv * (top - bottom);
}

}  // namespace probslam
