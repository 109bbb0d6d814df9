"""How good is a SLAM result: the relations metric of Kümmerle et al. 2009, "On measuring the
accuracy of SLAM algorithms", the NEES, evo's ATE and RPE, a path against reference positions
such as a GPS track (``position_error``), and the scores of landmark SLAM runs (path and map
against ground truth or a survey, data association against a dataset's labels).

A laser SLAM result is scored by the relative poses it implies between pairs of timestamps, compared
with reference relations (the Freiburg SLAM benchmark's ``*.relations`` files, hand-checked scan
alignments). Relative poses do not depend on where the map is anchored, so no global alignment
is needed, and an error in one place is counted once rather than carried along the trajectory.

Units: metres, radians and seconds; poses are ``(x, y, theta)`` with theta in (-pi, pi].
"""

from __future__ import annotations

import collections
import math
import os
from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, List, Optional, Tuple, Union

import numpy as np

from ._args import distinct_numbers, positive_real, real_array, require_fields, require_instance
from . import geometry
from ._core import wrap_angle
from .io._files import MAX_REPORTED_LINES, file_path, numeric_rows, require_regular_file
from .io.carmen import LaserScans
from .io.landmark_datasets import Mrclam

PathLike = Union[str, "os.PathLike[str]"]

#: Fields of a relations row: ``t1 t2 x y z roll pitch yaw``.
_RELATION_FIELDS = 8


@dataclass
class Relations:
    """Reference relations, R of them.

    t1, t2: (R,) seconds; delta: (R, 3) the expected pose at t2 in the frame of the pose at t1,
    ``(x m, y m, theta rad)``; skipped_rows: unreadable rows the reader skipped; skipped_lines:
    the line numbers of the first ``MAX_REPORTED_LINES`` of them.
    """

    t1: np.ndarray
    t2: np.ndarray
    delta: np.ndarray
    skipped_rows: int = 0
    skipped_lines: List[int] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.t1.shape[0])


@dataclass
class RelationsError:
    """Per-relation errors of a trajectory against reference relations, K relations used.

    translational: (K,) metres; rotational: (K,) radians, absolute; used: (K,) indices into the
    relations; skipped: relations with t1 or t2 outside the trajectory's time span. Means and
    standard deviations (population, ddof=0) are over the used relations; Kümmerle et al. report
    both the absolute errors and the squared ones.
    """

    translational: np.ndarray
    rotational: np.ndarray
    used: np.ndarray
    skipped: int = 0

    @property
    def trans_mean(self) -> float:
        """Mean translational error, metres."""
        return float(np.mean(self.translational))

    @property
    def trans_std(self) -> float:
        """Standard deviation of the translational error, metres."""
        return float(np.std(self.translational))

    @property
    def trans_sq_mean(self) -> float:
        """Mean squared translational error, square metres."""
        return float(np.mean(self.translational ** 2))

    @property
    def rot_mean_deg(self) -> float:
        """Mean rotational error, degrees."""
        return float(np.degrees(np.mean(self.rotational)))

    @property
    def rot_std_deg(self) -> float:
        """Standard deviation of the rotational error, degrees."""
        return float(np.degrees(np.std(self.rotational)))

    @property
    def rot_sq_mean_deg2(self) -> float:
        """Mean squared rotational error, square degrees."""
        return float(np.mean(np.degrees(self.rotational) ** 2))

    def __str__(self) -> str:
        return (f"relations {len(self.used)} (skipped {self.skipped}): translational "
                f"{self.trans_mean:.3f} +- {self.trans_std:.3f} m, rotational "
                f"{self.rot_mean_deg:.2f} +- {self.rot_std_deg:.2f} deg")


def _wrap(angle: np.ndarray, what: str) -> np.ndarray:
    """``probslam.wrap_angle`` of angles the arithmetic here computed, which may have overflowed
    for inputs near the largest double: then a ValueError naming ``what`` (the bound function
    would name its own argument, ``angle``)."""
    _require_finite(angle, what)
    return wrap_angle(angle)


#: ``nees`` treats a covariance as singular when its smallest eigenvalue is at most this times its
#: largest. Rounding alone leaves the smallest eigenvalue of an exactly rank-deficient symmetric
#: matrix near 1e-16 times the largest; 1e-12 keeps a margin of 1e4 above that while a real pose
#: covariance (e.g. 1 m^2 in position, 1e-8 rad^2 in heading) stays far above it.
NEES_SINGULAR_RTOL = 1e-12

