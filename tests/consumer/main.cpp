// Built against the installed package: maps one scan and optimises a small pose graph (which
// needs CHOLMOD through the package's dependencies), and checks both results.
#include <cmath>
#include <iostream>
#include <probslam/graph/graph_optimizer.hpp>
#include <probslam/grid/occupancy_grid_2d.hpp>

int main() {
  probslam::OccupancyGrid2D grid(0.1, 40, 40, {-2.0, -2.0});
  Eigen::VectorXd ranges = Eigen::VectorXd::Constant(91, 1.0);
  Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(91, -1.5, 1.5);
  const std::size_t updated = grid.insert_rays({0.0, 0.0, 0.0}, ranges, angles, 5.0);
  const Eigen::Vector2i wall = grid.cell_of(1.0, 0.0);
  const double p = grid.probability()(wall[0], wall[1]);
  std::cout << "consumer: " << updated << " cells updated, p(wall) = " << p << "\n";

  // Two poses, one edge: the optimum satisfies the edge exactly.
  probslam::PoseGraph2D graph;
  graph.add_pose(0, Eigen::Vector3d::Zero());
  graph.add_pose(1, {0.5, 0.5, 0.0});
  graph.add_pose_edge(0, 1, {1.0, 0.0, 0.5}, Eigen::Matrix3d::Identity());
  const probslam::OptimizationReport report = probslam::optimize(graph);
  std::cout << "consumer: chi2 " << report.initial_chi2 << " -> " << report.chi2 << "\n";
  return (updated > 0 && std::abs(p - 0.7) < 1e-12 && report.chi2 < 1e-20) ? 0 : 1;
}
