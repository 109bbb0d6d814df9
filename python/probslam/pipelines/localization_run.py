"""A raw laser log localized in a known map by Monte Carlo localization (ch. 8.3: KLD sampling,
augmented MCL), tracking or global: checked, run, then its trajectory written and its picture
drawn. ``localize_log(log, map, options)`` returns a ``LocalizationRun`` that summarises, writes
and draws itself (``probslam localize``). The filter's options travel as one
``MonteCarloLocalizationOptions`` (``localization.default_options(log)``: the defaults with the
log's no-return reading as max_range).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np

from .. import _core, io
from .._args import real_array, require_instance
from ..localization import (CONVERGED_CLUSTER_WEIGHT, CONVERGED_THETA_STD, CONVERGED_XY_STD, LocalizationResult,
                            default_options, localize)
from ..slam import scans_of
from .inputs import MAP_FILE, read_log, reading

PathLike = Union[str, "os.PathLike[str]"]

#: Where the particle cloud is recorded: at these shares of the log's odometry travel (the start,
#: early while a global cloud settles, and the end), so that a robot standing still does not give
#: pictures of the same cloud.
SNAPSHOT_TRAVEL = (0.0, 0.02, 0.1, 1.0)
#: The drawn estimate is broken where it jumps further than this (m) between two scans (a
#: relocation by augmented MCL, or a cluster that took over): a straight line there would cross
#: the map. The robot moves a few decimetres between two scans of any laser log.
TRACK_JUMP = 1.0


def snapshot_times(scans) -> List[float]:
    """The log times of SNAPSHOT_TRAVEL: the first scan at or after each share of the travel."""
    t = scans.timestamps
    if not len(t):
        return []
    xy = scans.laser_poses[:, :2]
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    index = [int(np.searchsorted(travelled, f * travelled[-1])) for f in SNAPSHOT_TRAVEL]
    return [float(t[i]) for i in sorted(set(min(i, len(t) - 1) for i in index))]


def check_map_holds_scans(grid: _core.OccupancyGrid2D, scans) -> None:
    """ValueError naming ``map`` when it is smaller than the log's median laser reading, so that it
    cannot hold a scan: a YAML whose resolution is off by orders (1e-6 for 0.05) would otherwise
    localize the robot in a speck."""
    r = scans.ranges
    r = r[np.isfinite(r) & (r > 0)]
    if not r.size:
        return
    median = float(np.median(r))
    width, height = grid.width * grid.resolution, grid.height * grid.resolution
    if math.hypot(width, height) < median:
        raise ValueError(f"map: {width:.3g} x {height:.3g} m ({grid.width} x {grid.height} cells of "
                         f"{grid.resolution:g} m) is smaller than the log's median laser reading ({median:.2f} m): "
                         "check its resolution")


def convergence_report(result: LocalizationResult) -> str:
    """When the estimate first converged, then the share of the time, and the spells it was lost."""
    if result.convergence_time is None:
        return (f"no (the largest cluster never came below {CONVERGED_XY_STD} m / {CONVERGED_THETA_STD} rad "
                f"holding {CONVERGED_CLUSTER_WEIGHT:.0%} of the weight)")
    text = (f"after {result.convergence_time:.1f} s of log, {result.travel_to_converge:.1f} m of travel; "
            f"then converged {100 * result.converged_fraction:.1f}% of the time")
    lost = result.lost
    if lost:
        spells = "; ".join(f"lost at {a:.1f} s, " + ("regained at {:.1f} s".format(b) if b is not None else
                                                     "not regained") for a, b in lost[:3])
        more = f"; {len(lost) - 3} more" if len(lost) > 3 else ""
        text += f" ({spells}{more})"
    return text


def converged_track(result: LocalizationResult) -> np.ndarray:
    """(K, 2) the estimate where it is converged, with a NaN row in each gap (scans not
    converged) and at each jump of more than TRACK_JUMP: a plotted line then shows only the track
    the filter was sure of, without straight lines across the map."""
    xy = np.asarray(result.poses, dtype=float)[:, :2]
    keep = np.asarray(result.converged, dtype=bool)
    step = np.concatenate([[0.0], np.hypot(*np.diff(xy, axis=0).T)])
    joined = np.concatenate([[False], keep[:-1] & keep[1:]]) & (step <= TRACK_JUMP)
    rows = []
    for i in np.flatnonzero(keep):
        if rows and not joined[i]:
            rows.append((np.nan, np.nan))
        rows.append(tuple(xy[i]))
    return np.array(rows, dtype=float).reshape(-1, 2)


@dataclass
class LocalizationRun:
    """One log localized in one map: the log, the map, where it started (None: global) and the
    filter's ``LocalizationResult``; ``summary``, ``write`` and ``draw`` present it."""

    log: object  # the log read (io.CarmenLog / io.RosbagLog), or its LaserScans
    grid: _core.OccupancyGrid2D
    result: LocalizationResult
    initial_pose: Optional[Tuple[float, float, float]] = None

    @property
    def converged(self) -> bool:
        """Whether the estimate ever converged."""
        return self.result.convergence_time is not None

    def summary(self, log_name: str = "the log", map_name: str = "the map", written: Sequence[str] = ()) -> str:
        """The run in lines: the log (``log_name``), the map (``map_name``), the start, the scans
        and updates, the particle counts, the convergence, the time and the files ``written``."""
        r, grid = self.result, self.grid
        n = r.num_particles
        start = ("global (uniform over free space)" if self.initial_pose is None else
                 "from x={:.2f} y={:.2f} theta={:.3f}".format(*self.initial_pose))
        lines = [f"log:           {log_name}"]
        if isinstance(self.log, io.RosbagLog):
            lines.append(f"bag:           {self.log.describe()}")
        lines += [f"map:           {map_name}: {grid.width} x {grid.height} cells at {grid.resolution} m",
                  f"start:         {start}",
                  f"scans:         {len(r.timestamps)}; {int(r.updated.sum())} filter updates"]
        if r.odometry_travel == 0.0 and len(r.timestamps) > 1:
            lines.append("odometry:      none: the log's poses never move, and the filter updates only after travel "
                         f"({r.options.update.distance} m or {math.degrees(r.options.update.angle):g} degrees), so "
                         "nothing moved it after the first scan; localize a log with odometry")
        lines += [f"particles:     {int(n.min())} to {int(n.max())} (median {int(np.median(n))}, last {int(n[-1])})",
                  f"converged:     {convergence_report(r)}",
                  f"time:          {r.seconds:.1f} s for {r.log_duration:.0f} s of log "
                  f"(real-time factor {r.real_time_factor:.0f})"]
        if written:
            lines.append(f"wrote:         {', '.join(written)}")
        return "\n".join(lines)

    def write(self, prefix: str, trajectory_format: str = "tum") -> List[str]:
        """PREFIX_trajectory.EXT: the estimate at every scan, with the log's times
        (``io.write_trajectory``); returns the paths written."""
        path = prefix + "_trajectory" + io.trajectory.EXTENSIONS[trajectory_format]
        return list(io.write_trajectory(self.result.timestamps, self.result.poses, path, format=trajectory_format))

    def draw(self, plt, title: str = ""):
        """A figure (matplotlib's pyplot given): the map, the converged estimate and the particle
        clouds recorded (``plot.occupancy_map``) beside the particle count over time."""
        from ..plot import occupancy_map

        r = self.result
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(14, 6.5), gridspec_kw=dict(width_ratios=(2, 1)))
        occupancy_map(ax, self.grid, converged_track(r), trajectory_label="MCL estimate (where converged)")
        colours = ("tab:blue", "tab:orange", "tab:green", "tab:purple")
        t0 = r.timestamps[0]
        for (t, particles), colour in zip(r.snapshots, colours):
            ax.scatter(particles[:, 0], particles[:, 1], s=0.5, color=colour, alpha=0.4,
                       label=f"particles at {t - t0:.0f} s ({len(particles)})")
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small", markerscale=8)
        ax.set_title(title, fontsize="medium")
        bx.plot(r.timestamps - t0, r.num_particles, color="tab:blue")
        bx.set_yscale("log")
        bx.set_xlabel("log time [s]")
        bx.set_ylabel("particles (KLD sampling)")
        if r.convergence_time is not None:
            bx.axvline(r.convergence_time, color="tab:red", lw=0.8, label="first converged")
            bx.legend(fontsize="small")
        return fig

    def write_plain_picture(self, path: str) -> str:
        """PATH: the picture without matplotlib (``io.write_png``: the map and the converged track)."""
        io.write_png(self.grid, path, trajectory=converged_track(self.result))  # it leaves out the NaN rows
        return path