#: ``nees`` rejects a covariance whose transpose differs by more than this times its largest
#: entry: filters symmetrise their covariances, so anything larger is a wrong argument (e.g. a
#: square root factor or an information matrix in the wrong layout), not rounding.
_SYMMETRY_RTOL = 1e-9


class SingularCovarianceError(ValueError):
    """``nees`` was given a singular covariance: the filter claims certainty in some direction."""


def nees(error: object, covariance: object) -> np.ndarray:
    """Normalised estimation error squared, e^T P^-1 e, for one or many estimates.

    Args:
        error: (..., n) estimate minus truth, in the state's units (metres, radians; wrap angle
            differences first, e.g. with ``probslam.sim.pose_error``).
        covariance: (..., n, n) the covariance the filter claims for that estimate, symmetric
            positive semi-definite, in the squared units of ``error``.

    Returns:
        (...) dimensionless NEES, finite; chi2(n)-distributed when the filter is consistent (mean n).

    Raises:
        SingularCovarianceError (a ValueError) when a covariance is singular: its smallest
        eigenvalue is at most ``NEES_SINGULAR_RTOL`` times its largest, or it is zero. The NEES is
        then unbounded; no pseudo-inverse is taken, as it would drop exactly the error the filter
        says is impossible and make an overconfident filter look consistent. A caller studying
        consistency counts these cases itself (e.g. as infinite NEES).
        ValueError naming the argument for non-finite input, an empty state (n = 0),
        mismatched shapes, an asymmetric covariance, or a NEES too large for a double;
        TypeError for anything but real numbers.
    """
    e = real_array(error, "error", None)
    p = real_array(covariance, "covariance", None)
    if e.ndim < 1 or e.shape[-1] == 0:
        raise ValueError(f"error: expected shape (..., n) with n >= 1, got {e.shape}")
    if p.shape != e.shape + e.shape[-1:]:
        raise ValueError(f"covariance must have shape error.shape + (n,) = {e.shape + e.shape[-1:]}, "
                         f"got error {e.shape} and covariance {p.shape}")
    scale = np.max(np.abs(p), axis=(-2, -1), keepdims=True)
    if np.any(np.abs(p - np.swapaxes(p, -1, -2)) > _SYMMETRY_RTOL * scale):
        raise ValueError("covariance must be symmetric")
    values, vectors = np.linalg.eigh(p)
    largest = values[..., -1:]
    singular = np.any(values <= NEES_SINGULAR_RTOL * largest, axis=-1) | (largest[..., 0] <= 0.0)
    if np.any(singular):
        where = tuple(int(i) for i in np.argwhere(singular)[0])
        raise SingularCovarianceError(f"covariance{list(where) if where else ''} is singular (eigenvalues "
                                      f"{values[where].tolist()}): the NEES is unbounded")
    projected = np.einsum("...ji,...j->...i", vectors, e)  # V^T e
    with np.errstate(over="ignore", invalid="ignore"):
        result = np.sum(projected ** 2 / values, axis=-1)
    _require_finite(result, "error and covariance: the NEES")
    return result


def _require_finite(result: np.ndarray, what: str) -> None:
    """ValueError unless every number of a result is finite (inputs near the largest double
    can overflow in the arithmetic; the policy is finite or raise)."""
    if not np.all(np.isfinite(result)):
        raise ValueError(f"{what} overflows a double (inputs too large)")

# --------------------------------------------------------------------------------------------
# Reading relations files


def _relation_check(values: List[float]) -> str:
    """Why a relations row of numbers cannot be used ("" if it can)."""
    return "t2 < t1" if values[1] < values[0] else ""


def read_relations(path: PathLike) -> Relations:
    """Read a Freiburg SLAM-benchmark relations file (plain, ``.gz`` or ``.bz2``).

    Each row is ``t1 t2 x y z roll pitch yaw`` (whitespace separated; ``#`` starts a comment,
    blank lines are ignored); for 2-D only x, y and yaw are kept, as ``delta``.

    Errors: a missing file raises ``FileNotFoundError``; a path that is not a regular file, a
    corrupt compressed stream, or a file with no valid row raises ``ValueError`` naming the file.
    Row-level: rows of the wrong field count, with non-numeric or non-finite values, or with
    t2 < t1 are skipped, counted in ``skipped_rows`` and announced by a warning naming the first
    line numbers (a real file is read even with a few bad rows).
    """
    path = file_path(path)
    require_regular_file(path)
    read = numeric_rows(path, (_RELATION_FIELDS,), "relation", _relation_check)
    read.warn(path, "relation")
    table = read.table
    return Relations(table[:, 0].copy(), table[:, 1].copy(), table[:, [2, 3, 7]].copy(), read.skipped,
                     read.skipped_lines)


