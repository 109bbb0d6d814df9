// OccupancyGrid3D's state (docs/file_format.md): the blocks as they are allocated, so that a
// loaded grid is the saved one block for block.
#include <cmath>
#include <string>

#include "probslam/core/state_file.hpp"
#include "probslam/grid/occupancy_grid_3d.hpp"

namespace probslam {

namespace {
/// A packed block key holds three 16-bit block coordinates (OccupancyGrid3D::pack): the block
/// coordinates of valid voxel keys are below 2^16 / kBlockSide, and nothing lies above bit 48.
bool valid_block_key(std::uint64_t packed) {
  constexpr std::uint64_t kLimit = OctreeLattice::kKeyLimit >> OccupancyGrid3D::kBlockBits;
  return (packed >> 48) == 0 && (packed & 0xffff) < kLimit && ((packed >> 16) & 0xffff) < kLimit &&
         ((packed >> 32) & 0xffff) < kLimit;
}
}  // namespace

void OccupancyGrid3D::write_state(StateWriter& w) const {
  w.f64(lattice_.res);
  w.f64(params_.p_hit);
  w.f64(params_.p_miss);
  w.f64(params_.clamp_min);
  w.f64(params_.clamp_max);
  w.f64(params_.occupancy_threshold);
  w.count(block_keys_.size());
  for (std::size_t b = 0; b < block_keys_.size(); ++b) {
    w.u64(block_keys_[b]);
    const float* v = block_values(b);
    for (int i = 0; i < kBlockVoxels; ++i) w.f32(v[i]);
  }
}

OccupancyGrid3D OccupancyGrid3D::read_state(StateReader& r) {
  const double res = r.f64();
  OccupancyParams3D params;
  params.p_hit = r.f64();
  params.p_miss = r.f64();
  params.clamp_min = r.f64();
  params.clamp_max = r.f64();
  params.occupancy_threshold = r.f64();
  OccupancyGrid3D grid = validated(r, "grid", [&] { return OccupancyGrid3D(res, params); });
  // count() checks the blocks' bytes are there before any block is allocated.
  const std::size_t blocks = r.count(8 + 4 * static_cast<std::size_t>(kBlockVoxels));
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::uint64_t packed = r.u64();
    if (!valid_block_key(packed)) r.fail("block " + std::to_string(b) + " has a key outside OctoMap's key range");
    if (grid.find_block(packed) >= 0) r.fail("block " + std::to_string(b) + " repeats an earlier block's key");
    const std::size_t index = grid.find_or_create_block(packed);
    float* v = grid.block_values(index);
    std::uint32_t known = 0;
    for (int i = 0; i < kBlockVoxels; ++i) {
      v[i] = r.f32();
      if (std::isnan(v[i])) continue;
      // Every update clamps: a known voxel outside the bounds is a damaged file.
      if (!(v[i] >= grid.lo_ && v[i] <= grid.hi_))
        r.fail("a voxel's log-odds " + std::to_string(v[i]) + " lies outside the clamp bounds");
      ++known;
    }
    grid.known_[index] = known;
  }
  return grid;
}

void OccupancyGrid3D::save(const std::string& path) const { save_state(*this, path); }
OccupancyGrid3D OccupancyGrid3D::load(const std::string& path) { return load_state<OccupancyGrid3D>(path); }

}  // namespace probslam
