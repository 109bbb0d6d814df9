#pragma once
// Exact grid traversal of a ray (Amanatides & Woo), shared by the 2-D and 3-D grids.
#include <array>
#include <cmath>
#include <limits>

namespace probslam {

template <int Dim>
using CellKey = std::array<int, Dim>;

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

  Real direction[Dim];
  Real length_sq = 0;
  for (int i = 0; i < Dim; ++i) {
    direction[i] = end[i] - origin[i];
    length_sq += direction[i] * direction[i];
  }
  const Real length = static_cast<Real>(std::sqrt(static_cast<double>(length_sq)));
  for (int i = 0; i < Dim; ++i) direction[i] /= length;

  int step[Dim];
  double t_max[Dim], t_delta[Dim];
  const double res = lattice.resolution();
  for (int i = 0; i < Dim; ++i) {
    step[i] = direction[i] > 0 ? 1 : (direction[i] < 0 ? -1 : 0);
    if (step[i] != 0) {
      double border = lattice.key_to_coord(i, key[i]);
      border += static_cast<Real>(step[i] * res * 0.5);
      t_max[i] = (border - origin[i]) / direction[i];
      t_delta[i] = res / std::fabs(direction[i]);
    } else {
      t_max[i] = std::numeric_limits<double>::max();
      t_delta[i] = std::numeric_limits<double>::max();
    }
  }

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
