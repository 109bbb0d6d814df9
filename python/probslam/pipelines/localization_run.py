"""A raw laser log localized in a known map by Monte Carlo localization (ch. 8.3: KLD sampling,
augmented MCL), tracking or global: checked, run, then its trajectory written and its picture
drawn. ``localize_log(log, map, options)`` returns a ``LocalizationRun`` that summarises, writes
and draws itself (``probslam localize``). The filter's options travel as one
``MonteCarloLocalizationOptions`` (``localization.default_options(log)``: the defaults with the
log's no-return reading as max_range). A run may take a piece of the log (``LogPiece``: a segment
of log time, or two spliced as a kidnapped robot) and score itself against a reference in the map's
frame (``LocalizationRun.reference_metrics``: when it converged to it, ``eval.convergence``), as
the localize runs of ``probslam batch`` and benchmarks/bench_localization.py do.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .. import _core, geometry, io
from .. import eval as evaluation
from .._args import positive_real, real_array, require_instance, require_integer
from ..localization import (CONVERGED_CLUSTER_WEIGHT, CONVERGED_THETA_STD, CONVERGED_XY_STD, LocalizationResult,
                            default_options, localize)
from ..slam import scans_of
from ._options import Options, described
from .evaluation import EvaluationOptions, TrajectoryEvaluation
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
#: A step between two scans of none, back, or of this many seconds or more is the logger's clock
#: jumping (the raw Intel log's goes back), not time the robot moved: a laser log's scans come a
#: fraction of a second apart. A piece of a log (``LogPiece``) counts its time without such steps.
CLOCK_JUMP = 5.0
#: ``localize_log``'s initial_pose that starts from the reference's pose at the first scan.
FROM_REFERENCE = "reference"


def span_end(timestamps: np.ndarray, start: int, seconds: float) -> int:
    """One past the last scan of the piece of ``seconds`` of log time from scan ``start`` (the
    scan that reaches it is the piece's last; a step of a clock jump, CLOCK_JUMP, counts as
    none), or the log's length when less is left."""
    steps = np.diff(np.asarray(timestamps, dtype=float)[start:])
    elapsed = np.cumsum(np.where((steps > 0) & (steps < CLOCK_JUMP), steps, 0.0))
    reached = int(np.searchsorted(elapsed, seconds, side="left"))
    return len(timestamps) if reached == len(elapsed) else start + reached + 2


def splice(scans: io.LaserScans, first, second) -> io.LaserScans:
    """A kidnapped robot's log: the scans ``first`` then the scans ``second`` (row indices, slices
    or masks of ``scans``), the second piece's odometry (its laser and robot poses) moved rigidly
    to continue from the first piece's last laser pose: the odometry does not see the jump, the
    true pose jumps. Each scan keeps its own time, so that a reference of the log pairs with it
    (the filter reads no time). ValueError naming ``first`` / ``second`` when one is empty."""
    a, b = scans.take(first), scans.take(second)
    for name, piece in (("first", a), ("second", b)):
        if len(piece) == 0:
            raise ValueError(f"{name}: the piece holds no scan")
    end, start = a.laser_poses[-1], b.laser_poses[0]
    b = dataclasses.replace(b, **{name: geometry.compose(end, geometry.between(start, getattr(b, name)))
                                  for name in ("laser_poses", "robot_poses")})
    return io.LaserScans(**{f.name: np.concatenate([getattr(a, f.name), getattr(b, f.name)])
                            for f in dataclasses.fields(a)})