def relations_on_logger_time(relations: Union[Relations, PathLike], scans: LaserScans) -> Relations:
    """The relations with t1, t2 moved from the raw log's ipc time onto its logger time.

    The Freiburg relations files are stamped with the ipc time of the raw log's scans (every
    ``aces.relations`` time is a FLASER ipc stamp of ``aces.clf``), while ``read_carmen_log``,
    ``run_slam`` and ``probslam slam`` give the logger time (the clock the corrected Radish logs
    carry). scans: the raw log's ``LaserScans`` (``read_carmen_log(...).scans``); each relation
    time t becomes t - (ipc - logger) of the scan whose ipc stamp is nearest to t (the two clocks
    differ by a constant in the benchmark logs: ACES 70.1797 s, Intel 976052857.337284 s).
    ValueError naming ``scans`` when they have no ipc time (a ROS bag, a simulation).
    """
    if not isinstance(relations, Relations):
        relations = read_relations(file_path(relations, "relations", "a Relations or the path of a relations file"))
    require_instance(scans, LaserScans, "scans")
    ipc = real_array(scans.ipc_timestamps, "scans.ipc_timestamps", (None,), finite=False)
    logger = real_array(scans.timestamps, "scans.timestamps", (ipc.shape[0],), finite=False)
    known = np.isfinite(ipc) & np.isfinite(logger)
    if not np.any(known):
        raise ValueError("scans: no scan has both an ipc and a logger time (relations are stamped with a raw "
                         "CARMEN log's ipc time; read that log with read_carmen_log)")
    order = np.argsort(ipc[known], kind="stable")
    ipc_sorted, offset = ipc[known][order], (ipc - logger)[known][order]

    def moved(t: np.ndarray) -> np.ndarray:
        at = np.searchsorted(ipc_sorted, t)
        below, above = np.clip(at - 1, 0, len(ipc_sorted) - 1), np.clip(at, 0, len(ipc_sorted) - 1)
        nearest = np.where(np.abs(t - ipc_sorted[below]) <= np.abs(ipc_sorted[above] - t), below, above)
        return t - offset[nearest]

    t1, t2, delta = _checked_relations(relations)
    return Relations(moved(t1), moved(t2), delta.copy(), relations.skipped_rows, list(relations.skipped_lines))


#: How far apart (s) a relation's time and an estimate's may be and still be the same scan's: the
#: logs and relations files write times to the microsecond.
SAME_SCAN_TIME = 1e-6
#: Relation times every candidate clock offset is tried on before all of them are checked, and
#: candidates tried at once (bounds the work and memory of ``clock_offset``'s search to ~8 MB).
OFFSET_PROBES = 20
OFFSET_CHUNK = 50_000


def on_times(times: np.ndarray, stamps: np.ndarray) -> np.ndarray:
    """(K,) bool: which ``stamps`` are one of the sorted ``times`` (within SAME_SCAN_TIME)."""
    at = np.searchsorted(times, stamps)
    gap = np.minimum(np.abs(times[np.minimum(at, len(times) - 1)] - stamps),
                     np.abs(times[np.maximum(at - 1, 0)] - stamps))
    return gap <= SAME_SCAN_TIME


def clock_offset(times: np.ndarray, stamps: np.ndarray) -> Optional[float]:
    """The one constant c for which every stamp - c is one of the sorted ``times`` (0 when they
    already are); None when no c or more than one does. The Freiburg relations name scans by their
    ipc time, ``run_slam`` stamps them with the logger time, and in the benchmark logs the two
    clocks differ by a constant (ACES 70.1797 s, Intel 976052857.337284 s)."""
    if np.all(on_times(times, stamps)):
        return 0.0
    probes = stamps[np.linspace(0, len(stamps) - 1, min(OFFSET_PROBES, len(stamps))).astype(int)]
    found = []
    for start in range(0, len(times), OFFSET_CHUNK):
        candidates = probes[0] - times[start:start + OFFSET_CHUNK]
        fit = on_times(times, (probes[None, :] - candidates[:, None]).ravel()).reshape(len(candidates), -1)
        found.extend(candidates[fit.all(axis=1)])
    distinct = np.unique(np.round(np.array(found) / SAME_SCAN_TIME)) if found else []
    if len(distinct) != 1 or not np.all(on_times(times, stamps - found[0])):
        return None
    return float(found[0])


