"""When an estimate gets to the reference and stays there: the first pose from which every pose
is within a position and a heading tolerance of the reference's to the end, and the log time and
odometry travel it took to get there (a global localization's convergence, a kidnapped robot's
recovery)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from .._args import positive_real, real_array
from ._checks import _require_finite, _wrap
from .trajectory import MAX_TIME_DIFFERENCE, _poses_at_times, associate

#: A pose counts as right when within this of the reference's (m, rad): a few map cells and a
#: few degrees, well inside a corridor's width and far below the distance to a wrong room.
CONVERGED_POSITION = 0.5
CONVERGED_HEADING = 0.2


@dataclass(frozen=True)
class Convergence:
    """Where an estimate converged to its reference, as ``convergence`` finds it.

    index: the estimate's first pose from which every pose paired with the reference is right
    to the end (None: the last paired pose is wrong); time: seconds from the estimate's first
    pose to it; travel: metres of odometry travel from the first pose to it (None without
    odometry); both None when it did not converge. position_errors (K,) m, heading_errors (K,)
    rad in [0, pi]: at the pairs; est_indices, ref_indices (K,): the pairs (``associate``).
    """

    index: Optional[int]
    time: Optional[float]
    travel: Optional[float]
    position_errors: np.ndarray
    heading_errors: np.ndarray
    est_indices: np.ndarray
    ref_indices: np.ndarray

    @property
    def converged(self) -> bool:
        """Whether the estimate is right from some pose to the end."""
        return self.index is not None


def convergence(times_est: object, poses_est: object, times_ref: object, poses_ref: object, *,
                odometry: object = None, position_tolerance: float = CONVERGED_POSITION,
                heading_tolerance: float = CONVERGED_HEADING,
                max_time_difference: float = MAX_TIME_DIFFERENCE) -> Convergence:
    """Where the estimate ``(times_est (N,), poses_est (N, 3))`` converged to the reference
    ``(times_ref (M,), poses_ref (M, 3))``: the poses paired by time (``associate``), a pair is
    right when its position error is below ``position_tolerance`` (m) and its heading error below
    ``heading_tolerance`` (rad), and the estimate converged at the first paired pose after the last
    wrong one (none wrong: the first paired pose). ``odometry`` (N, 3): the odometry poses at the
    estimate's poses, whose travel to that pose is reported (None: not reported).

    Returns a ``Convergence``. Errors: ``TypeError`` / ``ValueError`` naming the argument for
    arrays of the wrong type or shape, NaN or inf, tolerances that are not finite and > 0, or no
    pose paired with the reference."""
    te, pe = _poses_at_times(times_est, poses_est, "est")  # a log's clock may jump back
    tr, pr = _poses_at_times(times_ref, poses_ref, "ref")
    odom = None if odometry is None else real_array(odometry, "odometry", (len(te), 3))
    position_tolerance = positive_real(position_tolerance, "position_tolerance")
    heading_tolerance = positive_real(heading_tolerance, "heading_tolerance")
    ie, ir = associate(te, tr, max_time_difference)
    if ie.size == 0:
        raise ValueError(f"times_est: no pose within max_time_difference {max_time_difference:g} s of a reference "
                         f"pose (estimate [{te.min():.9g}, {te.max():.9g}] s, reference [{tr.min():.9g}, "
                         f"{tr.max():.9g}] s)")
    order = np.argsort(ie, kind="stable")  # in the estimate's order (associate gives the shorter one's)
    ie, ir = ie[order], ir[order]
    position = np.hypot(pe[ie, 0] - pr[ir, 0], pe[ie, 1] - pr[ir, 1])
    _require_finite(position, "poses_est and poses_ref: the errors")
    heading = np.abs(_wrap(pe[ie, 2] - pr[ir, 2], "poses_est and poses_ref: the heading errors"))
    wrong = np.flatnonzero((position >= position_tolerance) | (heading >= heading_tolerance))
    first = 0 if wrong.size == 0 else int(wrong[-1]) + 1
    index = time = travel = None
    if first < ie.size:
        index = int(ie[first])
        time = float(te[index] - te[0])
        if odom is not None:
            travel = float(np.sum(np.hypot(*np.diff(odom[:index + 1, :2], axis=0).T)))
    return Convergence(index, time, travel, position, heading, ie, ir)


__all__ = ["CONVERGED_HEADING", "CONVERGED_POSITION", "Convergence", "convergence"]
