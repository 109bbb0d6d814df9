#include "probslam/fastslam/tiled_grid_2d.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "probslam/core/check.hpp"

namespace probslam {

/// The tiled grid as apply_scan sees it (OccupancyGrid2D's GridScanStore over tiles). The cells
/// this scan updated are marked in a bitmap per touched tile, held by the store alone: tiles carry
/// no per-cell stamp (a third of their memory), and a finished tile is its log-odds only.
class TiledScanStore {
 public:
  explicit TiledScanStore(TiledGrid2D& grid)
      : grid_(grid),
        hit_delta_(logit(grid.beam_.p_hit) - grid.l0_),
        miss_delta_(logit(grid.beam_.p_miss) - grid.l0_),
        slot_(grid.tiles_.size(), -1) {}
  bool contains(const CellKey<2>& key) const { return grid_.contains(key[1], key[0]); }
  KeyBox<2> box() const { return {{0, 0}, {grid_.width_, grid_.height_}}; }
  bool update_once(const CellKey<2>& key, bool hit) {
    const int row = key[1], col = key[0];
    const std::size_t t = grid_.tile_index(row, col);
    const int c = TiledGrid2D::cell_in_tile(row, col);
    int& slot = slot_[t];
    if (slot < 0) {
      slot = static_cast<int>(seen_.size());
      seen_.emplace_back();
      seen_.back().fill(0u);
    }
    // Checked before writing: a cell already updated in this scan needs no private tile.
    std::uint64_t& word = seen_[static_cast<std::size_t>(slot)][static_cast<std::size_t>(c >> 6)];
    const std::uint64_t bit = std::uint64_t{1} << (c & 63);
    if (word & bit) return false;
    word |= bit;
    TiledGrid2D::Tile& tile = grid_.writable_tile(t);
    tile.log_odds[c] = grid_.clamp_.apply(tile.log_odds[c] + (hit ? hit_delta_ : miss_delta_));
    return true;
  }

 private:
  TiledGrid2D& grid_;
  double hit_delta_, miss_delta_;
  std::vector<int> slot_;  // per tile-table slot: its bitmap in seen_, or -1 (untouched)
  std::vector<std::array<std::uint64_t, TiledGrid2D::kTileCells / 64>> seen_;  // cells updated, per touched tile
};

TiledGrid2D::TiledGrid2D(const OccupancyGrid2D& prototype)
    : lattice_(prototype.lattice()),
      width_(prototype.width()),
      height_(prototype.height()),
      tiles_x_((prototype.width() + kTileSize - 1) >> kTileShift),
      tiles_y_((prototype.height() + kTileSize - 1) >> kTileShift),
      p_prior_(prototype.p_prior()),
      l0_(prototype.prior_log_odds()),
      clamp_(prototype.clamp()),
      beam_(prototype.beam_model()),
      tiles_(static_cast<std::size_t>(tiles_x_) * tiles_y_) {
  const double* cells = prototype.data();
  for (int row = 0; row < height_; ++row)
    for (int col = 0; col < width_; ++col) {
      const double l = cells[static_cast<std::size_t>(row) * width_ + col];
      if (l != l0_) writable_tile(tile_index(row, col)).log_odds[cell_in_tile(row, col)] = l;
    }
}

TiledGrid2D::Tile& TiledGrid2D::writable_tile(std::size_t index) {
  std::shared_ptr<Tile>& slot = tiles_[index];
  if (!slot) {
    slot = std::allocate_shared<Tile>(CountingAllocator<Tile>(tile_count_));
    slot->log_odds.fill(l0_);
  } else if (slot.use_count() > 1) {
    slot = std::allocate_shared<Tile>(CountingAllocator<Tile>(tile_count_), *slot);
  } else {
    // Sole owner: the other holders' reads of this tile (before they let go of it, a release
    // decrement) happen before the writes that follow.
    std::atomic_thread_fence(std::memory_order_acquire);
  }
  return *slot;
}

std::size_t TiledGrid2D::insert_rays(const Eigen::Vector3d& pose, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                                     const Eigen::Ref<const Eigen::VectorXd>& beam_angles, double max_range) {
  check_scan_shape(pose, ranges, beam_angles);
  require_positive(max_range, "max_range");
  LaserSegments2D segments;
  if (!laser_segments(lattice_, width_, height_, pose, ranges, beam_angles, max_range, segments)) return 0;
  TiledScanStore store(*this);
  return apply_scan<2, double>(lattice_, store, segments.view());
}

TiledGrid2D::Growth TiledGrid2D::plan_growth(double xmin, double ymin, double xmax, double ymax) const {
  require(std::isfinite(xmin) && std::isfinite(xmax) && xmin <= xmax, "xmin", "must be finite and <= xmax");
  require(std::isfinite(ymin) && std::isfinite(ymax) && ymin <= ymax, "ymin", "must be finite and <= ymax");
  const double tile_m = kTileSize * lattice_.res;
  Growth g;
  // Tiles to add on each side, as doubles first: far bounds must be refused, not overflow.
  g.add_left = std::max(0.0, std::ceil((lattice_.x0 - xmin) / tile_m));
  g.add_down = std::max(0.0, std::ceil((lattice_.y0 - ymin) / tile_m));
  const double new_x0 = lattice_.x0 - g.add_left * tile_m, new_y0 = lattice_.y0 - g.add_down * tile_m;
  g.width = std::max(g.add_left * kTileSize + width_, std::ceil((xmax - new_x0) / lattice_.res) + 1.0);
  g.height = std::max(g.add_down * kTileSize + height_, std::ceil((ymax - new_y0) / lattice_.res) + 1.0);
  g.none = g.add_left == 0.0 && g.add_down == 0.0 && g.width == width_ && g.height == height_;
  return g;
}

double TiledGrid2D::cells_after_growth(double xmin, double ymin, double xmax, double ymax) const {
  const Growth g = plan_growth(xmin, ymin, xmax, ymax);
  return g.width * g.height;
}

double TiledGrid2D::tiles_after_growth(double xmin, double ymin, double xmax, double ymax) const {
  const Growth g = plan_growth(xmin, ymin, xmax, ymax);
  return std::ceil(g.width / kTileSize) * std::ceil(g.height / kTileSize);
}

void TiledGrid2D::grow_to_include(double xmin, double ymin, double xmax, double ymax) {
  const Growth g = plan_growth(xmin, ymin, xmax, ymax);
  if (g.none) return;
  const double add_left = g.add_left, add_down = g.add_down, width = g.width, height = g.height;
  const double tile_m = kTileSize * lattice_.res;
  const double new_x0 = lattice_.x0 - add_left * tile_m, new_y0 = lattice_.y0 - add_down * tile_m;
  if (width * height > static_cast<double>(OccupancyGrid2D::kMaxCells))
    throw_invalid_argument("xmax", "would grow the grid beyond OccupancyGrid2D.max_cells = " +
                                       std::to_string(OccupancyGrid2D::kMaxCells));
  const int left = static_cast<int>(add_left), down = static_cast<int>(add_down);
  const int new_w = static_cast<int>(width), new_h = static_cast<int>(height);
  const int new_tx = (new_w + kTileSize - 1) >> kTileShift, new_ty = (new_h + kTileSize - 1) >> kTileShift;
  std::vector<std::shared_ptr<Tile>> table(static_cast<std::size_t>(new_tx) * new_ty);
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx)
      table[static_cast<std::size_t>(ty + down) * new_tx + (tx + left)] = std::move(tiles_[static_cast<std::size_t>(ty) * tiles_x_ + tx]);
  tiles_ = std::move(table);
  lattice_.x0 = new_x0;
  lattice_.y0 = new_y0;
  width_ = new_w;
  height_ = new_h;
  tiles_x_ = new_tx;
  tiles_y_ = new_ty;
}

