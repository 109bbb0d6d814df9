"""Rigid transforms of the plane, vectorised: poses as rows ``(x m, y m, theta rad)``, the SE(2)
algebra of ``Pose2`` (compose, between, inverse) on whole arrays at once. The one Python form of
it; io, eval, the simulators and the refinement use these rather than their own.

The functions broadcast (``(N, 3)`` with ``(3,)``, or two ``(N, 3)``), return headings wrapped to
(-pi, pi], and do not check their input: callers that take user data check it first (a NaN or an
infinite heading raises ValueError from the wrap, naming ``angle``).
"""

from __future__ import annotations

import numpy as np

from ._core import wrap_angle


def _rows(a) -> np.ndarray:
    return np.asarray(a, dtype=float)


def rotations(theta) -> np.ndarray:
    """(..., 2, 2) the rotation matrices R(theta) = [[cos, -sin], [sin, cos]] of angles (...,)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def transform_points(poses, points) -> np.ndarray:
    """(..., 2): points given in the frames of ``poses`` (..., 3), in their parent frame
    (``R(theta) p + t`` row by row; a sighting placed in the world)."""
    poses = _rows(poses)
    return poses[..., :2] + np.einsum("...ij,...j->...i", rotations(poses[..., 2]), _rows(points))


def compose(a, b) -> np.ndarray:
    """``a (+) b`` row by row: pose (or motion) ``b`` given in the frame of ``a``, in a's parent
    frame (``Pose2.compose``)."""
    a, b = np.broadcast_arrays(_rows(a), _rows(b))
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([a[..., 0] + c * b[..., 0] - s * b[..., 1], a[..., 1] + s * b[..., 0] + c * b[..., 1],
                     wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def between(a, b) -> np.ndarray:
    """``a^-1 (+) b`` row by row: pose ``b`` in the frame of pose ``a``, the motion from a to b
    (``Pose2.between``)."""
    a, b = np.broadcast_arrays(_rows(a), _rows(b))
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(b[..., 2] - a[..., 2])], axis=-1)


def inverse(a) -> np.ndarray:
    """``a^-1`` row by row (``Pose2.inverse``)."""
    a = _rows(a)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([-c * a[..., 0] - s * a[..., 1], s * a[..., 0] - c * a[..., 1], wrap_angle(-a[..., 2])], axis=-1)


def steps(poses) -> np.ndarray:
    """(T - 1, 3): the motion from each pose of a path to the next, in the frame of the first
    (``between(poses[:-1], poses[1:])``; odometry increments)."""
    poses = _rows(poses)
    return between(poses[:-1], poses[1:])


def accumulate(start, motions) -> np.ndarray:
    """(T + 1, 3): the path that starts at pose ``start`` and makes ``motions`` (T, 3) one after
    the other, each in the frame of the pose before it (``steps``' inverse: dead reckoning).
    Headings are summed before the positions are rotated, so no loop runs over the path."""
    start, motions = _rows(start), _rows(motions).reshape(-1, 3)
    heading = start[2] + np.concatenate([[0.0], np.cumsum(motions[:, 2])])
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])
    moves = np.column_stack([c * motions[:, 0] - s * motions[:, 1], s * motions[:, 0] + c * motions[:, 1]])
    xy = start[:2] + np.concatenate([np.zeros((1, 2)), np.cumsum(moves, axis=0)])
    return np.column_stack([xy, wrap_angle(heading)])


def interpolate(times, poses, query) -> np.ndarray:
    """(Q, 3) poses at ``query`` times along a path (``times`` (N,) non-decreasing, ``poses``
    (N, 3)): x and y linear in time, theta along the shorter way round between the two
    neighbouring poses. At a time shared by several poses the last of them is used; a query
    outside the span takes the nearest end's segment (callers keep queries inside)."""
    ts, ps, q = _rows(times), _rows(poses), _rows(query)
    n = ts.shape[0]
    # side="right": a query at a repeated timestamp starts from the last pose stamped with it.
    i = np.clip(np.searchsorted(ts, q, side="right") - 1, 0, max(n - 2, 0))
    j = np.minimum(i + 1, n - 1)
    dt = ts[j] - ts[i]
    # dt is 0 only at the end (repeated last timestamp, or one pose): take the later pose.
    frac = np.where(dt > 0, (q - ts[i]) / np.where(dt > 0, dt, 1.0), 1.0)
    xy = ps[i, :2] + frac[:, None] * (ps[j, :2] - ps[i, :2])
    theta = wrap_angle(ps[i, 2] + frac * wrap_angle(ps[j, 2] - ps[i, 2]))
    return np.column_stack([xy, theta])


__all__ = ["accumulate", "between", "compose", "interpolate", "inverse", "rotations", "steps", "transform_points"]
