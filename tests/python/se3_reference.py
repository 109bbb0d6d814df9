"""SE(3) written independently of probslam (scipy's Rotation), for the 3-D pose-graph tests'
dense references: a pose is a pair (Rotation, translation (3,)), a row [x, y, z, qx, qy, qz, qw]
as PoseGraph3D holds it; the objective of a graph of poses and points and a dense Gauss-Newton of
it with finite-difference Jacobians."""

import numpy as np
from scipy.spatial.transform import Rotation

#: The reference's central differences: truncation O(h^2) ~ 1e-12 and rounding ~ 1e-16 / h ~ 1e-10
#: in its Jacobians shift neither its fixed point nor its marginals beyond ~1e-9 relative.
FD_STEP = 1e-6


def to_row(rotation, t):
    return np.concatenate([t, rotation.as_quat()])  # scipy's quaternion order is (x, y, z, w) too


def from_row(row):
    return Rotation.from_quat(row[3:]), np.asarray(row[:3], dtype=float)


def compose(a, b):
    (ra, ta), (rb, tb) = a, b
    return ra * rb, ta + ra.apply(tb)


def between(a, b):
    """a^-1 b."""
    (ra, ta), (rb, tb) = a, b
    return ra.inv() * rb, ra.inv().apply(tb - ta)


def pose_error(xi, xj, z):
    """[t_e, Log(R_e)] of z^-1 xi^-1 xj: PoseGraph3D's edge error."""
    (ri, ti), (rj, tj), (rz, tz) = xi, xj, z
    return np.concatenate([rz.inv().apply(ri.inv().apply(tj - ti) - tz), (rz.inv() * ri.inv() * rj).as_rotvec()])


def retract(x, d):
    """x (+) [v, w] = (R Exp(w), t + R v): the right perturbation."""
    r, t = x
    return r * Rotation.from_rotvec(d[3:]), t + r.apply(d[:3])


def observe(x, offset, p):
    """The point p in the frame of the sensor at `offset` on pose x: (x * offset)^-1 p."""
    rs, ts = compose(x, offset)
    return rs.inv().apply(p - ts)


def residuals(poses, points, pose_edges, point_edges):
    """(error, information) of each pose edge (i, j, z, info), then of each point edge
    (i, k, z, info, offset): PoseGraph3D's edge errors."""
    out = [(pose_error(poses[i], poses[j], z), info) for i, j, z, info in pose_edges]
    out += [(observe(poses[i], off, points[k]) - z, info) for i, k, z, info, off in point_edges]
    return out


def chi2(*problem):
    return sum(float(e @ info @ e) for e, info in residuals(*problem))


def dense_gauss_newton(poses, points, pose_edges, point_edges, iterations=60):
    """Gauss-Newton on the dense normal equations over [poses 1.. (6 each), points (3 each)], the
    first pose held, each edge's Jacobian by central differences in its own two vertices; returns
    the poses, the points and the dense information matrix at the end."""
    poses, points = list(poses), [np.array(p, dtype=float) for p in points]
    n, m = len(poses), len(points)
    size = 6 * (n - 1) + 3 * m

    def linearised(error, vertices):
        """error(poses, points) and its Jacobian in the free vertices ("pose", i) / ("point", k)."""
        e = error(poses, points)
        jac = np.zeros((e.size, size))
        for kind, v in vertices:
            if kind == "pose" and v == 0:
                continue  # the held first pose
            width, column = (6, 6 * (v - 1)) if kind == "pose" else (3, 6 * (n - 1) + 3 * v)
            for k in range(width):
                d = np.zeros(width)
                d[k] = FD_STEP
                ends = []
                for step in (d, -d):
                    ps, ls = list(poses), list(points)
                    if kind == "pose":
                        ps[v] = retract(poses[v], step)
                    else:
                        ls[v] = points[v] + step
                    ends.append(error(ps, ls))
                jac[:, column + k] = (ends[0] - ends[1]) / (2 * FD_STEP)
        return e, jac

    for _ in range(iterations):
        h, b = np.zeros((size, size)), np.zeros(size)
        edges = [(lambda ps, ls, i=i, j=j, z=z: pose_error(ps[i], ps[j], z), [("pose", i), ("pose", j)], info)
                 for i, j, z, info in pose_edges]
        edges += [(lambda ps, ls, i=i, k=k, z=z, off=off: observe(ps[i], off, ls[k]) - z, [("pose", i), ("point", k)],
                   info) for i, k, z, info, off in point_edges]
        for error, vertices, info in edges:
            e, jac = linearised(error, vertices)
            h += jac.T @ info @ jac
            b -= jac.T @ info @ e
        dx = np.linalg.solve(h, b)
        poses = [poses[0]] + [retract(poses[v], dx[6 * (v - 1):6 * v]) for v in range(1, n)]
        points = [points[k] + dx[6 * (n - 1) + 3 * k:6 * (n - 1) + 3 * k + 3] for k in range(m)]
        if np.abs(dx).max() < 1e-13:
            break
    return poses, points, h