# --------------------------------------------------------------------------------------------
# Interpolation and the metric


def _trajectory(timestamps: object, poses: object) -> Tuple[np.ndarray, np.ndarray]:
    """Checked (N,) timestamps and (N, 3) poses: non-empty, same length, non-decreasing."""
    ts = real_array(timestamps, "timestamps", (None,))
    ps = real_array(poses, "poses", (None, 3))
    if ts.shape[0] == 0:
        raise ValueError("timestamps: empty trajectory")
    if ps.shape[0] != ts.shape[0]:
        raise ValueError(f"poses: {ps.shape[0]} poses for {ts.shape[0]} timestamps")
    decreasing = np.flatnonzero(np.diff(ts) < 0)
    if decreasing.size:
        i = int(decreasing[0])
        raise ValueError("timestamps: decrease at index {} ({} then {})".format(i + 1, *distinct_numbers(ts[i], ts[i + 1])))
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


def _checked_relations(relations: Relations) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t1, t2, delta of a Relations built by hand, checked as read_relations would."""
    t1 = real_array(relations.t1, "relations.t1", (None,))
    t2 = real_array(relations.t2, "relations.t2", (t1.shape[0],))
    delta = real_array(relations.delta, "relations.delta", (t1.shape[0], 3))
    if t1.shape[0] == 0:
        raise ValueError("relations: empty (no relation to score)")
    backwards = np.flatnonzero(t2 < t1)
    if backwards.size:
        i = int(backwards[0])
        raise ValueError(f"relations: {backwards.size} rows with t2 < t1 (read_relations skips such rows), "
                         f"first row {i} (t1 {t1[i]:g}, t2 {t2[i]:g})")
    return t1, t2, delta


def relations_error(timestamps: object, poses: object,
                    relations: Union[Relations, PathLike]) -> RelationsError:
    """Kümmerle et al.'s relations error of a trajectory.

    timestamps: (N,) seconds, non-decreasing; poses: (N, 3) ``(x m, y m, theta rad)``;
    relations: a ``Relations`` or the path of a relations file (read with ``read_relations``).
    For each relation the poses x1, x2 at t1, t2 are interpolated (``interpolate_poses``), the
    estimated relative pose is ``d_est = x1^-1 (+) x2`` and the error ``e = d_ref^-1 (+) d_est``;
    translational error ``|e_xy|`` (which equals ``|d_est_xy - d_ref_xy|``), rotational
    ``|wrap(e_theta)|``. Relations with t1 or t2 outside the trajectory's span are skipped and
    counted; if none is left, ``ValueError``. Argument errors are as for ``interpolate_poses``;
    a hand-built ``Relations`` is checked as ``read_relations`` checks a file's rows (finite,
    t2 >= t1; one bad row refuses the whole call, naming it), and must not be empty.
    """
    if not isinstance(relations, Relations):
        relations = read_relations(file_path(relations, "relations", "a Relations or the path of a relations file"))
    ts, ps = _trajectory(timestamps, poses)
    t1, t2, delta = _checked_relations(relations)
    inside = (np.minimum(t1, t2) >= ts[0]) & (np.maximum(t1, t2) <= ts[-1])
    used = np.flatnonzero(inside)
    if used.size == 0:
        raise ValueError(f"relations: none of the {len(t1)} relations lies within the trajectory "
                         f"span [{ts[0]:g}, {ts[-1]:g}]")
    what = "poses and relations: the relations error"
    d_est = _between(_interpolate(ts, ps, t1[used], what), _interpolate(ts, ps, t2[used], what), what)
    e = _between(delta[used], d_est, what)
    translational = np.hypot(e[:, 0], e[:, 1])
    _require_finite(translational, what)
    return RelationsError(translational, np.abs(e[:, 2]), used, int(len(t1) - used.size))


# --------------------------------------------------------------------------------------------
# Trajectories against a ground-truth trajectory: ATE and RPE, as evo computes them


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


#: The statistics of errors that evo prints, in its order (alphabetical).
STATISTICS = ("max", "mean", "median", "min", "rmse", "sse", "std")


def error_statistics(errors: object) -> Dict[str, float]:
    """evo's statistics of errors (K,) >= 0, K >= 1: max, mean, median, min, rmse (root mean
    square), sse (sum of squares), std (population, ddof=0)."""
    e = real_array(errors, "errors", (None,))
    if e.size == 0:
        raise ValueError("errors: empty (no statistic of nothing)")
    squares = e ** 2
    return dict(max=float(np.max(e)), mean=float(np.mean(e)), median=float(np.median(e)), min=float(np.min(e)),
                rmse=float(np.sqrt(np.mean(squares))), sse=float(np.sum(squares)), std=float(np.std(e)))


def statistics_table(title: str, statistics: Dict[str, float]) -> str:
    """``title``, a blank line and one ``name<TAB>value`` row per statistic, laid out as evo's
    ``Result.pretty_str`` (names right-aligned in 10 characters, six decimals)."""
    return title + "\n\n" + "".join(f"{name:>10}\t{value:.6f}\n" for name, value in statistics.items())


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
    ts = real_array(times, f"times_{which}", (None,))
    ps = real_array(poses, f"poses_{which}", (len(ts), 3))
    if len(ts) == 0:
        raise ValueError(f"times_{which}: empty trajectory")
    return ts, ps


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


# --------------------------------------------------------------------------------------------
# A path against reference positions with times: a GPS track


@dataclass(frozen=True)
class PositionError:
    """An estimated path against reference positions (``position_error``): the estimate's
    position interpolated at the time of each reference fix inside its time span.

    count: K, the fixes used; outside: the fixes outside the estimate's span, not used;
    ref_indices (K,): the fixes used, rows of the reference; errors (K,): the distance (m) of
    each from the estimate as it is, rmse their root mean square; errors_aligned (K,),
    rmse_aligned: the same after the SE(2) alignment ``rotation`` (2, 2), ``translation`` (2,)
    of the estimate onto the fixes (Umeyama without scale, evo's ``--align``, as ``ate``'s).
    """

    errors: np.ndarray
    errors_aligned: np.ndarray
    rmse: float
    rmse_aligned: float
    count: int
    outside: int
    ref_indices: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray

    def __str__(self) -> str:
        """evo's statistics of the errors, as they are and aligned (two tables as ``ate``'s)."""
        head = "position error at the reference's fixes (m)"
        return (statistics_table(head + "\n(not aligned)", error_statistics(self.errors)) + "\n"
                + statistics_table(head + "\n(with SE(2) Umeyama alignment)", error_statistics(self.errors_aligned)))


def _path_positions(times_est: object, poses_est: object) -> Tuple[np.ndarray, np.ndarray]:
    """Checked (N,) times, non-decreasing, and (N, 3) poses (x, y, theta; (N, 2) positions get
    a heading of 0), N >= 1."""
    te = real_array(times_est, "times_est", (None,))
    if len(te) == 0:
        raise ValueError("times_est: empty trajectory")
    decreasing = np.flatnonzero(np.diff(te) < 0)
    if decreasing.size:
        i = int(decreasing[0])
        raise ValueError(f"times_est: decrease at index {i + 1} ({te[i]:g} then {te[i + 1]:g}); the path is "
                         f"interpolated in time")
    pe = real_array(poses_est, "poses_est", (len(te), None))
    if pe.shape[1] not in (2, 3):
        raise ValueError(f"poses_est: expected shape (N, 3) poses or (N, 2) positions, got {pe.shape}")
    return te, pe if pe.shape[1] == 3 else np.column_stack([pe, np.zeros(len(pe))])


def position_error(times_est: object, poses_est: object, times_ref: object, positions_ref: object) -> PositionError:
    """An estimated path against reference positions with times, such as a GPS track: the
    estimate's position is interpolated linearly at the time of each reference fix inside the
    estimate's time span (fixes outside it are not used), and the distances to the fixes give the
    RMS error, as it is and after the SE(2) alignment of the positions that minimises their
    squared errors (``align_rigid``: Umeyama without scale, evo's convention, as ``ate``'s).

    times_est (N,) seconds, non-decreasing; poses_est (N, 3) ``(x, y, theta)`` or (N, 2)
    positions (m); times_ref (M,) seconds in any order; positions_ref (M, 2) m.

    Returns a ``PositionError``. Errors: ``TypeError`` / ``ValueError`` naming the argument for
    arrays of the wrong type or shape, empty, NaN or inf, decreasing ``times_est``, no fix
    inside the estimate's span, or coordinates so large that the arithmetic overflows."""
    te, pe = _path_positions(times_est, poses_est)
    tr = real_array(times_ref, "times_ref", (None,))
    pr = real_array(positions_ref, "positions_ref", (len(tr), 2))
    inside = np.flatnonzero((tr >= te[0]) & (tr <= te[-1]))
    if inside.size == 0:
        span = f"[{tr.min():.9g}, {tr.max():.9g}] s" if len(tr) else "empty"
        raise ValueError(f"times_ref: no fix within the estimate's time span [{te[0]:.9g}, {te[-1]:.9g}] s "
                         f"(reference {span})")
    est = _interpolate(te, pe, tr[inside], "poses_est")[:, :2]
    ref = pr[inside]
    with np.errstate(over="ignore", invalid="ignore"):
        errors = np.hypot(est[:, 0] - ref[:, 0], est[:, 1] - ref[:, 1])
    _require_finite(errors, "poses_est and positions_ref: the errors")
    rotation, translation = _se2_alignment(est, ref, "poses_est and positions_ref: the alignment")
    with np.errstate(over="ignore", invalid="ignore"):
        moved = est @ rotation.T + translation
        aligned = np.hypot(moved[:, 0] - ref[:, 0], moved[:, 1] - ref[:, 1])
    _require_finite(aligned, "poses_est and positions_ref: the aligned errors")
    with np.errstate(over="ignore"):
        rms = np.sqrt([np.mean(errors ** 2), np.mean(aligned ** 2)])
    _require_finite(rms, "poses_est and positions_ref: the RMS errors")
    return PositionError(errors, aligned, float(rms[0]), float(rms[1]), int(inside.size), int(len(tr) - inside.size),
                         inside.astype(np.int64), rotation, translation)


