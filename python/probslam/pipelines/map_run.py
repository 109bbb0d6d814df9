"""A laser log with known poses to its occupancy grid (ch. 9.2, or a learned inverse model,
ch. 9.3): read, map, write the map_server files and draw. ``map_log(log, options)`` runs it all;
``MapRun`` runs it step by step for a caller that reports each step (``probslam map``). Options
travel as one ``MapOptions``; every refusal names its field.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import List, Optional, Sequence, Union

from ._options import Options, described
from .. import io
from ..io.laser_log import read_carmen_scans
from .._args import positive_real, require_instance
from ..data import path as data_path
from ..mapping import DEFAULT_MAX_RANGE, DEFAULT_RESOLUTION, MappingResult, map_laser_log

PathLike = Union[str, "os.PathLike[str]"]

#: ``MapOptions(inverse_model="bundled")``: a learned inverse model of the Intel laser
#: (studies/eval_inverse_real.py).
BUNDLED_INVERSE_MODEL = "intel_laser_inverse.npz"
#: Why the ray model's beam options do not apply with a learned inverse model.
LEARNED_MODEL_DECIDES = "the learned model decides what each beam says"


@dataclass
class MapOptions(Options):
    """How ``map_log`` maps a log."""

    resolution: Optional[float] = described(None, "cell size (None: mapping.DEFAULT_RESOLUTION; with "
                                                  "``inverse_model`` the model's own)", "m", type=float)
    max_range: Optional[float] = described(None, "readings at or beyond it only clear space (None: "
                                                 "mapping.DEFAULT_MAX_RANGE; with ``inverse_model`` the model's own)",
                                           "m", type=float)
    robot_radius: float = described(0.0, "clear the robot's footprint (ray model only)", "m")
    skip_no_return: bool = described(True, "drop readings at the sensor maximum (they mean \"nothing seen\"; ray "
                                           "model only)")
    inverse_model: Optional[PathLike] = described(None, "a LearnedInverseModel file (LearnedInverseModel.save), or "
                                                        "'bundled' (the Intel laser's), to map with instead of the ray "
                                                        "model, ch. 9.3 (None: the ray model)", type=str)

    def validate(self) -> None:
        """ValueError / TypeError naming the first field that is wrong or does not apply."""
        for name in ("resolution", "max_range"):
            if getattr(self, name) is not None:
                positive_real(getattr(self, name), name)
        require_instance(self.robot_radius, (int, float), "robot_radius")
        if not (math.isfinite(self.robot_radius) and self.robot_radius >= 0):
            raise ValueError(f"robot_radius must be finite and >= 0, got {self.robot_radius!r}")
        require_instance(self.skip_no_return, bool, "skip_no_return")
        if self.inverse_model is not None:
            require_instance(self.inverse_model, (str, os.PathLike), "inverse_model")
            if self.robot_radius:
                raise ValueError(f"robot_radius does not apply with inverse_model ({LEARNED_MODEL_DECIDES})")
            if not self.skip_no_return:
                raise ValueError(f"skip_no_return does not apply with inverse_model ({LEARNED_MODEL_DECIDES})")


@dataclass
class MapRun:
    """One log's map, step by step: ``prepare`` it (options checked, a learned model loaded),
    ``run`` it, then ``write`` and ``draw``. ``summary`` says what was made, in lines."""

    log: object  # the log read: io.CarmenLog or io.RosbagLog
    options: MapOptions
    path: Optional[str]  # the log's file (for the hint about raw odometry); None: not said
    resolution: float
    max_range: float
    model: object = None  # the LearnedInverseModel, or None for the ray model
    model_path: Optional[str] = None
    mapping: Optional[MappingResult] = None
    started: float = 0.0  # time.perf_counter() when the run began (its log's reading included)

    @classmethod
    def prepare(cls, log: Union[PathLike, object], options: Optional[MapOptions] = None,
                path: Optional[PathLike] = None, read_seconds: float = 0.0) -> "MapRun":
        """A run of ``log`` (a CARMEN log's path, or a log read: ``io.CarmenLog`` / ``io.RosbagLog``;
        ``path`` its file and ``read_seconds`` the time its reading took, counted in the total)
        with ``options``. ValueError for a bag with no poses, naming ``inverse_model`` for a model
        that cannot be read."""
        started = time.perf_counter() - read_seconds
        run = cls._prepare(log, options, path)
        run.started = started
        return run

    @classmethod
    def _prepare(cls, log, options: Optional[MapOptions], path: Optional[PathLike]) -> "MapRun":
        options = MapOptions() if options is None else options
        require_instance(options, MapOptions, "options")
        options.validate()
        if isinstance(log, (str, os.PathLike)):
            path, log = os.fspath(log), read_carmen_scans(log)
        require_instance(log, io.CarmenLog, "log")
        if isinstance(log, io.RosbagLog) and log.pose_source == "none":
            raise ValueError(f"{path or log.path}: no poses to map with (no odometry, tf or pose topic in the bag); "
                             "'probslam slam' maps a bag of scans alone")
        if options.inverse_model is None:
            return cls(log, options, None if path is None else os.fspath(path),
                       _or(options.resolution, DEFAULT_RESOLUTION), _or(options.max_range, DEFAULT_MAX_RANGE))
        from ..inverse_learning import LearnedInverseModel, learned_map_geometry

        model_path = os.fspath(options.inverse_model)
        model_path = data_path(BUNDLED_INVERSE_MODEL) if model_path == "bundled" else model_path
        try:
            model = LearnedInverseModel.load(model_path)
        except (OSError, ValueError, TypeError) as exc:
            raise ValueError(f"inverse_model: {exc}") from None
        # The model's own cell size and range where the options give none: it learned on them,
        # and a finer lattice or longer range costs the network's time on every extra field cell.
        resolution, max_range = learned_map_geometry(model, options.resolution, options.max_range)
        return cls(log, options, None if path is None else os.fspath(path), resolution, max_range, model, model_path)

    def start_summary(self) -> str:
        """With a learned model, a line saying how it maps (it takes longer); "" for the ray model."""
        if self.model is None:
            return ""
        own = [name for name, given, value in (("--resolution", self.options.resolution, self.model.resolution),
                                               ("--max-range", self.options.max_range, self.model.max_range))
               if given is None and value is not None]
        return (f"mapping:       {len(self.log.scans)} scans with the learned inverse model "
                f"{os.path.basename(self.model_path)} at {self.resolution:g} m cells, readings to {self.max_range:g} m"
                + (f" (the model's own {' and '.join(own)})" if own else "") + "; a network on every cell in range "
                "takes longer than the ray model")

    def run(self, progress: Optional[bool] = None) -> MappingResult:
        """Maps the log's scans (``mapping.map_laser_log``, or ``map_laser_log_learned``);
        ``progress=None`` shows a bar only on a terminal."""
        if self.model is None:
            self.mapping = map_laser_log(self.log.scans, resolution=self.resolution, max_range=self.max_range,
                                         robot_radius=self.options.robot_radius,
                                         skip_no_return=self.options.skip_no_return, progress=progress)
        else:
            from ..inverse_learning import map_laser_log_learned

            self.mapping = map_laser_log_learned(self.model, self.log.scans, resolution=self.resolution,
                                                 max_range=self.max_range, progress=progress)
        return self.mapping

    @property
    def grid(self):
        """The map (``OccupancyGrid2D``); None until ``run``."""
        return None if self.mapping is None else self.mapping.grid

    def write(self, prefix: str) -> List[str]:
        """PREFIX.yaml and PREFIX.pgm (map_server's); returns the paths written."""
        io.save_ros_map(self.grid, prefix + ".yaml")
        return [prefix + ".yaml", prefix + ".pgm"]

    def title(self) -> str:
        """The picture's title: the log and what the map is."""
        name = os.path.basename(self.path) if self.path else "a laser log"
        return f"probslam map: {name}\noccupancy grid at the log's poses"

    def draw(self, plt):
        """A figure of the map and the log's laser poses (matplotlib's pyplot given)."""
        from ..plot import occupancy_map_figure

        return occupancy_map_figure(plt, self.grid, self.log.scans.laser_poses, "laser poses (the log's)", self.title())

    def write_plain_picture(self, path: str) -> str:
        """PATH: the picture without matplotlib (``io.write_png``: one pixel a cell)."""
        io.write_png(self.grid, path, trajectory=self.log.scans.laser_poses)
        return path

    def summary(self, name: Optional[str] = None, written: Sequence[str] = (), hint: bool = True) -> str:
        """What was mapped and made, in lines (``name``: how to call the log; default its path),
        the files ``written``, and (``hint``) what the map means when its poses may be raw odometry.
        Its time: the total since the run began (the log's reading included) and the mapping's."""
        m, grid, log = self.mapping, self.grid, self.log
        rate = m.beams / m.seconds / 1e6 if m.seconds > 0 else float("inf")
        total = time.perf_counter() - self.started
        lines = [f"log:           {self.path if name is None else name}"]
        if isinstance(log, io.RosbagLog):
            lines.append(f"bag:           {log.describe()}")
        lines += [f"scans:         {m.scans}"
                  + (f" ({log.skipped_wide_scans} skipped: far wider than the rest)" if log.skipped_wide_scans else "")
                  + (f" ({log.skipped_rows} malformed log lines skipped)"
                     if log.skipped_rows and not isinstance(log, io.RosbagLog) else ""),
                  f"beams:         {m.beams}",
                  f"cells updated: {m.cells_updated}",
                  f"map:           {grid.width} x {grid.height} cells at {grid.resolution} m, origin {grid.origin}",
                  f"time:          {total:.2f} s total, {m.seconds:.3f} s mapping ({rate:.2f} M beams/s)"]
        if written:
            lines.append(f"wrote:         {', '.join(written)}")
        if hint and self.odometry_hint():
            lines.append(f"hint:          {self.odometry_hint()}")
        return "\n".join(lines)

    def odometry_hint(self) -> str:
        """What the map means when its poses may be raw odometry, which smears a map wherever it
        drifts: a bag's odometry or tf are; a CARMEN log's FLASER poses are either (a raw log and
        a corrected one write the same fields, the same way), so the hint is conditional there.
        "" for a bag's pose topic and a log without a path."""
        if self.path is None:
            return ""
        slam = f"'probslam slam {self.path}' corrects them (scan matching, loop closures)"
        if isinstance(self.log, io.RosbagLog):
            if self.log.pose_source.startswith("poses"):
                return ""
            return (f"the poses are the bag's {self.log.pose_source}, raw odometry: the map smears wherever it "
                    f"drifts; {slam}")
        return (f"map draws the log's poses as they are; if they are raw odometry (a log as the robot recorded it, "
                f"not a corrected one), the map smears wherever it drifts, and {slam}")


def _or(value: Optional[float], default: float) -> float:
    return default if value is None else value


def map_log(log: Union[PathLike, object], options: Optional[MapOptions] = None,
            progress: Optional[bool] = None) -> MapRun:
    """Maps ``log`` (a CARMEN log's path, or a log read) with ``options``; the run with its map."""
    run = MapRun.prepare(log, options)
    run.run(progress)
    return run


__all__ = ["BUNDLED_INVERSE_MODEL", "MapOptions", "MapRun", "map_log"]
