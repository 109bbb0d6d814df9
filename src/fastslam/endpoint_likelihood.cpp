#include "probslam/fastslam/endpoint_likelihood.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "probslam/core/check.hpp"
#include "probslam/grid/log_odds.hpp"

namespace probslam {

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

double EndpointLikelihood::log_likelihood(const TiledGrid2D& grid, const Eigen::Vector3d& pose,
                                          const Eigen::Ref<const Points2>& points, double* quality) const {
  const double c = std::cos(pose.z()), s = std::sin(pose.z());
  const GridLattice2D& lattice = grid.lattice();
  const double threshold = occupied_log_odds_;
  const double radius2 = options_.search_radius * options_.search_radius;
  const double two_var = 2.0 * options_.sigma * options_.sigma;
  double sum = 0.0, hits = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const double x = pose.x() + c * points(i, 0) - s * points(i, 1);
    const double y = pose.y() + s * points(i, 0) + c * points(i, 1);
    const int row = lattice.key(1, y), col = lattice.key(0, x);
    // Offset of the point from its cell's centre; a cell at centre distance D from that centre
    // lies at least D - half_diagonal_ from the point, so the search stops once that exceeds
    // the best distance found.
    const double ex = x - lattice.key_to_coord(0, col), ey = y - lattice.key_to_coord(1, row);
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
    if (best2 <= radius2) {
      const double hit = std::exp(-best2 / two_var);
      sum += std::log((1.0 - options_.p_rand) * hit + options_.p_rand);
      hits += hit;
    } else {
      sum += log_p_none_;
    }
  }
  if (quality) *quality = points.rows() > 0 ? hits / static_cast<double>(points.rows()) : 0.0;
  return sum;
}

}  // namespace probslam