def _se2_alignment(est: np.ndarray, ref: np.ndarray, what: str) -> Tuple[np.ndarray, np.ndarray]:
    """``align_rigid`` of (K, 2) positions onto (K, 2), an overflow named by ``what`` (the
    kernel would name its own arguments)."""
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            rotation, translation = align_rigid(est, ref)
    except ValueError:  # the cross-covariance overflows
        raise ValueError(f"{what} overflows a double (inputs too large)") from None
    _require_finite(np.concatenate([rotation.ravel(), translation]), what)
    return rotation, translation


# --------------------------------------------------------------------------------------------
# Landmark SLAM: a path and a map against ground truth, data association against labels


def align_rigid(estimate: np.ndarray, truth: np.ndarray):
    """Best-fit rotation R (2, 2) and translation t (2,) with R @ estimate + t ~ truth (Kabsch)."""
    estimate = real_array(estimate, "estimate", (None, 2))
    truth = real_array(truth, "truth", (len(estimate), 2))
    if len(estimate) == 0:
        raise ValueError("estimate: no points to align")
    with np.errstate(over="ignore", invalid="ignore"):
        mu_e, mu_t = estimate.mean(0), truth.mean(0)
        cross = (estimate - mu_e).T @ (truth - mu_t)
    _require_finite(cross, "estimate and truth: the cross-covariance")  # an SVD of inf or NaN fails
    u, _, vt = np.linalg.svd(cross)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, d]) @ u.T
    return r, mu_t - r @ mu_e


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root mean square of the Euclidean distances between rows of a and b (N, 2 or 3)."""
    return float(np.sqrt(np.mean(np.sum((np.asarray(a) - np.asarray(b)) ** 2, axis=1))))


def truth_positions(groundtruth: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(T, 2) ground-truth positions at `times` (linear interpolation of (t, x, y, ...) rows, held
    at the ends; ``interpolate_poses`` is the whole pose, within the span only)."""
    groundtruth = np.asarray(groundtruth)
    if groundtruth.ndim != 2 or groundtruth.shape[1] < 3 or len(groundtruth) == 0:
        raise ValueError(f"groundtruth: expected (T, 3 or more) rows (t, x, y, ...), got shape {groundtruth.shape}")
    times = real_array(times, "times", (None,))
    return np.column_stack([np.interp(times, groundtruth[:, 0], groundtruth[:, 1]),
                            np.interp(times, groundtruth[:, 0], groundtruth[:, 2])])


