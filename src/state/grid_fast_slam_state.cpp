// GridFastSlam's and its tiled maps' state (docs/file_format.md).
#include <cmath>
#include <unordered_map>

#include "probslam/core/options_description.hpp"
#include "probslam/fastslam/grid_fast_slam.hpp"
#include "probslam/fastslam/tiled_grid_2d.hpp"

namespace probslam {

void TiledGrid2D::write_family(StateWriter& w, const std::vector<std::shared_ptr<TiledGrid2D>>& grids) {
  std::unordered_map<const Tile*, std::int64_t> tile_index;
  std::vector<const Tile*> tiles;
  std::unordered_map<const TiledGrid2D*, std::int64_t> grid_index;
  std::vector<const TiledGrid2D*> distinct;
  for (const auto& g : grids) {
    if (!g || !grid_index.emplace(g.get(), static_cast<std::int64_t>(distinct.size())).second) continue;
    distinct.push_back(g.get());
    for (const auto& t : g->tiles_)
      if (t && tile_index.emplace(t.get(), static_cast<std::int64_t>(tiles.size())).second) tiles.push_back(t.get());
  }
  w.count(tiles.size());
  for (const Tile* t : tiles)
    for (double v : t->log_odds) w.f64(v);
  w.count(distinct.size());
  for (const TiledGrid2D* g : distinct) {
    for (double v : {g->lattice_.x0, g->lattice_.y0, g->lattice_.res, g->lattice_.inv_res}) w.f64(v);
    for (int v : {g->width_, g->height_, g->tiles_x_, g->tiles_y_}) w.i32(v);
    w.f64(g->p_prior_);
    w.f64(g->l0_);
    w.boolean(g->clamp_.enabled);
    w.f64(g->clamp_.min);
    w.f64(g->clamp_.max);
    w.f64(g->beam_.p_hit);
    w.f64(g->beam_.p_miss);
    w.count(g->tiles_.size());
    for (const auto& t : g->tiles_) w.i64(t ? tile_index.at(t.get()) : -1);
  }
  w.count(grids.size());
  for (const auto& g : grids) w.i64(g ? grid_index.at(g.get()) : -1);
}

std::vector<std::shared_ptr<TiledGrid2D>> TiledGrid2D::read_family(StateReader& r) {
  const TileCount count = std::make_shared<std::atomic<std::int64_t>>(0);
  const std::size_t nt = r.count(8 * kTileCells);
  std::vector<std::shared_ptr<Tile>> tiles;
  tiles.reserve(nt);
  for (std::size_t k = 0; k < nt; ++k) {
    auto t = std::allocate_shared<Tile>(CountingAllocator<Tile>(count));
    for (double& v : t->log_odds) {
      v = r.f64();
      if (!(std::abs(v) <= kMaxLogOddsValue)) r.fail("a tile's log-odds is not finite or out of range");
    }
    tiles.push_back(std::move(t));
  }
  const std::size_t ng = r.count(100);
  std::vector<std::shared_ptr<TiledGrid2D>> distinct;
  for (std::size_t k = 0; k < ng; ++k) {
    // A grid of one prior cell, its every field then replaced by the saved ones and checked.
    auto g = std::make_shared<TiledGrid2D>(OccupancyGrid2D(1.0, 1, 1));
    g->tile_count_ = count;
    for (double* v : {&g->lattice_.x0, &g->lattice_.y0, &g->lattice_.res, &g->lattice_.inv_res}) *v = r.f64();
    for (int* v : {&g->width_, &g->height_, &g->tiles_x_, &g->tiles_y_}) *v = r.i32();
    g->p_prior_ = r.f64();
    g->l0_ = r.f64();
    g->clamp_.enabled = r.boolean();
    g->clamp_.min = r.f64();
    g->clamp_.max = r.f64();
    g->beam_.p_hit = r.f64();
    g->beam_.p_miss = r.f64();
    if (!(g->lattice_.res > 0.0) || !std::isfinite(g->lattice_.x0) || !std::isfinite(g->lattice_.y0) ||
        g->width_ <= 0 || g->height_ <= 0 ||
        static_cast<double>(g->width_) * g->height_ > static_cast<double>(OccupancyGrid2D::kMaxCells) ||
        g->tiles_x_ != (g->width_ + kTileSize - 1) / kTileSize || g->tiles_y_ != (g->height_ + kTileSize - 1) / kTileSize)
      r.fail("a tiled grid's geometry is inconsistent");
    const std::size_t slots = r.count(8);
    if (slots != static_cast<std::size_t>(g->tiles_x_) * static_cast<std::size_t>(g->tiles_y_))
      r.fail("a tiled grid's table does not match its size");
    g->tiles_.assign(slots, nullptr);
    for (auto& slot : g->tiles_) {
      const std::int64_t t = r.i64();
      if (t < -1 || t >= static_cast<std::int64_t>(nt)) r.fail("a tile index is out of range");
      if (t >= 0) slot = tiles[static_cast<std::size_t>(t)];
    }
    distinct.push_back(std::move(g));
  }
  const std::size_t n = r.count(8);
  std::vector<std::shared_ptr<TiledGrid2D>> out;
  out.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::int64_t g = r.i64();
    if (g < -1 || g >= static_cast<std::int64_t>(ng)) r.fail("a grid index is out of range");
    out.push_back(g >= 0 ? distinct[static_cast<std::size_t>(g)] : nullptr);
  }
  return out;
}

