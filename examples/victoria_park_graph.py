# Victoria Park as a pose/landmark graph: EKF SLAM as the starting point, then Gauss-Newton.
import probslam
from probslam import graph as pg

path = probslam.data.path("victoria_park_1000.txt")   # or the whole victoriaPark.txt (iSAM)
g = pg.read_pose_graph(path)                 # vertices by dead reckoning
pg.initialize(g, "ekf")                      # or "incremental" (optimises as it goes), "odometry"
report = pg.optimize(g)                      # whole file: chi2 6184.12 in 5 iterations
print(f"{len(g.pose_ids)} poses, {len(g.point_ids)} landmarks: chi2 {report.chi2:.2f} "
      f"after {report.iterations} iterations")