def localize_log(log: Union[PathLike, object], map: Union[PathLike, _core.OccupancyGrid2D],
                 options: Optional[_core.MonteCarloLocalizationOptions] = None, *,
                 initial_pose: Optional[Sequence[float]] = None,
                 progress: Optional[bool] = None) -> LocalizationRun:
    """Localizes ``log`` (a CARMEN log or ROS bag path, a log read, or its ``LaserScans``) in
    ``map`` (a map_server YAML path or an ``OccupancyGrid2D``) from ``initial_pose`` (x, y, theta
    in the map's frame: tracking; None: global, particles over the free space) with ``options``
    (None: ``localization.default_options(log)``), the particle cloud recorded at SNAPSHOT_TRAVEL.
    ValueError naming ``initial_pose`` when it is not three finite numbers, ``map`` when it cannot
    hold a scan; the filter's own errors name its option; files that are not a map or a log an
    InputError naming them (``inputs.reading``)."""
    if isinstance(map, (str, os.PathLike)):
        with reading(os.fspath(map), MAP_FILE):
            map = io.load_ros_map(map)
    if isinstance(log, (str, os.PathLike)):
        log = read_log(os.fspath(log))
    require_instance(map, _core.OccupancyGrid2D, "map")
    if initial_pose is not None:
        initial_pose = tuple(float(v) for v in real_array(initial_pose, "initial_pose", (3,)))
    scans = scans_of(log)
    check_map_holds_scans(map, scans)
    result = localize(scans, map, options=default_options(scans) if options is None else options,
                      initial_pose=initial_pose, snapshot_times=snapshot_times(scans), progress=progress)
    return LocalizationRun(log, map, result, initial_pose)


__all__ = ["LocalizationRun", "SNAPSHOT_TRAVEL", "TRACK_JUMP", "check_map_holds_scans", "convergence_report",
           "converged_track", "localize_log", "snapshot_times"]
