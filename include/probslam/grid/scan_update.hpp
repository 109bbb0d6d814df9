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
  const KeyBox<Dim> box = store.box();
  for (std::size_t i = first; i < last; ++i) {
    // Clipped to the store's box: a ray costs what its part inside costs, whatever its length.
    walk_ray_in_box<Dim, Real>(lattice, box, scan.origin, scan.ends + i * Dim, [&](const CellKey<Dim>& key) {
      updated += store.update_once(key, false);
      return true;
    });
  }
  return updated;
}

/// Applies one scan with OctoMap's rules: every cell a ray crosses (origin's cell included,
/// end cell excluded) gets the miss update, every end cell of a hit the hit update; within a
/// scan each cell changes at most once and a cell both hit and crossed counts as hit.
///
/// Store provides `bool contains(const CellKey<Dim>&)`, `KeyBox<Dim> box()` (the keys it holds)
/// and `bool update_once(const CellKey<Dim>&, bool hit)`, which applies the update unless the
/// cell was already updated in this scan (the caller starts a new scan on the store first). Rays
/// are clipped to the store's box.
/// Returns the number of cells updated.
template <int Dim, typename Real, class Lattice, class Store>
std::size_t apply_scan(const Lattice& lattice, Store& store, const ScanSegments<Dim, Real>& scan) {
  // Hits first, so that a later ray crossing a hit cell leaves it alone.
  const std::size_t hits = apply_hits(lattice, store, scan);
  return hits + apply_misses(lattice, store, scan, 0, scan.n);
}

}  // namespace probslam
