"""Trajectories against a ground-truth trajectory: the absolute and relative trajectory errors
(ATE, RPE) as evo computes them, after an association of the poses by time."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple

import numpy as np

from .._args import positive_real, real_array
from ._checks import _require_finite, _wrap
from .alignment import _se2_alignment
from .poses import _between, _path_times
from .statistics import STATISTICS, error_statistics, statistics_table


#: ``ate`` / ``rpe``'s default ``max_time_difference`` (s): evo's (``evo_ape --t_max_diff``).
MAX_TIME_DIFFERENCE = 0.01

#: The alignments of ``ate`` and ``rpe``: "se2", the rotation and translation that minimise the
#: squared position errors (Umeyama without scale, as evo's ``--align``), or "none".
ALIGNMENTS = ("se2", "none")

#: The units of ``rpe``'s ``delta``: poses, metres travelled, seconds.
DELTA_UNITS = ("frames", "m", "s")


@dataclass(frozen=True)
class TrajectoryError:
    """Translational errors of a trajectory against a reference, with evo's statistics.

    metric: "ATE" (absolute: the distance between each estimated position, after the
    alignment, and the reference's at the same time) or "RPE" (relative: the translation of
    ``(ref_i^-1 ref_j)^-1 (est_i^-1 est_j)`` for each pair ``(i, j)`` of associated poses);
    errors (K,) metres; count K; rmse, mean, median, std (population, ddof=0), min, max (m) and
    sse (m^2, the sum of squares) as ``evo_ape`` / ``evo_rpe`` print them; matched: how many
    poses were associated by time (K for ATE); est_indices, ref_indices (matched,): the
    associated rows of each trajectory; pairs (K, 2): RPE's pairs of indices into the
    associated poses (empty for ATE); rotation (2, 2), translation (2,): the alignment applied
    to the estimate (identity and zero with ``align="none"``); align, delta, delta_unit: the
    options (delta None for ATE).
    """

    metric: str
    errors: np.ndarray
    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    sse: float
    count: int
    matched: int
    est_indices: np.ndarray
    ref_indices: np.ndarray
    pairs: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    align: str
    delta: Optional[float] = None
    delta_unit: Optional[str] = None

    @property
    def statistics(self) -> Dict[str, float]:
        """{name: value} of the statistics evo prints (max, mean, median, min, rmse, sse, std)."""
        return {name: getattr(self, name) for name in STATISTICS}

    def title(self) -> str:
        """evo's title of the result: what was measured and how."""
        if self.metric == "ATE":
            head = "APE w.r.t. translation part (m)"
        else:
            head = f"RPE w.r.t. translation part (m)\nfor delta = {self.delta:g} ({self.delta_unit}) using consecutive pairs"
        return head + ("\n(with SE(2) Umeyama alignment)" if self.align == "se2" else "\n(not aligned)")

    def __str__(self) -> str:
        return statistics_table(self.title(), self.statistics)



def _trajectory_error(metric: str, errors: np.ndarray, **fields: Any) -> TrajectoryError:
    with np.errstate(over="ignore", invalid="ignore"):
        statistics = error_statistics(errors)
    # Errors near 1e154 m are finite but their squares are not (sse, rmse, std).
    _require_finite(np.array(list(statistics.values()), float), "poses_est and poses_ref: the error statistics")
    return TrajectoryError(metric, errors, count=int(errors.size), **statistics, **fields)


def _nearest_unsorted(long: np.ndarray, short: np.ndarray) -> np.ndarray:
    """For each time of ``short``, the index into unsorted ``long`` of its nearest time, as
    ``argmin(abs(long - t))`` picks it (of equally near times, the lowest index), in
    O((N + M) log N): a stable sort of ``long``; the nearest time is the first at or above t or
    the last below it, and of equal times the stable order's first has the lowest index."""
    order = np.argsort(long, kind="stable")
    ordered = long[order]
    above = np.searchsorted(ordered, short, side="left")  # the first of its equal times
    below = np.searchsorted(ordered, ordered[np.maximum(above - 1, 0)], side="left")
    has_above, has_below = above < len(long), above > 0
    i_above, i_below = order[np.minimum(above, len(long) - 1)], order[below]
    d_above = np.where(has_above, np.abs(long[i_above] - short), np.inf)
    d_below = np.where(has_below, np.abs(long[i_below] - short), np.inf)
    tie = d_above == d_below
    return np.where(d_below < d_above, i_below, np.where(tie, np.minimum(i_above, i_below), i_above)).astype(np.int64)


