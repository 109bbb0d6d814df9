"""Monte Carlo localization of a raw laser log in a known map (C++ ``MonteCarloLocalization``):
the driver that feeds a log's odometry and scans to the filter and records its estimate.

Units: metres, radians, seconds. Poses are laser poses ``(x, y, theta)`` in the map's frame.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np
from tqdm import tqdm

from . import _core
from .io.carmen import CarmenLog, LaserScans
from .slam import scans_of

PathLike = Union[str, "os.PathLike[str]"]

# The estimate counts as converged when the largest cluster's position standard deviation (its
# covariance's larger x-y eigenvalue, square-rooted) and heading standard deviation fall below
# these: a tracked robot's cloud spans a few decimetres and a few degrees; a global cloud that
# has not settled spans metres.
CONVERGED_XY_STD = 0.5
CONVERGED_THETA_STD = 0.25
# ... and when that cluster holds most of the weight: a global cloud after one scan splits into
# many small tight clusters, none of which is an answer while the others are about as likely.
CONVERGED_CLUSTER_WEIGHT = 0.5


@dataclass
class LocalizationResult:
    """What ``localize`` returns.

    timestamps (S,) s; poses (S, 3) the estimate at every scan (the largest cluster's weighted
    mean, moved by odometry between updates); covariances (S, 3, 3); num_particles (S,);
    converged (S,) bool (``CONVERGED_XY_STD`` / ``CONVERGED_THETA_STD`` / ``CONVERGED_CLUSTER_WEIGHT``); updated (S,) bool (the
    filter updated at this scan); convergence_time: seconds of log from the first scan until the
    estimate first converged (None if it never did); travel_to_converge: metres of odometry
    travel until then; seconds of processing; log_duration s; snapshots: (timestamp, particles
    (M, 3)) at the requested times; options the filter's ``MonteCarloLocalizationOptions``; odometry_travel: metres of
    odometry over the scans (0: nothing moves the filter after its first update).
    ``converged_fraction`` and ``lost`` tell how it went after the first convergence.
    """

    timestamps: np.ndarray
    poses: np.ndarray
    covariances: np.ndarray
    num_particles: np.ndarray
    converged: np.ndarray
    updated: np.ndarray
    convergence_time: Optional[float]
    travel_to_converge: Optional[float]
    seconds: float
    log_duration: float
    snapshots: List[Tuple[float, np.ndarray]] = field(default_factory=list)
    options: Optional[_core.MonteCarloLocalizationOptions] = None
    odometry_travel: float = 0.0

    @property
    def converged_fraction(self) -> Optional[float]:
        """Share of the scans from the first convergence on at which the estimate was converged
        (None if it never converged)."""
        first = np.flatnonzero(self.converged)
        return None if first.size == 0 else float(np.mean(self.converged[first[0]:]))

    @property
    def lost(self) -> List[Tuple[float, Optional[float]]]:
        """The spells without convergence after the first: (log time it was lost, log time it
        converged again or None), seconds from the first scan."""
        c = np.asarray(self.converged, dtype=bool)
        first = np.flatnonzero(c)
        if first.size == 0:
            return []
        t = self.timestamps - self.timestamps[0]
        change = np.flatnonzero(np.diff(c[first[0]:].astype(np.int8))) + first[0] + 1
        starts = [int(i) for i in change if not c[i]]
        ends = [int(i) for i in change if c[i]]
        return [(float(t[a]), next((float(t[b]) for b in ends if b > a), None)) for a in starts]

    @property
    def real_time_factor(self) -> float:
        """Seconds of log per second of processing."""
        return self.log_duration / self.seconds if self.seconds > 0 else float("inf")


def is_converged(covariance: np.ndarray, cluster_weight: float = 1.0) -> bool:
    """Whether a cluster covariance (3, 3) is below ``CONVERGED_XY_STD`` / ``CONVERGED_THETA_STD``
    and the cluster holds at least ``CONVERGED_CLUSTER_WEIGHT`` of the weight."""
    cov = np.asarray(covariance, dtype=float)
    xy = float(np.linalg.eigvalsh(cov[:2, :2])[-1])
    return bool(np.sqrt(max(xy, 0.0)) < CONVERGED_XY_STD and np.sqrt(max(cov[2, 2], 0.0)) < CONVERGED_THETA_STD
                and cluster_weight >= CONVERGED_CLUSTER_WEIGHT)


def default_options(log: Union[PathLike, CarmenLog, LaserScans]) -> _core.MonteCarloLocalizationOptions:
    """The filter's options for a log: the defaults, with max_range at the log's no-return
    reading when it has one (a CARMEN or ROS bag path, a ``CarmenLog`` or its ``LaserScans``)."""
    options = _core.MonteCarloLocalizationOptions()
    no_return = scans_of(log).no_return_range()
    if np.isfinite(no_return):
        options.max_range = no_return
    return options


def localize(log: Union[PathLike, CarmenLog, LaserScans], map: _core.OccupancyGrid2D, *,
             initial_pose: Optional[Sequence[float]] = None, initial_covariance: Optional[np.ndarray] = None,
             start: int = 0, stop: Optional[int] = None, snapshot_times: Sequence[float] = (),
             options: Optional[_core.MonteCarloLocalizationOptions] = None,
             progress: Optional[bool] = None) -> LocalizationResult:
    """Localizes the scans ``start:stop`` of a raw log (a CARMEN or ROS bag path, a ``CarmenLog``
    or its ``LaserScans``) in ``map`` (an ``OccupancyGrid2D``, e.g. ``io.load_ros_map``'s).

    ``initial_pose`` (x, y, theta) in the map's frame with ``initial_covariance`` (3, 3; default
    diag(0.25 m, 0.25 m, 15 deg)^2) for tracking; None for global localization (particles
    uniform over the free cells). ``options``: the filter's ``MonteCarloLocalizationOptions``;
    None takes the defaults with max_range at the log's no-return reading (given options are
    used as they are). ``snapshot_times``: log times (s) at
    which the particle cloud is recorded (the first scan at or after each). ``progress=None``
    shows a bar only on a terminal.
    """
    if not isinstance(map, _core.OccupancyGrid2D):
        raise TypeError("map must be an OccupancyGrid2D")
    scans = scans_of(log)
    n = len(scans)
    for name, v in (("start", start), ("stop", stop)):
        if v is not None and (isinstance(v, bool) or int(v) != v or not 0 <= v <= n):
            raise ValueError(f"{name} must be an integer in [0, {n}], got {v!r}")
    stop = n if stop is None else int(stop)
    start = int(start)
    if stop - start < 1:
        raise ValueError("start, stop: the range holds no scan")
    if options is None:
        options = default_options(scans)
    elif not isinstance(options, _core.MonteCarloLocalizationOptions):
        raise TypeError(f"options: expected a MonteCarloLocalizationOptions, got {type(options).__name__}")
    options = options.copy()
    mcl = _core.MonteCarloLocalization(map, options=options, initial_pose=initial_pose,
                                       initial_covariance=initial_covariance)
    skip = options.max_range + 1.0  # a value the filter skips (at or beyond max_range)
    angles = scans.beam_angles()
    odom = scans.laser_poses
    times = np.asarray(snapshot_times, dtype=float)
    m = stop - start
    poses = np.empty((m, 3))
    covs = np.empty((m, 3, 3))
    counts = np.empty(m, dtype=np.int64)
    shares = np.empty(m)
    updated = np.zeros(m, dtype=bool)
    snapshots: List[Tuple[float, np.ndarray]] = []
    pending = sorted(times.tolist())
    t0 = time.perf_counter()
    with tqdm(total=m, unit="scan", desc="localize", disable=(None if progress is None else not progress)) as bar:
        for i, k in enumerate(range(start, stop)):
            if i > 0:
                mcl.predict_odometry(previous=odom[k - 1], current=odom[k])
            b = int(scans.num_beams[k])
            r = scans.ranges[k, :b]
            r = np.where(np.isfinite(r) & (r >= 0), r, skip)
            u = mcl.update(r, angles[k, :b])
            updated[i] = u.updated
            poses[i] = mcl.pose
            covs[i] = mcl.covariance
            shares[i] = mcl.cluster_weight
            counts[i] = mcl.num_particles
            while pending and scans.timestamps[k] >= pending[0]:
                pending.pop(0)
                snapshots.append((float(scans.timestamps[k]), mcl.poses))
            if i % 100 == 99:
                bar.update(100)
        bar.update(m - bar.n)
    seconds = time.perf_counter() - t0
    t = scans.timestamps[start:stop]
    duration = float(t[-1] - t[0]) if m > 1 else 0.0
    conv = np.array([is_converged(c, w) for c, w in zip(covs, shares)], dtype=bool)
    good = np.flatnonzero(conv)
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(odom[start:stop, :2], axis=0).T))])
    conv_time = travel = None
    if good.size:
        conv_time = float(t[good[0]] - t[0])
        travel = float(travelled[good[0]])
    return LocalizationResult(timestamps=np.array(t, dtype=float), poses=poses, covariances=covs, num_particles=counts,
                              converged=conv, updated=updated, convergence_time=conv_time,
                              travel_to_converge=travel, seconds=seconds, log_duration=duration,
                              snapshots=snapshots, options=options, odometry_travel=float(travelled[-1]))


__all__ = ["CONVERGED_CLUSTER_WEIGHT", "CONVERGED_THETA_STD", "CONVERGED_XY_STD", "LocalizationResult", "default_options",
           "is_converged", "localize"]
