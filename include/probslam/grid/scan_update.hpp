#pragma once
// The per-scan hit/miss update of the laser-beam model, shared by the 2-D and 3-D grids.
#include <cstddef>
#include <cstdint>

#include "probslam/grid/ray_traversal.hpp"

namespace probslam {

/// One scan's rays, already turned into segments: `ends` holds n end points of Dim
/// coordinates each, `is_hit[i]` says whether ray i ends in an obstacle (else it only clears).
template <int Dim, typename Real>
struct ScanSegments {
  const Real* origin;
  const Real* ends;
  const std::uint8_t* is_hit;
  std::size_t n;
};

/// The hit half of a scan: every hit's end cell gets the hit update (once per scan). Run it
/// before apply_misses so that a cell both hit and crossed counts as hit. Returns the number of
/// cells updated.
template <int Dim, typename Real, class Lattice, class Store>
std::size_t apply_hits(const Lattice& lattice, Store& store, const ScanSegments<Dim, Real>& scan) {
  std::size_t updated = 0;
  for (std::size_t i = 0; i < scan.n; ++i) {
    if (!scan.is_hit[i]) continue;
    CellKey<Dim> key;
    for (int d = 0; d < Dim; ++d) key[d] = lattice.key(d, scan.ends[i * Dim + d]);
    if (store.contains(key) && store.update_once(key, true)) ++updated;
  }
  return updated;
}

/// The miss half of a scan for rays [first, last): every cell a ray crosses (origin's cell
/// included, end cell excluded) gets the miss update unless it changed already in this scan.
/// Split from apply_hits so that a caller may walk disjoint ranges of rays concurrently.
template <int Dim, typename Real, class Lattice, class Store>
std::size_t apply_misses(const Lattice& lattice, Store& store, const ScanSegments<Dim, Real>& scan,
                         std::size_t first, std::size_t last) {
  std::size_t updated = 0;
  CellKey<Dim> origin_key;
  for (int d = 0; d < Dim; ++d) origin_key[d] = lattice.key(d, scan.origin[d]);
  const bool origin_inside = store.contains(origin_key);
  for (std::size_t i = first; i < last; ++i) {
    const Real* end = scan.ends + i * Dim;
    CellKey<Dim> end_key;
    for (int d = 0; d < Dim; ++d) end_key[d] = lattice.key(d, end[d]);
    if (origin_inside && store.contains(end_key)) {
      // Both ends inside a box, so the whole segment is: the walk need not watch for an exit.
      // (The check stays: rounding may step beside a segment that runs along the box's edge.)
      walk_ray<Dim, Real>(lattice, scan.origin, end, [&](const CellKey<Dim>& key) {
        if (store.contains(key)) updated += store.update_once(key, false);
        return true;
      });
      continue;
    }
    bool entered = false;
    walk_ray<Dim, Real>(lattice, scan.origin, end, [&](const CellKey<Dim>& key) {
      if (!store.contains(key)) return !entered;  // a segment leaves a box only once
      entered = true;
      if (store.update_once(key, false)) ++updated;
      return true;
    });
  }
  return updated;
}

/// Applies one scan with OctoMap's rules: every cell a ray crosses (origin's cell included,
/// end cell excluded) gets the miss update, every end cell of a hit the hit update; within a
/// scan each cell changes at most once and a cell both hit and crossed counts as hit.
///
/// Store provides `bool contains(const CellKey<Dim>&)` and `bool update_once(const CellKey<Dim>&,
/// bool hit)`, which applies the update unless the cell was already updated in this scan (the
/// caller starts a new scan on the store first). Rays leaving a bounded store stop there.
/// Returns the number of cells updated.
template <int Dim, typename Real, class Lattice, class Store>
std::size_t apply_scan(const Lattice& lattice, Store& store, const ScanSegments<Dim, Real>& scan) {
  // Hits first, so that a later ray crossing a hit cell leaves it alone.
  const std::size_t hits = apply_hits(lattice, store, scan);
  return hits + apply_misses(lattice, store, scan, 0, scan.n);
}

}  // namespace probslam
