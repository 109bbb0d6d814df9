// OccupancyGrid2D's state (docs/file_format.md).
#include <cmath>

#include "probslam/core/state_file.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

void OccupancyGrid2D::write_state(StateWriter& w) const {
  w.f64(lattice_.res);
  w.i32(width_);
  w.i32(height_);
  w.f64(lattice_.x0);
  w.f64(lattice_.y0);
  w.f64(p_prior_);
  w.boolean(clamp_.enabled);
  w.f64(clamp_.min);
  w.f64(clamp_.max);
  w.f64(beam_.p_hit);
  w.f64(beam_.p_miss);
  w.doubles(log_odds_);
}

OccupancyGrid2D OccupancyGrid2D::read_state(StateReader& r) {
  const double res = r.f64();
  const int width = r.i32(), height = r.i32();
  const double x0 = r.f64(), y0 = r.f64(), p_prior = r.f64();
  LogOddsClamp clamp;
  clamp.enabled = r.boolean();
  clamp.min = r.f64();
  clamp.max = r.f64();
  if (!clamp.enabled) clamp = LogOddsClamp::none();
  BeamModel beam;
  beam.p_hit = r.f64();
  beam.p_miss = r.f64();
  // The cells' bytes must be there before the constructor allocates them.
  r.require_bytes(8.0 + 8.0 * static_cast<double>(width) * static_cast<double>(height), "the grid's cells");
  OccupancyGrid2D grid = validated(r, "grid", [&] {
    OccupancyGrid2D g(res, width, height, {x0, y0}, p_prior, clamp);
    g.set_beam_model(beam);
    return g;
  });
  std::vector<double> cells = r.doubles();
  if (cells.size() != grid.log_odds_.size()) r.fail("the grid holds a wrong number of cells");
  for (double l : cells)
    if (!(std::abs(l) <= kMaxLogOddsValue)) r.fail("a cell's log-odds is not finite or out of range");
  grid.log_odds_ = std::move(cells);
  return grid;
}

void OccupancyGrid2D::save(const std::string& path) const { save_state(*this, path); }
OccupancyGrid2D OccupancyGrid2D::load(const std::string& path) { return load_state<OccupancyGrid2D>(path); }

}  // namespace probslam
