# A 3-D pose graph with point landmarks: four poses on a square, each seeing three pillars through
# a sensor mounted 0.2 m ahead and 0.5 m up (g2o's EDGE_SE3_TRACKXYZ with a PARAMS_SE3OFFSET).
# The poses start from odometry that drifts, the points from their first sighting.
import numpy as np
import probslam as ps

pillars = np.array([[2.0, 2.0, 1.0], [-1.0, 2.5, 1.5], [0.5, -1.5, 0.8]])
yaw = [0.0, np.pi / 2, np.pi, -np.pi / 2]
truth = [(1.4 * np.array([np.cos(a - 3 * np.pi / 4), np.sin(a - 3 * np.pi / 4), 0.0]), a) for a in yaw]  # 1.98 m sides
sensor = [0.2, 0.0, 0.5, 0, 0, 0, 1]                     # [x, y, z, qx, qy, qz, qw] in the pose's frame


def seen(position, heading, point):                     # the point in the sensor's frame
    c, s = np.cos(heading), np.sin(heading)
    body = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) @ (point - position)
    return body - np.array(sensor[:3])


g = ps.PoseGraph3D()
g.add_pose(0, [*truth[0][0], 0, 0, 0, 1])                # the first pose holds the gauge where it truly is
for i in range(1, 4):
    g.add_pose(i, [0, 0, 0, 0, 0, 0, 1])
for i in range(4):                                      # odometry: 2.05 m and 88 deg a step
    g.add_pose_edge(i, (i + 1) % 4, [2.05, 0, 0, 0, 0, np.sin(np.radians(44)), np.cos(np.radians(44))],
                    np.diag([100, 100, 100, 400, 400, 400]))
for k, pillar in enumerate(pillars):
    g.add_point(10 + k, [0, 0, 0])
    for i, (position, heading) in enumerate(truth):
        g.add_point_edge(i, 10 + k, seen(position, heading, pillar), 400 * np.eye(3), offset=sensor)
ps.initialize_odometry(g)                               # poses by composing edges, points from a sighting
report = ps.optimize(g)
cov = ps.marginal_covariances(g, [10])[0]               # (3, 3) m^2, world frame
print(f"chi2 {report.chi2:.4f} after {report.iterations} iterations; pillar 10 at {np.round(g.points[0], 3)} "
      f"+- {np.sqrt(cov[0, 0]):.3f} m")
