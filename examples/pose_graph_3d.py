# A 3-D pose graph: a square loop of climbing quarter turns whose last edge closes the loop (and
# disagrees with the climb), initialised by the chordal relaxation and optimised; poses are
# [x, y, z, qx, qy, qz, qw].
import numpy as np
import probslam as ps

quarter_turn = [1.0, 0.0, 0.1, 0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)]  # 1 m ahead, 90 deg left, 0.1 m up
g = ps.PoseGraph3D()
for i in range(4):
    g.add_pose(i, [0, 0, 0, 0, 0, 0, 1])                # values to be replaced by the initialisation
for i in range(4):
    g.add_pose_edge(i, (i + 1) % 4, quarter_turn, np.diag([100, 100, 100, 400, 400, 400]))
ps.initialize_chordal(g)                                # or ps.initialize_odometry(g)
report = ps.optimize(g, algorithm="levenberg-marquardt")
cov = ps.marginal_covariances(g, [2])                   # (6, 6) in the pose's tangent
print(f"chi2 {report.chi2:.4f} after {report.iterations} iterations; z of pose 2: {g.poses[2, 2]:.3f} m")
