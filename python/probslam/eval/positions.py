"""A path against reference positions with times, such as a GPS track: the estimate interpolated
at each fix, with and without an SE(2) alignment."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

import numpy as np

from .._args import real_array
from ._checks import _require_finite
from .alignment import _se2_alignment
from .poses import _interpolate, _path_times
from .statistics import error_statistics, statistics_table


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
    te = _path_times(times_est, "times_est", why="; the path is interpolated in time")
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
