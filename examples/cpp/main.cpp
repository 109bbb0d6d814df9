// The C++ example of docs/install.md, complete: one laser scan into a 2-D occupancy grid, a small point
// cloud into a 3-D grid written as an OctoMap .bt file, and a pose graph optimised. Exits 1 if a
// result is not what it must be.
#include <cmath>
#include <cstddef>
#include <iostream>
#include <vector>

#include <Eigen/Core>
#include <probslam/graph/graph_optimizer.hpp>
#include <probslam/grid/occupancy_grid_2d.hpp>
#include <probslam/grid/occupancy_grid_3d.hpp>
#include <probslam/io/octomap_bt.hpp>

int main() {
  const double pi = std::acos(-1.0);
  // 2-D: 0.05 m cells, 20 m x 20 m, origin (lower-left corner) at (-10, -10).
  probslam::OccupancyGrid2D grid(0.05, 400, 400, {-10.0, -10.0});
  const Eigen::Vector3d pose(0.0, 0.0, 0.3);  // x, y (m), heading (rad)
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(181, -pi / 2, pi / 2);  // rad
  const Eigen::VectorXd ranges = Eigen::VectorXd::Constant(181, 4.0);                      // m
  const std::size_t cells = grid.insert_rays(pose, ranges, angles, 30.0);
  const Eigen::Vector2i hit = grid.cell_of(4.0 * std::cos(0.3), 4.0 * std::sin(0.3));
  const double p_hit = grid.probability()(hit[0], hit[1]);

  // 3-D: 0.1 m voxels; a wall of points 5 m ahead of a sensor 1.8 m above the ground.
  probslam::OccupancyGrid3D voxels(0.1);
  std::vector<float> xyz;  // x, y, z of each point
  for (int i = 0; i < 50; ++i)
    for (int k = 0; k < 30; ++k) xyz.insert(xyz.end(), {5.0f, -2.5f + 0.1f * i, 0.1f * k});
  const float origin[3] = {0.0f, 0.0f, 1.8f};
  const probslam::InsertStats3D stats = voxels.insert_point_cloud(xyz.data(), xyz.size() / 3, origin, 20.0);
  const std::size_t nodes = probslam::write_octomap_bt(voxels, "map.bt");

  // A pose graph: three poses, two odometry edges; the optimum satisfies both.
  probslam::PoseGraph2D graph;
  graph.add_pose(0, Eigen::Vector3d::Zero());
  graph.add_pose(1, {0.5, 0.5, 0.0});
  graph.add_pose(2, {1.0, 1.0, 0.0});
  graph.add_pose_edge(0, 1, {1.0, 0.0, 0.5}, Eigen::Matrix3d::Identity());
  graph.add_pose_edge(1, 2, {1.0, 0.0, 0.5}, Eigen::Matrix3d::Identity());
  const probslam::OptimizationReport report = probslam::optimize(graph);

  std::cout << "2-D: " << cells << " cells updated, p(hit cell) = " << p_hit << "\n"
            << "3-D: " << stats.points << " points, " << stats.voxels_updated << " voxels updated, "
            << voxels.num_occupied_voxels() << " occupied; map.bt has " << nodes << " nodes\n"
            << "graph: chi2 " << report.initial_chi2 << " -> " << report.chi2 << " in " << report.iterations
            << " iterations\n";
  const bool ok = cells > 0 && p_hit > 0.5 && voxels.num_occupied_voxels() > 0 && nodes > 0 && report.chi2 < 1e-12;
  return ok ? 0 : 1;
}
