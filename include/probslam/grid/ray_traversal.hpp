#pragma once
// Exact grid traversal of a ray (Amanatides & Woo), shared by the 2-D and 3-D grids.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

namespace probslam {

template <int Dim>
using CellKey = std::array<int, Dim>;

/// Cell keys saturate at +-kKeyBound instead of overflowing the int cast (undefined behaviour):
/// every grid is far smaller (OccupancyGrid2D::kMaxCells, OctoMap's 65536 keys per axis), so a
/// saturated key lies outside it, and a walk may still step a few cells from it without overflow.
constexpr int kKeyBound = 1 << 30;

/// floor(scaled) as a key, saturated to [-kKeyBound, kKeyBound]; NaN gives -kKeyBound (outside).
inline int saturated_key(double scaled) {
  const double f = std::floor(scaled);
  if (!(f > -kKeyBound)) return -kKeyBound;
  if (!(f < kKeyBound)) return kKeyBound;
  return static_cast<int>(f);
}

/// The keys [lo, hi) of a bounded grid, per axis.
template <int Dim>
struct KeyBox {
  CellKey<Dim> lo, hi;
  bool contains(const CellKey<Dim>& k) const {
    for (int i = 0; i < Dim; ++i)
      if (k[i] < lo[i] || k[i] >= hi[i]) return false;
    return true;
  }
};

/// The start of walk_ray, shared with the grids' specialised walks: per axis the step (+1, -1 or
/// 0), the ray parameter at the first cell border (t_max) and between borders (t_delta), and the
/// segment's length; OctoMap's arithmetic (a Real direction and length, double distances). `key`
/// is the origin's cell.
template <int Dim, typename Real>
struct RayStart {
  int step[Dim];
  double t_max[Dim], t_delta[Dim];
  Real length;
};

template <int Dim, typename Real, class Lattice>
RayStart<Dim, Real> ray_start(const Lattice& lattice, const Real* origin, const Real* end, const int* key) {
  RayStart<Dim, Real> s;
  Real direction[Dim];
  Real length_sq = 0;
  for (int i = 0; i < Dim; ++i) {
    direction[i] = end[i] - origin[i];
    length_sq += direction[i] * direction[i];
  }
  s.length = static_cast<Real>(std::sqrt(static_cast<double>(length_sq)));
  for (int i = 0; i < Dim; ++i) direction[i] /= s.length;
  const double res = lattice.resolution();
  for (int i = 0; i < Dim; ++i) {
    s.step[i] = direction[i] > 0 ? 1 : (direction[i] < 0 ? -1 : 0);
    if (s.step[i] != 0) {
      double border = lattice.key_to_coord(i, key[i]);
      border += static_cast<Real>(s.step[i] * res * 0.5);
      s.t_max[i] = (border - origin[i]) / direction[i];
      s.t_delta[i] = res / std::fabs(direction[i]);
    } else {
      s.t_max[i] = std::numeric_limits<double>::max();
      s.t_delta[i] = std::numeric_limits<double>::max();
    }
  }
  return s;
}

/// Walks the cells a segment crosses, with OctoMap 1.9's computeRayKeys arithmetic: the
/// origin's cell is visited first, the end's cell is not visited, a segment inside one cell
/// visits nothing, ties step along the higher axis, and the walk stops once the distance
/// travelled exceeds the segment's length (rounding may otherwise miss the end cell).
/// Real is the type of the points (float reproduces OctoMap bit for bit, double is exact
/// to double precision); step distances are double, as in OctoMap.
///
/// Lattice provides `int key(int axis, double coord)`, `double key_to_coord(int axis, int key)`
/// (the cell centre) and `double resolution()`. `visit(const CellKey<Dim>&)` returns false to
/// stop the walk early.
template <int Dim, typename Real, class Lattice, class Visit>
void walk_ray(const Lattice& lattice, const Real* origin, const Real* end, Visit&& visit) {
  CellKey<Dim> key, key_end;
  for (int i = 0; i < Dim; ++i) {
    key[i] = lattice.key(i, origin[i]);
    key_end[i] = lattice.key(i, end[i]);
  }
  if (key == key_end) return;
  if (!visit(key)) return;

  RayStart<Dim, Real> start = ray_start<Dim>(lattice, origin, end, key.data());
  const int* const step = start.step;
  double* const t_max = start.t_max;
  const double* const t_delta = start.t_delta;
  const Real length = start.length;

  if constexpr (Dim == 2) {
    // The same steps with scalar state: the compiler keeps it in registers and selects the
    // axis without a branch.
    int kx = key[0], ky = key[1];
    const int ex = key_end[0], ey = key_end[1], sx = step[0], sy = step[1];
    double tx = t_max[0], ty = t_max[1];
    const double dx = t_delta[0], dy = t_delta[1];
    for (;;) {
      const bool along_x = tx < ty;
      kx += along_x ? sx : 0;
      ky += along_x ? 0 : sy;
      tx += along_x ? dx : 0.0;
      ty += along_x ? 0.0 : dy;
      if (kx == ex && ky == ey) return;
      if (std::min(tx, ty) > length) return;
      if (!visit(CellKey<2>{kx, ky})) return;
    }
  }
  for (;;) {
    int dim = 0;
    for (int i = 1; i < Dim; ++i)
      if (!(t_max[dim] < t_max[i])) dim = i;
    key[dim] += step[dim];
    t_max[dim] += t_delta[dim];
    if (key == key_end) return;
    double travelled = t_max[0];
    for (int i = 1; i < Dim; ++i) travelled = std::min(travelled, t_max[i]);
    if (travelled > length) return;
    if (!visit(key)) return;
  }
}

}  // namespace probslam

