#pragma once
// Which cells a range measurement can return from, and at what range: the cells a laser ray
// crosses (the grid's exact ray walk) or the cells of a sonar cone, ordered by that range. The
// expected range on a binary map is the range of the first occupied one (ch. 6.3).
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "probslam/grid/binary_map_2d.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"

namespace probslam {

enum class BeamShape {
  kLaser,  // an infinitely thin ray; a cell returns where the ray enters it
  kSonar,  // a cone of opening angle beta; a cell returns at its centre's distance if the centre lies in the cone
};

/// The shape of a beam and its reach: max_range (m), and the cone's full opening angle beta
/// (rad, in (0, 2 pi]) for a sonar.
struct BeamGeometry {
  BeamShape shape = BeamShape::kLaser;
  double max_range = 5.0;
  double beta = 0.0;
  /// Throws std::invalid_argument naming the first bad parameter.
  void validate() const;
};

/// One cell of a footprint: its row-major index and the range at which it returns.
struct FootprintCell {
  std::int32_t cell;
  double range;
};

/// The cells of a width x height grid on `lattice` that the beam at world bearing
/// pose[2] + beam_angle can return from at a range < max_range, by increasing range (ties in
/// walk or row-major order). Laser: the cells the exact walk (ray_traversal.hpp) crosses, at
/// the distance where the ray enters each (0 for the sensor's own cell). Sonar: the cells whose
/// centre lies within beta/2 of the bearing and closer than max_range, at that distance.
/// `out` is replaced. Arguments must be finite and geometry valid.
void beam_footprint(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose,
                    double beam_angle, const BeamGeometry& geometry, std::vector<FootprintCell>& out);

/// Footprint cells one call may test at most, summed over its beams: a sonar cone of 2 pi tests
/// its whole disc, so 1000 such beams over a 4000 x 4000 grid would test 1.6e10 cells (minutes,
/// and for Table 9.3's index hundreds of GB). 2^28 tests take seconds and index in about 5 GiB.
inline constexpr double kMaxFootprintVisits = 268435456.0;

/// An upper bound of the cells beam_footprint (or expected_range) tests for one beam: a laser's
/// cells crossed within max_range, a sonar cone's bounding box, both clipped to the grid.
double beam_footprint_visits(const GridLattice2D& lattice, int width, int height, const Eigen::Vector3d& pose,
                             double beam_angle, const BeamGeometry& geometry);

/// std::invalid_argument naming `name` when `visits` (a sum of beam_footprint_visits) exceeds
/// kMaxFootprintVisits; called before the work starts.
void require_footprint_budget(double visits, const char* name);

/// The range of the first occupied cell of the beam's footprint on `map`, max_range if none:
/// the z* of eq. 6.4. Computed directly (the laser walk stops at the first occupied cell).
double expected_range(const BinaryMap2D& map, const Eigen::Vector3d& pose, double beam_angle,
                      const BeamGeometry& geometry);

}  // namespace probslam
