// Built against the installed package: maps one scan and checks the result.
#include <cmath>
#include <iostream>
#include <probslam/grid/occupancy_grid_2d.hpp>

int main() {
  probslam::OccupancyGrid2D grid(0.1, 40, 40, {-2.0, -2.0});
  Eigen::VectorXd ranges = Eigen::VectorXd::Constant(91, 1.0);
  Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(91, -1.5, 1.5);
  const std::size_t updated = grid.insert_rays({0.0, 0.0, 0.0}, ranges, angles, 5.0);
  const Eigen::Vector2i wall = grid.cell_of(1.0, 0.0);
  const double p = grid.probability()(wall[0], wall[1]);
  std::cout << "consumer: " << updated << " cells updated, p(wall) = " << p << "\n";
  return (updated > 0 && std::abs(p - 0.7) < 1e-12) ? 0 : 1;
}
