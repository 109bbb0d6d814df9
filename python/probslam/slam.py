"""SLAM from a raw laser log, two ways: incremental scan matching into local submaps and GraphSLAM
over the submaps with correlative loop closures (Thrun et al. ch. 11.7; C++ ``SubmapSlam2D``), or
grid-based FastSLAM, a particle filter whose particles carry their own maps (C++ ``GridFastSlam``).

Units: metres, radians, seconds. Poses are laser poses ``(x, y, theta)`` in the frame of the first
scan's odometry pose.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Any, Dict, Optional, Union

import numpy as np
from tqdm import tqdm

from . import _core
from .io.trajectory import write_trajectory as write_trajectory_file
from .datasets import carmen
from .io.carmen import CarmenLog, LaserScans
from .io.rosbag import is_bag, read_rosbag
from .mapping import no_return_range

PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class SlamResult:
    """What ``run_slam`` returns.

    timestamps (S,) s; poses (S, 3) laser poses (GraphSLAM: optimised; rbpf: the best particle's
    path); grid the occupancy map (GraphSLAM: every scan at ``poses``; rbpf: the best particle's
    map); summary the counts (``SubmapSlamSummary`` or ``GridFastSlamSummary``); seconds of
    processing; log_duration in s; odometry whether the log had it; method "graph" or "rbpf".
    GraphSLAM only (None for rbpf): frontend_poses (S, 3) from incremental scan matching alone;
    submap_poses (N, 3) the graph's nodes; graph the optimised ``PoseGraph2D`` (one pose per
    submap); constraints the graph's edges (``SubmapConstraints``: from_submap, to_submap,
    measurement (M, 3), covariance (M, 3, 3), loop, scan, match_quality, active).
    rbpf only: tile_sharing, the particles' map tiles (``TileSharing``: references, distinct, bytes).
    """

    timestamps: np.ndarray
    poses: np.ndarray
    frontend_poses: Optional[np.ndarray]
    submap_poses: Optional[np.ndarray]
    grid: _core.OccupancyGrid2D
    graph: Optional[_core.PoseGraph2D]
    constraints: Optional[_core.SubmapConstraints]
    summary: Union[_core.SubmapSlamSummary, _core.GridFastSlamSummary]
    seconds: float
    log_duration: float
    odometry: bool
    options: Dict[str, Any] = field(default_factory=dict)
    method: str = "graph"
    tile_sharing: Optional[_core.TileSharing] = None

    @property
    def real_time_factor(self) -> float:
        """Log duration over processing time (> 1: faster than the robot recorded it)."""
        return self.log_duration / self.seconds if self.seconds > 0 else float("inf")


#: The methods of ``run_slam``.
METHODS = ("graph", "rbpf")


def run_slam(log: Union[PathLike, CarmenLog, LaserScans], *, method: str = "graph", progress: Optional[bool] = None,
             chunk: int = 200, **options: Any) -> SlamResult:
    """Turns a raw log (a CARMEN or ROS bag path, a ``CarmenLog`` such as ``io.read_rosbag``'s, or
    its ``LaserScans``) into a consistent map.

    ``method="graph"`` (default): ``options`` are those of ``probslam.SubmapSlam2D``: the
    frontend's (resolution (m), max_range (m; default: the log's no-return reading),
    max_usable_range, sigma, p_rand, linear_window, angular_window, min_travel, min_rotation,
    submap_distance, submap_scans, min_match_quality, odometry_noise, use_odometry_prior) and the
    loop closures' (loop_closures, closure_scans_per_submap, closure_min_match_quality,
    closure_window_sigmas, closure_{min,max}_{linear,angular}_window, closure_max_distance,
    dissolve_chi2, max_rounds, field_cache_mb). A log without odometry runs on scan matching
    alone (no odometry prior, every scan matched, wider windows).

    ``method="rbpf"``: grid-based FastSLAM, ``options`` those of ``probslam.GridFastSlam``
    (num_particles (30), proposal ("scan-matching", "motion" or "improved-odometry"),
    resolution, max_range, max_usable_range, sigma, p_rand, search_radius, odometry_noise,
    resample_threshold, update_distance, update_angle, corrected_start, seed, threads, ...). It
    needs odometry.

    ``progress=None`` shows a bar only on a terminal.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if isinstance(log, (str, os.PathLike)):
        log = read_rosbag(log) if is_bag(log) else carmen.load(log)
    scans = log.scans if isinstance(log, CarmenLog) else log
    if not isinstance(scans, LaserScans):
        raise TypeError("log must be a path, a CarmenLog or LaserScans")
    if len(scans) == 0:
        raise ValueError("log has no laser scans")
    if int(chunk) != chunk or chunk < 1:
        raise ValueError("chunk must be an integer >= 1")
    odometry = carmen.has_odometry(scans)
    opts: Dict[str, Any] = {}
    no_return = no_return_range(scans)
    if np.isfinite(no_return):
        opts["max_range"] = no_return
    if not odometry:
        if method == "rbpf":
            raise ValueError("log has no odometry (its laser poses never move): method 'rbpf' samples the "
                             "odometry motion model; use method 'graph', which runs on scan matching alone")
        # Without odometry each scan is matched against the last one's pose: every scan, and a
        # window wide enough for the motion between two scans.
        opts.update(use_odometry_prior=False, min_travel=0.0, min_rotation=0.0, linear_window=0.5,
                    angular_window=0.5)
    opts.update(options)
    mapper = _core.GridFastSlam(**opts) if method == "rbpf" else _core.SubmapSlam2D(**opts)
    angles = scans.beam_angles()
    t0 = time.perf_counter()
    # As map_laser_log: disable=None lets tqdm show the bar only on a terminal.
    with tqdm(total=len(scans), unit="scan", desc=method,
              disable=(None if progress is None else not progress)) as bar:
        for a in range(0, len(scans), chunk):
            b = min(len(scans), a + chunk)
            mapper.add_scans(scans.ranges[a:b], angles[a:b], scans.laser_poses[a:b], scans.timestamps[a:b])
            bar.update(b - a)
    t = scans.timestamps
    duration = float(np.nanmax(t) - np.nanmin(t)) if np.isfinite(t).any() else 0.0
    if method == "rbpf":
        grid = mapper.map()
        seconds = time.perf_counter() - t0
        return SlamResult(timestamps=mapper.timestamps, poses=mapper.scan_poses, frontend_poses=None,
                          submap_poses=None, grid=grid, graph=None, constraints=None, summary=mapper.summary,
                          seconds=seconds, log_duration=duration, odometry=odometry, options=opts, method=method,
                          tile_sharing=mapper.tile_sharing)
    frontend = mapper.frontend_poses
    mapper.finish()
    grid = mapper.map()
    seconds = time.perf_counter() - t0
    return SlamResult(timestamps=mapper.timestamps, poses=mapper.scan_poses, frontend_poses=frontend,
                      submap_poses=mapper.submap_poses, grid=grid, graph=mapper.graph(),
                      constraints=mapper.constraints, summary=mapper.summary, seconds=seconds, log_duration=duration,
                      odometry=odometry, options=opts, method=method)


def write_trajectory(timestamps: np.ndarray, poses: np.ndarray, path: PathLike) -> None:
    """One line per pose: ``timestamp x y theta`` (s, m, m, rad) after a ``#`` header, the layout
    ``probslam`` commands wrote before TUM (``io.write_trajectory(..., format="xyt")``, which this
    calls; TUM and KITTI are there too). timestamps (N,), poses (N, 3), finite (TypeError /
    ValueError naming them); the trajectory first and the path last, as every writer."""
    write_trajectory_file(timestamps, poses, path, format="xyt")


__all__ = ["METHODS", "SlamResult", "run_slam", "write_trajectory"]