def associate(times_a: object, times_b: object, max_time_difference: float = MAX_TIME_DIFFERENCE):
    """Pairs of poses at the same time, as evo's ``sync.associate_trajectories`` makes them:
    each time of the trajectory with fewer poses (``times_b`` when both have as many) is paired
    with the nearest time of the other, if that is at most ``max_time_difference`` (s) away (a
    tie goes to the earlier). times_a (N,), times_b (M,): seconds, in any order (a log's clock
    may jump back; unsorted times are searched as evo does, the nearest of all of them, in O(n log n)).

    Returns (ia, ib): int64 index arrays of equal length into times_a and times_b, in the
    order of the shorter trajectory's times (an index of the longer one may repeat when it is
    the nearest to two times)."""
    ta = real_array(times_a, "times_a", (None,))
    tb = real_array(times_b, "times_b", (None,))
    limit = positive_real(max_time_difference, "max_time_difference")
    b_longer = len(tb) > len(ta)
    short, long = (ta, tb) if b_longer else (tb, ta)
    if len(short) == 0 or len(long) == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    if np.all(np.diff(long) >= 0):
        above = np.minimum(np.searchsorted(long, short, side="right"), len(long) - 1)
        after = long[above] - short
        before = np.where(above > 0, short - long[np.maximum(above - 1, 0)], np.inf)
        take_after = (after <= limit) & (after < before)
        take_before = ~take_after & (before <= limit) & (before <= after)
        inside = (short >= long[0] - limit) & (short <= long[-1] + limit)
        keep = inside & (take_after | take_before)
        nearest = np.where(take_after, above, above - 1)
    else:
        nearest = _nearest_unsorted(long, short)
        keep = np.abs(long[nearest] - short) <= limit
    i_short = np.flatnonzero(keep)
    i_long = nearest[keep].astype(np.int64)
    return (i_short, i_long) if b_longer else (i_long, i_short)


def _poses_at_times(times: object, poses: object, which: str) -> Tuple[np.ndarray, np.ndarray]:
    """Checked (N,) times in any order and (N, 3) poses, N >= 1 (``which``: "est" or "ref")."""
    ts = _path_times(times, f"times_{which}", ordered=False)  # a log's clock may jump back
    return ts, real_array(poses, f"poses_{which}", (len(ts), 3))


def _associated(times_est, poses_est, times_ref, poses_ref, max_time_difference, align):
    """The estimate's and reference's poses at the associated times, the estimate aligned."""
    te, pe = _poses_at_times(times_est, poses_est, "est")
    tr, pr = _poses_at_times(times_ref, poses_ref, "ref")
    if align not in ALIGNMENTS:
        raise ValueError(f"align must be one of {', '.join(map(repr, ALIGNMENTS))}, got {align!r}")
    ie, ir = associate(te, tr, max_time_difference)
    if ie.size == 0:
        raise ValueError(f"times_est: no pose within max_time_difference {max_time_difference:g} s of a reference "
                         f"pose (estimate [{te.min():.9g}, {te.max():.9g}] s, reference [{tr.min():.9g}, "
                         f"{tr.max():.9g}] s)")
    est, ref = pe[ie], pr[ir]
    rotation, translation = np.eye(2), np.zeros(2)
    if align == "se2":
        rotation, translation = _se2_alignment(est[:, :2], ref[:, :2], "poses_est and poses_ref: the alignment")
        turn = math.atan2(rotation[1, 0], rotation[0, 0])
        est = np.column_stack([est[:, :2] @ rotation.T + translation, _wrap(est[:, 2] + turn, "poses_est")])
    return est, ref, dict(matched=int(ie.size), est_indices=ie, ref_indices=ir, rotation=rotation,
                          translation=translation, align=align)