#: The fields a landmark SLAM result (``probslam.LandmarkSlamResult``) must have to be scored.
_RESULT_FIELDS = ("times", "poses", "landmarks", "associations")


@dataclass
class MrclamScore:
    """Accuracy of an MRCLAM run against ground truth: path and landmark RMSE (m)."""

    path_rmse: float  # m, raw
    path_rmse_aligned: float  # m, after the best rigid alignment of the path to ground truth
    landmark_rmse: float  # m, against the surveyed positions (same frame as the path)
    landmark_rmse_aligned: float  # m, after the path's alignment
    # The path's alignment onto the ground truth, R estimate + t (the "aligned" errors', e.g. to
    # draw the estimate where the scores put it).
    rotation: np.ndarray = field(default_factory=lambda: np.eye(2))  # (2, 2)
    translation: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (2,) m


def score_mrclam(result, data: Mrclam, landmark_map: Optional[Dict[int, int]] = None) -> MrclamScore:
    """``result``: a ``LandmarkSlamResult`` of an MRCLAM robot with ground truth (times (T,),
    poses (T, 3), landmarks {id: (2,)}); ``landmark_map``: filter id -> surveyed subject
    (identity when correspondences were known, e.g. ``majority_labels(result)`` when hidden)."""
    require_fields(result, _RESULT_FIELDS, "result", "a LandmarkSlamResult")
    require_instance(data, Mrclam, "data")
    truth = truth_positions(data.groundtruth, result.times)
    r, t = align_rigid(result.poses[:, :2], truth)
    aligned = result.poses[:, :2] @ r.T + t
    surveyed = data.landmark_positions
    pairs = [(xy, surveyed[(landmark_map or {}).get(i, i)]) for i, xy in result.landmarks.items()
             if (landmark_map or {}).get(i, i) in surveyed]
    est = np.array([p[0] for p in pairs]).reshape(-1, 2)
    sur = np.array([p[1] for p in pairs]).reshape(-1, 2)
    return MrclamScore(rmse(result.poses[:, :2], truth), rmse(aligned, truth),
                       rmse(est, sur) if len(est) else float("nan"),
                       rmse(est @ r.T + t, sur) if len(est) else float("nan"), r, t)