OccupancyGrid2D TiledGrid2D::to_grid() const {
  OccupancyGrid2D grid(lattice_.res, width_, height_, origin(), p_prior_, clamp_);
  grid.set_beam_model(beam_);
  double* cells = grid.data();
  for (int row = 0; row < height_; ++row)
    for (int col = 0; col < width_; ++col) cells[static_cast<std::size_t>(row) * width_ + col] = log_odds(row, col);
  return grid;
}

std::size_t TiledGrid2D::tiles_allocated() const {
  std::size_t n = 0;
  for (const auto& t : tiles_) n += t != nullptr;
  return n;
}

TileSharing TiledGrid2D::sharing(const std::vector<const TiledGrid2D*>& grids) {
  TileSharing s;
  std::unordered_set<const Tile*> distinct;
  for (const TiledGrid2D* g : grids) {
    require(g != nullptr, "grids", "must not hold a null grid");
    for (const auto& t : g->tiles_)
      if (t) {
        ++s.references;
        distinct.insert(t.get());
      }
  }
  s.distinct = distinct.size();
  s.bytes = s.distinct * sizeof(Tile);
  return s;
}

std::vector<std::shared_ptr<TiledGrid2D>> TiledGrid2D::deep_copy(const std::vector<std::shared_ptr<TiledGrid2D>>& grids) {
  const TileCount count = std::make_shared<std::atomic<std::int64_t>>(0);
  std::unordered_map<const TiledGrid2D*, std::shared_ptr<TiledGrid2D>> grid_copies;
  std::unordered_map<const Tile*, std::shared_ptr<Tile>> tile_copies;
  std::vector<std::shared_ptr<TiledGrid2D>> out;
  out.reserve(grids.size());
  for (const std::shared_ptr<TiledGrid2D>& g : grids) {
    if (!g) {
      out.emplace_back();
      continue;
    }
    std::shared_ptr<TiledGrid2D>& copy = grid_copies[g.get()];
    if (!copy) {
      copy = std::make_shared<TiledGrid2D>(*g);  // the table, still pointing at g's tiles
      copy->tile_count_ = count;
      for (std::shared_ptr<Tile>& t : copy->tiles_) {
        if (!t) continue;
        std::shared_ptr<Tile>& clone = tile_copies[t.get()];
        if (!clone) clone = std::allocate_shared<Tile>(CountingAllocator<Tile>(count), *t);
        t = clone;
      }
    }
    out.push_back(copy);
  }
  return out;
}

}  // namespace probslam
