"""SE(3) written independently of probslam (scipy's Rotation), for the 3-D pose-graph tests'
dense references: a pose is a pair (Rotation, translation (3,)), a row [x, y, z, qx, qy, qz, qw]
as PoseGraph3D holds it."""

import numpy as np
from scipy.spatial.transform import Rotation


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
