"""The relations metric of Kümmerle et al. 2009, "On measuring the accuracy of SLAM algorithms".

A laser SLAM result is scored by the relative poses it implies between pairs of timestamps, compared
with reference relations (the Freiburg SLAM benchmark's ``*.relations`` files, hand-checked scan
alignments). Relative poses do not depend on where the map is anchored, so no global alignment
is needed, and an error in one place is counted once rather than carried along the trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional, Tuple, Union

import numpy as np

from .._args import real_array, require_instance
from ..io._files import file_path, numeric_rows, require_regular_file
from ..io.carmen import LaserScans
from ._checks import PathLike, _require_finite
from .poses import _between, _interpolate, _trajectory

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
