#pragma once
// OctoMap's binary octree format (.bt), as written by OcTree::writeBinary and read by
// OcTree::readBinary and octovis: a text header, then the tree depth first, two bytes per inner
// node holding two bits per child (00 unknown, 10 free leaf, 01 occupied leaf, 11 inner node;
// child i sets bit i&1 of x, bit 1 of y, bit 2 of z at that level). It stores occupancy only.
#include <cstddef>
#include <string>

#include "probslam/grid/occupancy_grid_3d.hpp"

namespace probslam {

/// Writes the grid's maximum-likelihood map: each known voxel occupied or free by the grid's
/// threshold, full uniform octants collapsed into one leaf (OctoMap's prune). Returns the
/// number of tree nodes written (the header's `size`).
std::size_t write_octomap_bt(const OccupancyGrid3D& grid, const std::string& path);

/// Reads a .bt file of an `OcTree` into a grid of the file's resolution. The format keeps no
/// log-odds: occupied leaves get logit(params.clamp_max), free ones logit(params.clamp_min), as
/// OcTree::readBinary does. Throws std::invalid_argument on a file that is not a complete,
/// consistent OcTree (bad header, other tree type, truncated or malformed data, node count not
/// matching the header) or that would expand to more than kMaxBtImportVoxels voxels.
OccupancyGrid3D read_octomap_bt(const std::string& path, const OccupancyParams3D& params = {});

/// Imports beyond this many voxels are refused rather than attempted. A pruned leaf of a few
/// bytes can stand for 2^45 voxels, each of which the import sets one by one: 2^25 voxels take
/// ~150 MB and ~10 s (geb079.bt, the shipped sample, expands to 1.1 million in 0.3 s).
constexpr std::size_t kMaxBtImportVoxels = std::size_t{1} << 25;

}  // namespace probslam
