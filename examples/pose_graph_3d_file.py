# A 3-D pose graph file straight to the optimiser and back: the bundled first 400 poses of the
# parking garage (g2o VERTEX_SE3:QUAT / EDGE_SE3:QUAT), read into a PoseGraph3D in C++,
# initialised by the chordal relaxation, optimised, written as g2o.
import probslam
from probslam import graph as pg

path = probslam.data.path("parking_garage_400.g2o")   # or any g2o SE3, iSAM EDGE3, TORO 3-D file
g = pg.read_pose_graph_3d(path)                       # C++ all the way: no per-record Python
pg.initialize_chordal(g)
report = pg.optimize(g)                               # Gauss-Newton; the 3-D solver defaults
pg.write_g2o_3d(g, "parking_garage_400_optimised.g2o")
print(f"{g.num_vertices} poses: chi2 {report.chi2:.6f} after {report.iterations} iterations")