@dataclass
class LogPiece(Options):
    """The scans of a log a localization runs on: a segment of log time (``span_end``), or two
    spliced as a kidnapped robot (``splice``: the second piece after the first, each scan keeping
    its time). Checked when made and by ``replace``: TypeError / ValueError naming the field."""

    start_scan: int = described(0, "the first scan (its index in the log)")
    segment_seconds: Optional[float] = described(None, "how much log time from ``start_scan`` (None: to the log's "
                                                       "end)", "s", type=float)
    splice_scan: Optional[int] = described(None, "a kidnapping: as long a piece from this scan (after the first) "
                                                 "follows the first, its odometry continued from the first's end "
                                                 "(None: no splice)", type=int)

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """TypeError / ValueError naming the first field that is wrong."""
        require_integer(self.start_scan, "start_scan", lowest=0)
        if self.segment_seconds is not None:
            positive_real(self.segment_seconds, "segment_seconds")
        if self.splice_scan is not None:
            require_integer(self.splice_scan, "splice_scan", lowest=0)

    def cut(self, scans: io.LaserScans) -> Tuple[io.LaserScans, Optional[int]]:
        """The piece's scans of ``scans`` and, spliced, the index of the first scan after the
        jump (None otherwise). ValueError naming the field that does not fit the log."""
        n = len(scans)
        if self.start_scan >= n:
            raise ValueError(f"start_scan: {self.start_scan} is past the log's last scan ({n - 1})")
        seconds = self.segment_seconds

        def end(start: int) -> int:
            return n if seconds is None else span_end(scans.timestamps, start, seconds)

        first = slice(self.start_scan, end(self.start_scan))
        if self.splice_scan is None:
            return scans.take(first), None
        if not first.stop <= self.splice_scan < n:
            raise ValueError(f"splice_scan: must lie in [{first.stop}, {n - 1}] (after the first piece, scans "
                             f"{first.start}-{first.stop - 1}: each scan keeps its time), got {self.splice_scan}")
        return splice(scans, first, slice(self.splice_scan, end(self.splice_scan))), first.stop - first.start


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
    filter's ``LocalizationResult``; ``summary``, ``write`` and ``draw`` present it. A run on a
    spliced piece (``LogPiece``) has ``jump``, the index of its first scan after the jump; a run
    given a reference keeps it (``reference``, its poses) and scores itself against it
    (``reference_metrics``)."""

    log: object  # the log read (io.CarmenLog / io.RosbagLog), or its LaserScans (a LogPiece's)
    grid: _core.OccupancyGrid2D
    result: LocalizationResult
    initial_pose: Optional[Tuple[float, float, float]] = None
    jump: Optional[int] = None
    reference: Optional[io.Trajectory] = None

    @property
    def converged(self) -> bool:
        """Whether the estimate ever converged."""
        return self.result.convergence_time is not None

    def reference_metrics(self, align: bool = False) -> Dict[str, Any]:
        """The run against its reference, in the map's frame (the trajectory of the SLAM run that
        made the map; with ``align``, a reference in another frame, the estimate first moved onto
        it as the ATE aligns it), each pose paired with the reference's at its time:
        ``converged_to_reference``, ``time_to_converge_s``, ``travel_to_converge_m``
        (``eval.convergence``; spliced: from the jump on); the position errors' median and max
        and the heading errors' median (degrees) over the run; spliced also ``jump_m`` (how far
        the reference jumps there) and ``tracked_before_jump`` (the median error before it below
        ``eval.CONVERGED_POSITION``). ValueError when the run has no reference."""
        if self.reference is None:
            raise ValueError("reference: the run was given none")
        r, ref = self.result, self.reference
        odometry = scans_of(self.log).laser_poses
        poses = r.poses
        if align:
            a = evaluation.ate(r.timestamps, r.poses, ref.timestamps, ref.poses, align="se2")
            turn = math.atan2(a.rotation[1, 0], a.rotation[0, 0])
            poses = geometry.compose([a.translation[0], a.translation[1], turn], r.poses)

        def converge(start: int) -> evaluation.Convergence:
            return evaluation.convergence(r.timestamps[start:], poses[start:], ref.timestamps, ref.poses,
                                          odometry=odometry[start:])

        whole = converge(0)
        after = whole if self.jump is None else converge(self.jump)
        metrics: Dict[str, Any] = {
            "converged_to_reference": after.converged, "time_to_converge_s": after.time,
            "travel_to_converge_m": after.travel, "error_median_m": float(np.median(whole.position_errors)),
            "error_max_m": float(np.max(whole.position_errors)),
            "heading_error_median_deg": math.degrees(float(np.median(whole.heading_errors)))}
        if self.jump is not None:
            paired = dict(zip(whole.est_indices.tolist(), whole.ref_indices.tolist()))
            ends = [paired.get(k) for k in (self.jump - 1, self.jump)]
            before = whole.position_errors[whole.est_indices < self.jump]
            metrics["jump_m"] = (None if None in ends else
                                 float(np.hypot(*(ref.poses[ends[1], :2] - ref.poses[ends[0], :2]))))
            metrics["tracked_before_jump"] = (bool(np.median(before) < evaluation.CONVERGED_POSITION)
                                              if before.size else None)
        return metrics

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


def reference_poses(path: PathLike, scans: io.LaserScans) -> io.Trajectory:
    """The poses of a localization's reference at ``path``: a trajectory file, or a CARMEN log
    with corrected poses (its clock checked against ``scans``'), read as ``probslam eval`` reads
    a reference (``TrajectoryEvaluation.read_reference``). ValueError naming ``reference`` for a
    file without poses (relations, positions)."""
    stand_in = io.Trajectory(scans.timestamps, scans.laser_poses, "log")  # the log's clock, for a CARMEN reference
    read = TrajectoryEvaluation(options=EvaluationOptions(), estimate_path="the log", estimate=stand_in)
    read.read_reference(path)
    if read.kind not in ("trajectory", "carmen"):
        raise ValueError(f"reference: {os.fspath(path)} is a {read.kind} file; a localization is scored against "
                         "poses (a trajectory file, a CARMEN log with corrected poses)")
    return read.reference


def localize_log(log: Union[PathLike, object], map: Union[PathLike, _core.OccupancyGrid2D],
                 options: Optional[_core.MonteCarloLocalizationOptions] = None, *,
                 initial_pose: Union[Sequence[float], str, None] = None, piece: Optional[LogPiece] = None,
                 reference: Union[PathLike, io.Trajectory, None] = None,
                 progress: Optional[bool] = None) -> LocalizationRun:
    """Localizes ``log`` (a CARMEN log or ROS bag path, a log read, or its ``LaserScans``), or
    its ``piece`` (a ``LogPiece``: a segment, or two spliced as a kidnapping; None: the whole log),
    in ``map`` (a map_server YAML path or an ``OccupancyGrid2D``) from ``initial_pose`` (x, y,
    theta in the map's frame: tracking; FROM_REFERENCE: the reference's pose at the first scan;
    None: global, particles over the free space) with ``options`` (None:
    ``localization.default_options(log)``, of the whole log), the particle cloud recorded at
    SNAPSHOT_TRAVEL. ``reference`` (a trajectory file or corrected CARMEN log, ``reference_poses``,
    or its poses read) is kept for ``LocalizationRun.reference_metrics``. ValueError naming
    ``initial_pose`` when it is not three finite numbers (or FROM_REFERENCE without a reference
    pose at the first scan's time), ``map`` when it cannot hold a scan, the ``piece``'s field that
    does not fit the log; the filter's own errors name its option; files that are not a map or a
    log an InputError naming them (``inputs.reading``)."""
    if isinstance(map, (str, os.PathLike)):
        with reading(os.fspath(map), MAP_FILE):
            map = io.load_ros_map(map)
    if isinstance(log, (str, os.PathLike)):
        log = read_log(os.fspath(log))
    require_instance(map, _core.OccupancyGrid2D, "map")
    if piece is not None:
        require_instance(piece, LogPiece, "piece")
    scans = scans_of(log)
    options = default_options(scans) if options is None else options
    jump = None
    if piece is not None:
        log, jump = piece.cut(scans)
        scans = log
    if reference is not None and not isinstance(reference, io.Trajectory):
        reference = reference_poses(reference, scans)
    if isinstance(initial_pose, str) and initial_pose == FROM_REFERENCE:
        initial_pose = _pose_at(reference, float(scans.timestamps[0]))
    elif initial_pose is not None:
        initial_pose = tuple(float(v) for v in real_array(initial_pose, "initial_pose", (3,)))
    check_map_holds_scans(map, scans)
    result = localize(scans, map, options=options, initial_pose=initial_pose, snapshot_times=snapshot_times(scans),
                      progress=progress)
    return LocalizationRun(log, map, result, initial_pose, jump, reference)


def _pose_at(reference: Optional[io.Trajectory], time: float) -> Tuple[float, float, float]:
    """The reference's pose paired with ``time`` (``eval.associate``): FROM_REFERENCE's start."""
    if reference is None:
        raise ValueError(f"initial_pose: {FROM_REFERENCE!r} needs a reference")
    _, k = evaluation.associate([time], reference.timestamps)
    if not k.size:
        raise ValueError(f"initial_pose: {FROM_REFERENCE!r}: the reference has no pose within "
                         f"{evaluation.MAX_TIME_DIFFERENCE:g} s of the first scan ({time:.9g} s)")
    return tuple(float(v) for v in reference.poses[k[0]])


__all__ = ["CLOCK_JUMP", "FROM_REFERENCE", "LocalizationRun", "LogPiece", "SNAPSHOT_TRAVEL", "TRACK_JUMP",
           "check_map_holds_scans", "convergence_report", "converged_track", "localize_log", "reference_poses",
           "snapshot_times", "span_end", "splice"]
