"""A raw laser log to a consistent map, the run of ``probslam slam``: ``slam_log(log, options)``
runs ``slam.run_slam`` (GraphSLAM over submaps, or grid-based FastSLAM) and returns a
``SlamLogRun``, which summarises, writes and draws itself. Options travel as the run's typed
``SubmapSlamOptions`` or ``GridFastSlamOptions`` (``slam.default_options(log, method)`` gives the
log's own).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

from .. import io
from .._args import require_instance
from ..graph import write_g2o
from ..io.trajectory import EXTENSIONS
from ..slam import INITIAL_MAP, SlamResult, default_options, load_initial_map, run_slam, with_fields
from .inputs import check_input, one_line, read_log

PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class SlamLogRun:
    """A finished SLAM run over a log: ``log`` as read (``CarmenLog`` or ``io.RosbagLog``),
    ``result`` (``SlamResult``), ``path`` the log's file (None: given already read),
    ``start_map`` the saved map it started from (its path) and ``initial_pose`` the guess there,
    ``resumed`` the run file it continued."""

    log: Any
    result: SlamResult
    path: Optional[str] = None
    start_map: Optional[str] = None
    initial_pose: Optional[Tuple[float, float, float]] = None
    resumed: Optional[str] = None

    def write(self, prefix: str, trajectory_format: str = "tum") -> List[str]:
        """PREFIX.yaml and PREFIX.pgm (map_server's map), the trajectory
        (PREFIX_trajectory.tum, .kitti or .txt by ``trajectory_format``) and, for GraphSLAM,
        PREFIX.g2o (the optimised submap graph); returns the paths written, in that order."""
        r = self.result
        io.save_ros_map(r.grid, prefix + ".yaml")
        written = [prefix + ".yaml", prefix + ".pgm"]
        written += io.write_trajectory(r.timestamps, r.poses, prefix + "_trajectory" + EXTENSIONS[trajectory_format],
                                       format=trajectory_format)
        if r.graph is not None:
            write_g2o(r.graph, prefix + ".g2o")
            written.append(prefix + ".g2o")
        return written

    def title(self) -> str:
        """The picture's title: the command, the log and the method."""
        r = self.result
        how = (f"grid-based FastSLAM, best of {r.options.num_particles} particles" if r.method == "rbpf"
               else "GraphSLAM over submaps")
        name = os.path.basename(self.path) if self.path else "a laser log"
        return f"probslam slam --method {r.method}: {name}\n{how}"

    def draw(self, plt):
        """A figure of the map and the run's laser poses (matplotlib's pyplot given)."""
        from ..plot import occupancy_map_figure

        return occupancy_map_figure(plt, self.result.grid, self.result.poses, "SLAM laser poses", self.title())

    def write_plain_picture(self, path: str) -> str:
        """PATH: the picture without matplotlib (``io.write_png``: one pixel a cell)."""
        io.write_png(self.result.grid, path, trajectory=self.result.poses)
        return path

    def summary(self, name: Optional[str] = None, written: Sequence[str] = ()) -> str:
        """What was run and made, in lines (``name``: how to call the log; default its path) and
        the files ``written``."""
        r, s, log = self.result, self.result.summary, self.log
        lines = [f"log:           {self.path if name is None else name}"]
        if isinstance(log, io.RosbagLog):
            lines.append(f"bag:           {log.describe()}")
        skipped = f", {log.skipped_wide_scans} skipped: far wider than the rest" if log.skipped_wide_scans else ""
        if self.resumed is not None:
            lines.append(f"resumed:       {self.resumed} ({r.method}, its saved options)")
        if self.start_map is not None:
            x, y, theta = self.initial_pose or (0.0, 0.0, 0.0)
            role = "every particle's first map" if r.method == "rbpf" else "the graph's fixed first submap"
            lines.append(f"started from:  {self.start_map} ({role}; the log's first scan guessed at {x:g} {y:g} "
                         f"{theta:g}, matched at {r.poses[0][0]:.3f} {r.poses[0][1]:.3f} {r.poses[0][2]:.3f})")
        if r.method == "rbpf":
            t = r.tile_sharing
            particles, proposal = r.options.num_particles, r.options.proposal
            lines += [f"method:        grid-based FastSLAM, {particles} particles, {proposal} proposal",
                      f"scans:         {s.scans}{skipped}; {s.updates} filter updates, {s.resamples} resamplings"]
            if proposal == "scan-matching":
                lines.append(f"proposal:      {s.matched} particle updates scan-matched, {s.fallbacks} fell back "
                             f"to the motion model")
            lines.append(f"maps:          {t.distinct} distinct tiles for {t.references} held "
                         f"({t.bytes / 2 ** 20:.1f} MiB)")
        else:
            lines += [f"scans:         {s.scans} ({s.matched_scans} scan-matched"
                      + ("" if r.odometry else "; no odometry in the log: scan matching alone") + ")" + skipped,
                      f"submaps:       {s.submaps}",
                      f"closures:      {s.closures_accepted} accepted, {s.closures_rejected} rejected, "
                      f"{s.closures_dissolved} dissolved ({s.closures_searched} searched, {s.rounds} rounds)"]
        grid = r.grid
        lines += [f"map:           {grid.width} x {grid.height} cells at {grid.resolution} m, origin {grid.origin}",
                  f"time:          {r.seconds:.1f} s for {r.log_duration:.0f} s of log "
                  f"(real-time factor {r.real_time_factor:.1f})"]
        if written:
            lines.append(f"wrote:         {', '.join(written)}")
        return "\n".join(lines)


def slam_log(log: Any, options=None, *, method: Optional[str] = None, fields: Optional[Dict[str, Any]] = None,
             path: Optional[PathLike] = None, initial_map=None, start_map: Optional[PathLike] = None,
             initial_pose=None, resume: Optional[PathLike] = None, save: Optional[PathLike] = None,
             progress: Optional[bool] = None) -> SlamLogRun:
    """``slam.run_slam`` over ``log`` (a CARMEN log's or a bag's path, read by ``inputs.read_log``,
    or a log already read: ``io.CarmenLog`` / ``io.RosbagLog``) with ``options`` (a
    ``SubmapSlamOptions`` or ``GridFastSlamOptions``; None: ``slam.default_options`` of the log,
    ``method`` and the start map) and the fields by path in ``fields``
    (``{"frontend.resolution": 0.1}``, ``slam.with_fields``), and the run that summarises, writes
    and draws it. ``initial_map``: a saved map to start from (an ``OccupancyGrid2D`` or its file,
    ``slam.load_initial_map``; errors name ``initial_map``), ``initial_pose`` the log's first scan
    in it; ``resume`` a run file to continue (its method and options), ``save`` where to write the
    run's; ``progress`` as run_slam's. ``path`` and ``start_map`` name the log's and the map's
    files in the summary (default: ``log`` and ``initial_map`` when they are paths)."""
    if isinstance(log, (str, os.PathLike)):
        path, log = os.fspath(log) if path is None else path, read_log(os.fspath(log))
    require_instance(log, io.CarmenLog, "log")
    if isinstance(initial_map, (str, os.PathLike)):
        start_map = initial_map if start_map is None else start_map
        if resume is None:  # run_slam refuses a start map with a resumed run
            check_input(os.fspath(initial_map), INITIAL_MAP)
            try:
                initial_map = load_initial_map(initial_map)
            except ValueError as e:  # named as the argument, once
                message = one_line(e)
                raise ValueError(message if message.startswith("initial_map") else f"initial_map: {message}") from None
    if resume is None:
        if options is None:
            options = default_options(log, method or "graph", initial_map=initial_map)
        options = with_fields(options, fields or {})
        result = run_slam(log, options=options, save=save, progress=progress, initial_map=initial_map,
                          initial_pose=initial_pose)
    else:
        result = run_slam(log, resume=resume, save=save, progress=progress, initial_map=initial_map,
                          initial_pose=initial_pose)
    return SlamLogRun(log=log, result=result, path=None if path is None else os.fspath(path),
                      start_map=None if start_map is None else os.fspath(start_map),
                      initial_pose=None if initial_pose is None else tuple(initial_pose),
                      resumed=None if resume is None else os.fspath(resume))


__all__ = ["SlamLogRun", "slam_log"]