@dataclass
class LandmarkScore:
    """A landmark map against the survey: RMSE (m) as estimated and after rigid alignment."""

    rmse: float  # m, map against the survey as estimated (frames may differ)
    rmse_aligned: float  # m, after the best rigid alignment of the map onto the survey
    errors: Dict[int, float]  # surveyed subject -> aligned error, m
    rotation: np.ndarray = field(default_factory=lambda: np.eye(2))  # (2, 2) R of R m + t ~ survey
    translation: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (2,) t, m

    def survey_in_map_frame(self, data: Mrclam) -> Dict[int, np.ndarray]:
        """Every surveyed landmark of ``data`` brought into the map's frame by the inverse of the
        alignment (subject -> (2,) m), to draw the survey over the map it was compared with."""
        require_instance(data, Mrclam, "data")
        return {s: (np.asarray(p) - self.translation) @ self.rotation for s, p in data.landmark_positions.items()}


def score_landmarks(landmarks: Dict[int, np.ndarray], data: Mrclam,
                    landmark_map: Optional[Dict[int, int]] = None) -> LandmarkScore:
    """The map alone against the survey, for data without robot ground truth (MRCLAM Dataset 1):
    the filter starts at (0, 0, 0), so its frame is the start pose's, and the map is rigidly
    aligned onto the surveyed landmarks. ``landmark_map``: filter id -> subject (identity by
    default). Needs at least two landmarks."""
    require_instance(landmarks, dict, "landmarks")
    require_instance(data, Mrclam, "data")
    surveyed = data.landmark_positions
    pairs = [(i, (landmark_map or {}).get(i, i)) for i in landmarks]
    pairs = [(i, s) for i, s in pairs if s in surveyed]
    if len(pairs) < 2:
        raise ValueError(f"landmarks: need at least two surveyed landmarks to align, got {len(pairs)}")
    est = np.array([landmarks[i] for i, _ in pairs])
    sur = np.array([surveyed[s] for _, s in pairs])
    r, t = align_rigid(est, sur)
    errors = np.hypot(*(est @ r.T + t - sur).T)
    return LandmarkScore(rmse(est, sur), float(np.sqrt(np.mean(errors ** 2))),
                         {s: float(e) for (_, s), e in zip(pairs, errors)}, r, t)


