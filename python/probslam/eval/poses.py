"""Poses along a trajectory, checked: interpolation at given times and relative poses, on the
vectorised SE(2) algebra of ``probslam.geometry``, with arguments checked and overflow near the
largest double named (the metrics build on these)."""

from __future__ import annotations

from typing import Tuple

import numpy as np

from .._args import distinct_numbers, real_array
from .. import geometry
from ._checks import _require_finite


def _path_times(times: object, name: str, ordered: bool = True, why: str = "") -> np.ndarray:
    """Checked (N,) times of a path, N >= 1, non-decreasing when ``ordered`` (``why``: the reason
    told after a decrease). One check for every metric, so their messages agree."""
    ts = real_array(times, name, (None,))
    if ts.shape[0] == 0:
        raise ValueError(f"{name}: empty trajectory")
    decreasing = np.flatnonzero(np.diff(ts) < 0) if ordered else ()
    if len(decreasing):
        i = int(decreasing[0])
        # distinct_numbers: two Unix times a fraction of a second apart must not print alike.
        before, after = distinct_numbers(ts[i], ts[i + 1])
        raise ValueError(f"{name}: decrease at index {i + 1} ({before} then {after}){why}")
    return ts


def _trajectory(timestamps: object, poses: object) -> Tuple[np.ndarray, np.ndarray]:
    """Checked (N,) timestamps and (N, 3) poses: non-empty, same length, non-decreasing."""
    ts = _path_times(timestamps, "timestamps")
    ps = real_array(poses, "poses", (None, 3))
    if ps.shape[0] != ts.shape[0]:
        raise ValueError(f"poses: {ps.shape[0]} poses for {ts.shape[0]} timestamps")
    return ts, ps


def _interpolate(ts: np.ndarray, ps: np.ndarray, q: np.ndarray, what: str) -> np.ndarray:
    """Interpolation on a checked trajectory, queries known to lie within its span (inputs near
    the largest double can overflow: an overflowing heading raises naming ``what``, the callers
    check the positions)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return _interpolate_unchecked(ts, ps, q, what)


def _interpolate_unchecked(ts: np.ndarray, ps: np.ndarray, q: np.ndarray, what: str) -> np.ndarray:
    _require_finite(np.diff(ps[:, 2]), what)  # headings near the largest double: their difference overflows
    return geometry.interpolate(ts, ps, q)


def interpolate_poses(timestamps: object, poses: object, query_times: object) -> np.ndarray:
    """Poses at ``query_times``, interpolated linearly along a trajectory.

    timestamps: (N,) seconds, non-decreasing; poses: (N, 3) ``(x m, y m, theta rad)``;
    query_times: (Q,) seconds within ``[timestamps[0], timestamps[-1]]`` (callers filter first).
    Returns (Q, 3): x and y linear in time, theta along the shorter way round between the two
    neighbouring poses, wrapped to (-pi, pi]. At a timestamp shared by several poses, the last of
    them is used. An empty query gives an empty (0, 3) result.

    Errors: non-numeric arrays raise ``TypeError``; wrong shapes, NaN / inf, an empty
    trajectory, decreasing timestamps, a query outside the span or coordinates so large that the
    interpolation overflows raise ``ValueError`` naming the argument.
    """
    ts, ps = _trajectory(timestamps, poses)
    q = real_array(query_times, "query_times", (None,))
    outside = np.flatnonzero((q < ts[0]) | (q > ts[-1]))
    if outside.size:
        k = int(outside[0])
        raise ValueError(f"query_times: {outside.size} outside the trajectory span "
                         f"[{ts[0]:g}, {ts[-1]:g}], first at index {k} ({q[k]:g})")
    what = "timestamps and poses: the interpolation"
    out = _interpolate(ts, ps, q, what)
    _require_finite(out, what)
    return out


def _between(a: np.ndarray, b: np.ndarray, what: str) -> np.ndarray:
    """``geometry.between`` of (K, 3) poses that may overflow near the largest double: a heading
    that did raises naming ``what`` (the callers check the positions)."""
    with np.errstate(over="ignore", invalid="ignore"):
        _require_finite(b[:, 2] - a[:, 2], what)
        return geometry.between(a, b)


def relative_poses(a: object, b: object) -> np.ndarray:
    """Poses ``b`` expressed in the frames of poses ``a``: ``a^-1 (+) b``, row by row, as
    ``Pose2.between`` does for one pair (the odometry that takes a robot from a to b).

    a, b: (K, 3) ``(x m, y m, theta rad)``, or both (3,) for one pair (then (3,) is returned).
    Returns (K, 3): x, y in metres in a's frame and the heading change wrapped to (-pi, pi].

    Errors: non-numeric arrays raise ``TypeError``; shapes other than (K, 3) / (3,), differing
    K, NaN or inf, or coordinates so large that the difference overflows raise ``ValueError``
    naming the argument.
    """
    pa, one_a = _pose_rows(a, "a")
    pb, one_b = _pose_rows(b, "b")
    if pa.shape != pb.shape or one_a != one_b:
        raise ValueError(f"b: expected the shape of a, {np.shape(a)}, got {np.shape(b)}")
    what = "a and b: the relative poses"
    out = _between(pa, pb, what)
    _require_finite(out, what)
    return out[0] if one_a else out


def _pose_rows(value: object, name: str) -> Tuple[np.ndarray, bool]:
    """``value`` as checked (K, 3) pose rows, and whether it was a single (3,) pose."""
    try:
        ndim = np.ndim(value)
    except ValueError as exc:  # ragged nested lists
        raise ValueError(f"{name}: not an array of numbers: {exc}") from None
    if ndim == 1:
        return real_array(value, name, (3,))[None], True
    return real_array(value, name, (None, 3)), False