void GridFastSlam::write_state(StateWriter& w) const {
  write_options(w, options_);  // the fields in describe()'s order
  w.boolean(corrector_ != nullptr);
  if (corrector_) corrector_->write_state(w);
  w.count(particles_.size());
  std::vector<std::shared_ptr<TiledGrid2D>> maps;
  for (const Particle& p : particles_) {
    w.matrix(p.pose);
    w.f64(p.log_weight);
    p.path.write_state(w);
    p.rng.write_state(w);
    maps.push_back(p.map);
  }
  TiledGrid2D::write_family(w, maps);
  rng_.write_state(w);
  w.u64(next_stream_);
  w.matrix(last_update_odometry_);
  w.matrix(last_update_raw_);
  w.matrix(corrected_cov_);
  w.matrix(last_corrected_);
  w.ints(scan_step_);
  w.count(scan_offset_.size());
  for (const Eigen::Vector3d& o : scan_offset_) w.matrix(o);
  w.doubles(timestamps_);
  const GridFastSlamSummary& s = summary_;
  for (long v : {s.scans, s.updates, s.resamples, s.matched, s.fallbacks}) w.i64(v);
  w.f64(s.effective_sample_size);
  w.boolean(start_map_.has_value());
  if (start_map_) {
    start_map_->write_state(w);
    w.matrix(initial_pose_);
  }
}

GridFastSlam GridFastSlam::read_state(StateReader& r) {
  GridFastSlamOptions o;
  read_options(r, o);
  GridFastSlam f = validated(r, "options", [&] { return GridFastSlam(o); });
  const bool has_corrector = r.boolean();
  if (has_corrector != (f.corrector_ != nullptr)) r.fail("the corrector does not match the options");
  if (has_corrector) f.corrector_ = std::make_unique<IncrementalScanMatcher>(IncrementalScanMatcher::read_state(r));
  const std::size_t m = r.count(40);
  if (m != f.particles_.size()) r.fail("holds " + std::to_string(m) + " particles, its options " + std::to_string(f.particles_.size()));
  for (Particle& p : f.particles_) {
    p.pose = r.matrix<Eigen::Vector3d>();
    p.log_weight = r.f64();
    p.path = PosePath::read_state(r);
    p.rng = ParticleRng::read_state(r);
    if (!p.pose.allFinite() || std::isnan(p.log_weight)) r.fail("a particle's pose or weight is not finite");
  }
  std::vector<std::shared_ptr<TiledGrid2D>> maps = TiledGrid2D::read_family(r);
  if (maps.size() != m) r.fail("the maps are not one per particle");
  for (std::size_t k = 0; k < m; ++k) {
    if (maps[k] && maps[k]->resolution() != o.resolution) r.fail("a particle's map has another resolution");
    f.particles_[k].map = std::move(maps[k]);
  }
  f.rng_ = ParticleRng::read_state(r);
  f.next_stream_ = r.u64();
  f.last_update_odometry_ = r.matrix<Eigen::Vector3d>();
  f.last_update_raw_ = r.matrix<Eigen::Vector3d>();
  f.corrected_cov_ = r.matrix<Eigen::Matrix3d>();
  f.last_corrected_ = r.matrix<Eigen::Vector3d>();
  f.scan_step_ = r.ints();
  const std::size_t no = r.count(40);
  for (std::size_t k = 0; k < no; ++k) f.scan_offset_.push_back(r.matrix<Eigen::Vector3d>());
  f.timestamps_ = r.doubles();
  if (f.scan_offset_.size() != f.scan_step_.size() || f.timestamps_.size() != f.scan_step_.size())
    r.fail("the scans' steps, offsets and timestamps differ in number");
  if (f.corrector_ && static_cast<std::size_t>(f.corrector_->num_scans()) != f.scan_step_.size())
    r.fail("the odometry corrector's scans do not match the filter's");
  for (const Eigen::Vector3d& offset : f.scan_offset_)
    if (!offset.allFinite()) r.fail("a scan's offset is not finite");
  for (const Particle& p : f.particles_) {
    if (!f.scan_step_.empty() && !p.map) r.fail("a particle has no map after the first scan");
    for (int step : f.scan_step_)
      if (step < 0 || static_cast<std::size_t>(step) >= p.path.size()) r.fail("a scan hangs from a step out of range");
  }
  GridFastSlamSummary& s = f.summary_;
  for (long* v : {&s.scans, &s.updates, &s.resamples, &s.matched, &s.fallbacks})
    if ((*v = static_cast<long>(r.i64())) < 0) r.fail("a counter is negative");
  if (static_cast<std::size_t>(s.scans) != f.scan_step_.size()) r.fail("the scan count does not match the scans stored");
  s.effective_sample_size = r.f64();
  if (r.boolean()) {
    f.start_map_ = OccupancyGrid2D::read_state(r);
    f.initial_pose_ = r.matrix<Eigen::Vector3d>();
    if (!f.initial_pose_.allFinite()) r.fail("the initial pose on the start map is not finite");
  }
  return f;
}

void GridFastSlam::save(const std::string& path) const { save_state(*this, path); }
GridFastSlam GridFastSlam::load(const std::string& path) { return load_state<GridFastSlam>(path); }

}  // namespace probslam
