# 3-D occupancy (points are rounded to float32, as in OctoMap).
import numpy as np
import probslam as ps

# A synthetic point cloud: the walls of a 10 m x 6 m room, 3 m high, seen from its centre.
rng = np.random.default_rng(0)
u, z = rng.uniform(0, 1, 20000), rng.uniform(0, 3, 20000)
wall = rng.integers(0, 4, 20000)
x = np.where(wall < 2, -5 + 10 * u, np.where(wall == 2, -5.0, 5.0))
y = np.where(wall == 0, -3.0, np.where(wall == 1, 3.0, -3 + 6 * u))
points = np.column_stack([x, y, z])                          # (n, 3) metres

grid = ps.OccupancyGrid3D(0.1)                 # p_hit=0.7, p_miss=0.4, clamp 0.1192..0.971
stats = grid.insert_point_cloud(points, origin=(0, 0, 1.8), max_range=20.0, threads=2)
stats.skipped_nonfinite                        # NaN/inf points are skipped and counted
centres, log_odds = grid.occupied_voxels()     # (n, 3) m, (n,) float32
grid.write_bt("map.bt")                        # opens in octovis; OccupancyGrid3D.read_bt reads it
floor_plan = grid.project_2d(z_min=0.2, z_max=2.0)   # an OccupancyGrid2D
print(f"{len(centres)} occupied voxels; floor plan {floor_plan.width} x {floor_plan.height} cells")