def ate(times_est: object, poses_est: object, times_ref: object, poses_ref: object, *, align: str = "se2",
        max_time_difference: float = MAX_TIME_DIFFERENCE) -> TrajectoryError:
    """Absolute trajectory error: evo's APE w.r.t. the translation part.

    times_est (N,), poses_est (N, 3); times_ref (M,), poses_ref (M, 3): seconds (in any order, as
    a log with a clock jump has them), ``(x m, y m, theta rad)``. Poses are associated by time
    (``associate``, nearest within ``max_time_difference`` s); with ``align="se2"`` (default) the estimate is moved by the
    rotation and translation that minimise the squared position errors (``align_rigid``:
    Umeyama without scale, evo's ``--align``), with "none" it is compared as it is. The error of
    a pose is the distance between its position and the reference's.

    Returns a ``TrajectoryError`` (metric "ATE"). Errors: ``TypeError`` / ``ValueError`` naming
    the argument for arrays of the wrong type or shape, empty, NaN or inf, an unknown
    ``align``, a ``max_time_difference`` that is not finite and > 0, or no pose associated."""
    est, ref, fields = _associated(times_est, poses_est, times_ref, poses_ref, max_time_difference, align)
    errors = np.hypot(est[:, 0] - ref[:, 0], est[:, 1] - ref[:, 1])
    _require_finite(errors, "poses_est and poses_ref: the errors")
    return _trajectory_error("ATE", errors, pairs=np.empty((0, 2), np.int64), **fields)


def _pairs(poses: np.ndarray, times: np.ndarray, delta: float, delta_unit: str) -> np.ndarray:
    """(K, 2) consecutive pairs of indices ``delta`` apart, as evo's ``id_pairs_from_delta``
    (all_pairs off): every ``delta``-th pose, or the next pose once the path travelled
    (metres) or the time passed (seconds) since the last one reaches ``delta``."""
    if delta_unit == "frames":
        ids = np.arange(0, len(poses), int(delta))
    else:
        steps = np.hypot(*np.diff(poses[:, :2], axis=0).T) if delta_unit == "m" else np.diff(times)
        ids, since = [0], 0.0
        for i, step in enumerate(steps, 1):
            since += float(step)
            if since >= delta:
                ids.append(i)
                since = 0.0
        ids = np.array(ids)
    return np.column_stack([ids[:-1], ids[1:]]).astype(np.int64)


def rpe(times_est: object, poses_est: object, times_ref: object, poses_ref: object, *, delta: float = 1,
        delta_unit: str = "frames", align: str = "none",
        max_time_difference: float = MAX_TIME_DIFFERENCE) -> TrajectoryError:
    """Relative pose error: evo's RPE w.r.t. the translation part, over consecutive pairs.

    Arguments as ``ate``'s. After the association by time, pairs ``(i, j)`` of associated poses
    are taken on the estimate as evo takes them: ``delta_unit="frames"``, every ``delta``-th pose
    (``delta`` an integer >= 1); "m", the next pose once the estimate has travelled ``delta``
    metres since the last; "s" (not in evo), the next pose once ``delta`` seconds have passed.
    The error of a pair is the length of the translation of ``(ref_i^-1 ref_j)^-1 (est_i^-1
    est_j)``. An alignment (default none, as ``evo_rpe``'s) moves both poses of a pair alike and
    so changes no error beyond rounding.

    Returns a ``TrajectoryError`` (metric "RPE"). Errors: those of ``ate``, a ``delta`` that is not
    finite and > 0 (an integer for frames), an unknown ``delta_unit``, or no pair."""
    if delta_unit not in DELTA_UNITS:
        raise ValueError(f"delta_unit must be one of {', '.join(map(repr, DELTA_UNITS))}, got {delta_unit!r}")
    step = positive_real(delta, "delta")
    if delta_unit == "frames" and step != int(step):
        raise ValueError(f"delta must be an integer number of frames, got {delta!r}")
    est, ref, fields = _associated(times_est, poses_est, times_ref, poses_ref, max_time_difference, align)
    matched_times = real_array(times_est, "times_est", (None,))[fields["est_indices"]]
    pairs = _pairs(est, matched_times, step, delta_unit)
    if len(pairs) == 0:
        raise ValueError(f"delta: {delta:g} {delta_unit} gives no pair among the {len(est)} associated poses")
    what = "poses_est and poses_ref: the relative errors"
    moved_ref = _between(ref[pairs[:, 0]], ref[pairs[:, 1]], what)
    moved_est = _between(est[pairs[:, 0]], est[pairs[:, 1]], what)
    e = _between(moved_ref, moved_est, what)
    errors = np.hypot(e[:, 0], e[:, 1])
    _require_finite(errors, what)
    return _trajectory_error("RPE", errors, pairs=pairs, delta=step, delta_unit=delta_unit, **fields)