def _record(result):
    """The association record of a hidden-correspondence run."""
    require_fields(result, _RESULT_FIELDS, "result", "a LandmarkSlamResult")
    if result.associations is None:
        raise ValueError("result: a run with known correspondences has no associations to score")
    return result.associations


def _applied_sightings(result) -> Iterator[Tuple[int, int]]:
    """(true id, filter landmark id) of every sighting a hidden-correspondence run put in its map."""
    record = _record(result)
    applied = record.ids >= 0
    return zip(record.truth[applied].tolist(), record.ids[applied].tolist())


def _labelling(labels, truth) -> Tuple[np.ndarray, np.ndarray]:
    """(labels, truth) of the labelled sightings (label != -1), checked to be two (K,) arrays."""
    labels, truth = np.asarray(labels), np.asarray(truth)
    if labels.shape != truth.shape or labels.ndim != 1:
        raise ValueError(f"labels, truth: expected two (K,) arrays, got {labels.shape} and {truth.shape}")
    keep = labels != -1
    return labels[keep], truth[keep]


def majority_truth(labels, truth) -> Dict[int, int]:
    """A labelling of sightings against their true ids, on arrays: labels (K,) (the landmark each
    sighting went to, -1 for none), truth (K,): each label -> the true id most of its sightings
    carry."""
    labels, truth = _labelling(labels, truth)
    votes: Dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    for lab, t in zip(labels.tolist(), truth.tolist()):
        votes[int(lab)][int(t)] += 1
    return {lab: c.most_common(1)[0][0] for lab, c in votes.items()}


def sighting_accuracy(labels, truth) -> float:
    """Fraction of the labelled sightings (label != -1) whose label's majority true id
    (``majority_truth``) is their own; NaN when none is labelled."""
    labels, truth = _labelling(labels, truth)
    if len(labels) == 0:
        return float("nan")
    major = majority_truth(labels, truth)
    return float(np.mean([major[int(lab)] == int(t) for lab, t in zip(labels.tolist(), truth.tolist())]))


def majority_labels(result) -> Dict[int, int]:
    """For a run with hidden correspondences: each filter landmark -> the true id (the dataset's
    label) most of its sightings carry."""
    record = _record(result)
    return majority_truth(record.ids, record.truth)


def primary_landmarks(result) -> Dict[int, int]:
    """For a run with hidden correspondences: true id -> the filter landmark holding most of its
    sightings (duplicates left out), among the landmarks still in the map."""
    votes: Dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    for t, i in _applied_sightings(result):
        if i in result.landmarks:
            votes[t][i] += 1
    return {t: c.most_common(1)[0][0] for t, c in votes.items()}


def association_accuracy(result) -> float:
    """Fraction of the sightings put in the map that went to a landmark whose majority true id
    (``majority_labels``) is their own; NaN when none was."""
    record = _record(result)
    return sighting_accuracy(record.ids, record.truth)


__all__ = [
    "ALIGNMENTS",
    "DELTA_UNITS",
    "MAX_REPORTED_LINES",
    "MAX_TIME_DIFFERENCE",
    "NEES_SINGULAR_RTOL",
    "LandmarkScore",
    "MrclamScore",
    "PositionError",
    "Relations",
    "RelationsError",
    "SAME_SCAN_TIME",
    "STATISTICS",
    "SingularCovarianceError",
    "TrajectoryError",
    "align_rigid",
    "associate",
    "ate",
    "association_accuracy",
    "clock_offset",
    "error_statistics",
    "interpolate_poses",
    "majority_labels",
    "majority_truth",
    "nees",
    "on_times",
    "position_error",
    "primary_landmarks",
    "read_relations",
    "relations_on_logger_time",
    "relations_error",
    "relative_poses",
    "rmse",
    "rpe",
    "score_landmarks",
    "score_mrclam",
    "statistics_table",
    "sighting_accuracy",
    "truth_positions",
]
