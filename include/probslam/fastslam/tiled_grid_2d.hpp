#pragma once
// A 2-D occupancy grid stored as tiles shared copy-on-write between particles (grid-based
// FastSLAM): copying a TiledGrid2D copies its table of tile pointers, never a cell; the first
// write to a tile another grid still holds clones that tile. A grid never sees another's change.
#include <Eigen/Core>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

class StateWriter;
class StateReader;

/// Tiles held by a set of grids: `references` counts a tile once per grid holding it,
/// `distinct` once in all (references - distinct tiles are shared, not copied).
struct TileSharing {
  std::size_t references = 0;
  std::size_t distinct = 0;
  std::size_t bytes = 0;  ///< memory of the distinct tiles
};

class TiledGrid2D {
 public:
  static constexpr int kTileShift = 5;
  static constexpr int kTileSize = 1 << kTileShift;  ///< cells per tile side (32 x 32 tiles)
  static constexpr int kTileCells = kTileSize * kTileSize;

  struct Tile {
    std::array<double, kTileCells> log_odds;  // row-major within the tile
  };
  /// Tiles alive in a family of grids (one grid and its copies): a counter, so that a memory
  /// bound costs one load rather than a walk over every tile.
  using TileCount = std::shared_ptr<std::atomic<std::int64_t>>;
  /// Allocates tiles (with their shared_ptr control block) and keeps the family's count: its
  /// copy in each control block keeps the counter alive as long as any tile.
  template <typename T>
  struct CountingAllocator {
    using value_type = T;
    TileCount count;
    explicit CountingAllocator(TileCount c) : count(std::move(c)) {}
    template <typename U>
    CountingAllocator(const CountingAllocator<U>& o) : count(o.count) {}  // NOLINT: rebinding
    T* allocate(std::size_t n) {
      T* p = std::allocator<T>().allocate(n);
      count->fetch_add(1, std::memory_order_relaxed);
      return p;
    }
    void deallocate(T* p, std::size_t n) {
      count->fetch_sub(1, std::memory_order_relaxed);
      std::allocator<T>().deallocate(p, n);
    }
    template <typename U>
    bool operator==(const CountingAllocator<U>& o) const { return count == o.count; }
    template <typename U>
    bool operator!=(const CountingAllocator<U>& o) const { return count != o.count; }
  };

  /// The geometry, prior, clamp, beam model and cells of `prototype` (a grid with only prior
  /// cells allocates no tile). Cells the grids never touch stay unallocated at the prior.
  explicit TiledGrid2D(const OccupancyGrid2D& prototype);

  /// Copies share every tile (O(tiles) pointer copies, no cell).
  TiledGrid2D(const TiledGrid2D&) = default;
  TiledGrid2D& operator=(const TiledGrid2D&) = default;
  TiledGrid2D(TiledGrid2D&&) noexcept = default;
  TiledGrid2D& operator=(TiledGrid2D&&) noexcept = default;

  double resolution() const { return lattice_.res; }
  int width() const { return width_; }
  int height() const { return height_; }
  Eigen::Vector2d origin() const { return {lattice_.x0, lattice_.y0}; }
  const GridLattice2D& lattice() const { return lattice_; }
  double prior_log_odds() const { return l0_; }

  bool contains(int row, int col) const {
    return static_cast<unsigned>(row) < static_cast<unsigned>(height_) &&
           static_cast<unsigned>(col) < static_cast<unsigned>(width_);
  }
  /// Log-odds of cell (row, col), which must lie inside (the prior where no tile is allocated).
  double log_odds(int row, int col) const {
    const Tile* t = tiles_[tile_index(row, col)].get();
    return t ? t->log_odds[cell_in_tile(row, col)] : l0_;
  }

  /// OccupancyGrid2D::insert_rays on this grid, with the same rules, result and checks
  /// (std::invalid_argument naming the argument; nothing changes then).
  std::size_t insert_rays(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                          const Eigen::Ref<const Eigen::VectorXd>& beam_angles, double max_range);

  /// Grows the grid by whole tiles (it never shrinks) to cover [xmin, xmax] x [ymin, ymax] (m):
  /// cells keep their values and tiles their sharing, new cells hold the prior, no cell is
  /// copied. std::invalid_argument for non-finite bounds or beyond OccupancyGrid2D::kMaxCells.
  void grow_to_include(double xmin, double ymin, double xmax, double ymax);

  /// Cells of the grid grow_to_include would make (as a double; this grid's when no growth is
  /// needed): a pure size computation, nothing allocated, for checks before a commit.
  double cells_after_growth(double xmin, double ymin, double xmax, double ymax) const;
  /// Tile table slots after that growth.
  double tiles_after_growth(double xmin, double ymin, double xmax, double ymax) const;
  /// Tiles alive in this grid's family (it and every grid copied from it, directly or not).
  std::int64_t live_tiles() const { return tile_count_->load(std::memory_order_relaxed); }

  /// The cells as a dense grid (geometry and settings as the prototype's).
  OccupancyGrid2D to_grid() const;

  int tiles_x() const { return tiles_x_; }
  int tiles_y() const { return tiles_y_; }
  /// Tiles this grid holds (allocated, shared or not).
  std::size_t tiles_allocated() const;
  /// True when this grid and `other` hold the same tile object at table slot `tile`.
  bool shares_tile(const TiledGrid2D& other, std::size_t tile) const {
    return tiles_[tile] != nullptr && tiles_[tile] == other.tiles_[tile];
  }
  static TileSharing sharing(const std::vector<const TiledGrid2D*>& grids);
  /// Deep copies of `grids` (entry k's copy at k; null stays null) in a new family: each distinct
  /// tile is cloned once, so tiles (and grids) shared among `grids` are shared among the copies
  /// as they were, and no copy shares a tile or a tile count with an original.
  static std::vector<std::shared_ptr<TiledGrid2D>> deep_copy(const std::vector<std::shared_ptr<TiledGrid2D>>& grids);
  /// `grids` as state: each distinct grid and each distinct tile once, so read_family gives
  /// deep_copy's result (the same sharing, in a family of its own). Null entries stay null.
  static void write_family(StateWriter& w, const std::vector<std::shared_ptr<TiledGrid2D>>& grids);
  static std::vector<std::shared_ptr<TiledGrid2D>> read_family(StateReader& r);

 private:
  friend class TiledScanStore;
  std::size_t tile_index(int row, int col) const {
    return static_cast<std::size_t>(row >> kTileShift) * tiles_x_ + (col >> kTileShift);
  }
  static int cell_in_tile(int row, int col) {
    return ((row & (kTileSize - 1)) << kTileShift) | (col & (kTileSize - 1));
  }
  /// The tile at `index`, this grid's alone: allocated at the prior, or cloned if shared.
  Tile& writable_tile(std::size_t index);
  struct Growth {
    double add_left = 0, add_down = 0, width = 0, height = 0;  // tiles added, cells after
    bool none = true;
  };
  Growth plan_growth(double xmin, double ymin, double xmax, double ymax) const;

  GridLattice2D lattice_;
  int width_ = 0, height_ = 0, tiles_x_ = 0, tiles_y_ = 0;
  double p_prior_ = 0.5, l0_ = 0.0;
  LogOddsClamp clamp_;
  BeamModel beam_;
  TileCount tile_count_ = std::make_shared<std::atomic<std::int64_t>>(0);
  std::vector<std::shared_ptr<Tile>> tiles_;  // row-major tile table; nullptr: all prior
};

}  // namespace probslam
