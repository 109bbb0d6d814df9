#include "probslam/grid/range_footprint.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/grid/ray_traversal.hpp"

namespace probslam {
namespace {

// The distance along the ray o + t d (unit d) at which it enters cell (kx, ky): the largest of
// the near-slab distances per axis, 0 for the cell holding the origin.
double entry_distance(const GridLattice2D& lattice, const double* o, const double* d, int kx, int ky) {
  double t = 0.0;
  const int key[2] = {kx, ky};
  for (int axis = 0; axis < 2; ++axis) {
    if (d[axis] == 0.0) continue;
    const double lo = lattice.key_to_coord(axis, key[axis]) - 0.5 * lattice.res;
    const double near = d[axis] > 0.0 ? lo : lo + lattice.res;
    t = std::max(t, (near - o[axis]) / d[axis]);
  }
  return t;
}

// Calls visit(cell, range) for the cells a laser ray crosses, in walk order (increasing range),
// while range < max_range; visit returns false to stop.
template <class Visit>
void walk_laser(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose, double beam_angle,
                double max_range, Visit&& visit) {
  const double a = pose[2] + beam_angle;
  const double d[2] = {std::cos(a), std::sin(a)};
  const double o[2] = {pose[0], pose[1]};
  // Walk two cells past max_range: walk_ray leaves out the end's cell, and every cell entered
  // before max_range lies then strictly before the end's cell.
  const double length = max_range + 2.0 * lattice.res;
  const double end[2] = {o[0] + length * d[0], o[1] + length * d[1]};
  const KeyBox<2> box{{0, 0}, {width, height}};
  walk_ray_in_box<2, double>(lattice, box, o, end, [&](const CellKey<2>& k) {
    const double t = entry_distance(lattice, o, d, k[0], k[1]);
    if (!(t < max_range)) return false;  // the walk is monotone: every later cell is farther
    return visit(static_cast<std::int32_t>(k[1]) * width + k[0], t);
  });
}

// The rows and columns of the grid a sonar cone can reach (inclusive; empty when lo > hi): its
// bounding box, from its apex, its two edges' ends and the disc's extreme points in the
// directions the cone contains, clipped to the grid.
struct CellBox {
  int row_lo, row_hi, col_lo, col_hi;
  double cells() const { return row_hi < row_lo || col_hi < col_lo ? 0.0 : double(row_hi - row_lo + 1) * (col_hi - col_lo + 1); }
};

CellBox cone_box(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose, double bearing,
                 const BeamGeometry& g) {
  const double half = 0.5 * g.beta;
  const double r = g.max_range;
  double xmin = pose[0], xmax = pose[0], ymin = pose[1], ymax = pose[1];
  const auto include = [&](double angle) {
    const double x = pose[0] + r * std::cos(angle), y = pose[1] + r * std::sin(angle);
    xmin = std::min(xmin, x), xmax = std::max(xmax, x), ymin = std::min(ymin, y), ymax = std::max(ymax, y);
  };
  include(bearing - half);
  include(bearing + half);
  for (const double axis : {0.0, 0.5 * kPi, kPi, -0.5 * kPi})
    if (std::fabs(wrap_angle(axis - bearing)) <= half) include(axis);
  return {std::max(0, lattice.key(1, ymin)), std::min(height - 1, lattice.key(1, ymax)),
          std::max(0, lattice.key(0, xmin)), std::min(width - 1, lattice.key(0, xmax))};
}

// Calls visit(cell, range) for every cell whose centre lies in the sonar cone closer than
// max_range, in row-major order.
template <class Visit>
void scan_cone(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose, double beam_angle,
               const BeamGeometry& g, Visit&& visit) {
  const double bearing = wrap_angle(pose[2] + beam_angle);
  const double half = 0.5 * g.beta;
  const double r = g.max_range;
  const CellBox box = cone_box(lattice, width, height, pose, bearing, g);
  for (int row = box.row_lo; row <= box.row_hi; ++row) {
    const double dy = lattice.key_to_coord(1, row) - pose[1];
    for (int col = box.col_lo; col <= box.col_hi; ++col) {
      const double dx = lattice.key_to_coord(0, col) - pose[0];
      const double range = std::sqrt(dx * dx + dy * dy);
      if (!(range < r)) continue;
      // A centre on the apex has no bearing: it is in every cone.
      if (range > 0.0 && std::fabs(wrap_angle(std::atan2(dy, dx) - bearing)) > half) continue;
      visit(static_cast<std::int32_t>(row) * width + col, range);
    }
  }
}

}  // namespace

void BeamGeometry::validate() const {
  require_positive(max_range, "max_range");
  if (shape == BeamShape::kSonar)
    require(std::isfinite(beta) && beta > 0.0 && beta <= kTwoPi, "beta", "must be a cone opening angle in (0, 2 pi] rad");
}

double beam_footprint_visits(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose,
                             double beam_angle, const BeamGeometry& geometry) {
  if (geometry.shape == BeamShape::kSonar)
    return cone_box(lattice, width, height, pose, wrap_angle(pose[2] + beam_angle), geometry).cells();
  // A walk crosses at most one cell per cell side travelled on each axis, plus the start's,
  // and never more than the grid's rows plus columns.
  const double a = pose[2] + beam_angle;
  const double reach = geometry.max_range / lattice.res;
  const double crossed = reach * (std::fabs(std::cos(a)) + std::fabs(std::sin(a))) + 4.0;
  return std::min(crossed, static_cast<double>(width) + height + 2.0);
}

void require_footprint_budget(double visits, const char* name) {
  if (!(visits <= kMaxFootprintVisits))
    throw_invalid_argument(name, "would test " + std::to_string(static_cast<long long>(visits)) +
              " footprint cells, more than kMaxFootprintVisits (2^28): use fewer beams or poses, a shorter "
              "max_range, a narrower cone or a coarser grid");
}

void beam_footprint(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose,
                    double beam_angle, const BeamGeometry& geometry, std::vector<FootprintCell>& out) {
  out.clear();
  if (geometry.shape == BeamShape::kLaser) {
    walk_laser(lattice, width, height, pose, beam_angle, geometry.max_range, [&](std::int32_t cell, double t) {
      out.push_back({cell, t});
      return true;
    });
    return;
  }
  scan_cone(lattice, width, height, pose, beam_angle, geometry,
            [&](std::int32_t cell, double range) { out.push_back({cell, range}); });
  std::stable_sort(out.begin(), out.end(),
                   [](const FootprintCell& a, const FootprintCell& b) { return a.range < b.range; });
}

double expected_range(const BinaryMap2D& map, const Eigen::Vector3d& pose, double beam_angle,
                      const BeamGeometry& geometry) {
  double nearest = geometry.max_range;
  if (geometry.shape == BeamShape::kLaser) {
    walk_laser(map.lattice(), map.width(), map.height(), pose, beam_angle, geometry.max_range,
               [&](std::int32_t cell, double t) {
                 if (!map.occupied(static_cast<std::size_t>(cell))) return true;
                 nearest = t;
                 return false;
               });
    return nearest;
  }
  scan_cone(map.lattice(), map.width(), map.height(), pose, beam_angle, geometry, [&](std::int32_t cell, double range) {
    if (map.occupied(static_cast<std::size_t>(cell))) nearest = std::min(nearest, range);
  });
  return nearest;
}

}  // namespace probslam
