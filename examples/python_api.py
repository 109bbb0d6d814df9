# A scan into a grid, a pose graph optimised, a laser log mapped: the Python API in a few lines.
import numpy as np
import probslam as ps

grid = ps.OccupancyGrid2D(resolution=0.05, width=400, height=400, origin=(-10, -10))
angles = np.linspace(-np.pi / 2, np.pi / 2, 181)          # radians, relative to the heading
grid.insert_rays(pose=(0.0, 0.0, 0.3), ranges=np.full(181, 4.0), angles=angles, max_range=30.0)
p = grid.probability()                                     # (height, width), eq. 9.6
grid.log_odds                                              # zero-copy (height, width) view

graph = ps.read_pose_graph(ps.data.path("intel_400.g2o"))  # g2o, TORO or iSAM text
report = ps.optimize(graph, algorithm="gauss-newton")      # report.chi2, .iterations
cov = ps.marginal_covariances(graph, [10, 20])             # 3x3 blocks, from the sparse factor
ps.write_g2o(graph, "intel_400_optimized.g2o")             # writers: the object first, then the path

log = ps.io.read_carmen_log(ps.data.path("intel_excerpt.log.gz"))   # or intel-corrected.log.gz
summary = ps.map_laser_log(log.scans, resolution=0.05, progress=False)
grid = summary.grid
ps.io.save_ros_map(grid, "intel.yaml"); ps.io.write_png(grid, "intel.png")
print(f"chi2 {report.chi2:.4f} after {report.iterations} iterations; {summary.scans} scans mapped")