namespace probslam {

/// walk_ray restricted to a box of keys: visits, in walk order, exactly the cells inside the box
/// that walk_ray(origin, end) visits, at a cost bounded by the box's size whatever the segment's
/// length. A segment that misses the box costs O(1); one whose origin lies inside the box (or
/// within a cell of it) is walked from its origin with walk_ray's own arithmetic (bit for bit the
/// unclipped walk) and stops where it leaves the box; one whose origin lies farther out starts at
/// the point where it enters the box grown by a cell (the same cells, up to rounding at a corner
/// the segment grazes within a few ulps). visit returns false to stop early.
template <int Dim, typename Real, class Lattice, class Visit>
void walk_ray_in_box(const Lattice& lattice, const KeyBox<Dim>& box, const Real* origin, const Real* end,
                     Visit&& visit) {
  CellKey<Dim> origin_key, end_key;
  for (int i = 0; i < Dim; ++i) {
    origin_key[i] = lattice.key(i, origin[i]);
    end_key[i] = lattice.key(i, end[i]);
  }
  if (box.contains(origin_key) && box.contains(end_key)) {
    // Both ends inside the box, so the whole segment is; rounding may still step beside a
    // segment that runs along the box's edge, hence the check.
    walk_ray<Dim, Real>(lattice, origin, end, [&](const CellKey<Dim>& k) { return !box.contains(k) || visit(k); });
    return;
  }
  // Liang-Barsky: the part of the segment inside the box grown by one cell on every side.
  const double res = lattice.resolution();
  double t_in = 0.0, t_out = 1.0;
  for (int i = 0; i < Dim; ++i) {
    const double lo = lattice.key_to_coord(i, box.lo[i] - 1) - 0.5 * res;
    const double hi = lattice.key_to_coord(i, box.hi[i]) + 0.5 * res;
    const double o = origin[i], d = static_cast<double>(end[i]) - o;
    // An end that overflowed lies beyond every box, on the side the segment heads to: the
    // arithmetic below would turn it into NaN, so such a segment is not walked at all.
    if (!std::isfinite(d)) return;
    if (d == 0.0) {
      if (!(o >= lo && o <= hi)) return;
      continue;
    }
    double a = (lo - o) / d, b = (hi - o) / d;
    if (a > b) std::swap(a, b);
    t_in = std::max(t_in, a);
    t_out = std::min(t_out, b);
  }
  if (!(t_in <= t_out)) return;  // misses the box (or NaN): nothing to visit
  Real start[Dim];
  const Real* from = origin;
  if (t_in > 0.0) {
    for (int i = 0; i < Dim; ++i)
      start[i] = static_cast<Real>(origin[i] + t_in * (static_cast<double>(end[i]) - origin[i]));
    from = start;
  }
  int step[Dim];
  for (int i = 0; i < Dim; ++i) step[i] = end[i] > from[i] ? 1 : (end[i] < from[i] ? -1 : 0);
  walk_ray<Dim, Real>(lattice, from, end, [&](const CellKey<Dim>& k) {
    bool inside = true;
    for (int i = 0; i < Dim; ++i) {
      // The walk is monotone per axis: outside and not heading back in means it is done.
      if (k[i] < box.lo[i]) {
        if (step[i] <= 0) return false;
        inside = false;
      } else if (k[i] >= box.hi[i]) {
        if (step[i] >= 0) return false;
        inside = false;
      }
    }
    return !inside || visit(k);
  });
}

}  // namespace probslam
