"""SLAM from a raw laser log, two ways: incremental scan matching into local submaps and GraphSLAM
over the submaps with correlative loop closures (Thrun et al. ch. 11.7; C++ ``SubmapSlam2D``), or
grid-based FastSLAM, a particle filter whose particles carry their own maps (C++ ``GridFastSlam``).

Units: metres, radians, seconds. Poses are laser poses ``(x, y, theta)`` in the frame of the first
scan's odometry pose.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import struct
import threading
import time
from dataclasses import dataclass
from typing import Any, Dict, Optional, Union

import numpy as np
from tqdm import tqdm

from . import _core
from ._args import require_integer
from .io._files import file_path, require_regular_file
from .io.trajectory import write_trajectory as write_trajectory_file
from .io.carmen import ODOMETRY_NOISE_SIZE, CarmenLog, LaserScans
from .io.laser_log import has_odometry, read_laser_log

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
    timings: processor seconds per stage of the SLAM object (``SubmapSlam2D.timings`` or
    ``GridFastSlam.timings``; a resumed run's count from its loading); memory (GraphSLAM only):
    the bytes its large buffers hold at the end (``SubmapSlam2D.memory``); options the run's
    ``SubmapSlamOptions`` or ``GridFastSlamOptions`` (as the SLAM object ran them).
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
    options: Union[_core.SubmapSlamOptions, _core.GridFastSlamOptions, None] = None
    method: str = "graph"
    tile_sharing: Optional[_core.TileSharing] = None
    timings: Optional[Union[_core.SubmapSlamTimings, _core.GridFastSlamTimings]] = None
    memory: Optional[_core.SubmapSlamMemory] = None

    @property
    def real_time_factor(self) -> float:
        """Log duration over processing time (> 1: faster than the robot recorded it)."""
        return self.log_duration / self.seconds if self.seconds > 0 else float("inf")


#: The methods of ``run_slam``.
METHODS = ("graph", "rbpf")


#: The first bytes of a run file (``run_slam(save=...)``, ``probslam slam --save``), its layout's version.
RUN_MAGIC = b"PSLRUN\0\0"
RUN_FORMAT_VERSION = 2
#: Metadata larger than this is a damaged file, not a run's few fields.
MAX_RUN_METADATA_BYTES = 1 << 20
_RUN_CLASSES = {"graph": "SubmapSlam2D", "rbpf": "GridFastSlam"}
#: Each method's options class.
OPTIONS_CLASSES = {"graph": _core.SubmapSlamOptions, "rbpf": _core.GridFastSlamOptions}
#: run_slam's scans per add_scans call by method (see its ``chunk``).
DEFAULT_CHUNK = {"graph": 200, "rbpf": 1}


@dataclass
class SlamRun:
    """A run file's content: the SLAM object (``SubmapSlam2D`` before its final ``finish``, or
    ``GridFastSlam``), its method, how many scans of the log it has processed (scans_done), the
    timestamps of the log's first scan and of the last processed one (to check that a resumed
    log is the same) and the log's number of scans; ``options`` the run's options object (the
    SLAM object's: its state file holds them)."""

    mapper: Any
    method: str
    scans_done: int
    first_timestamp: float
    last_timestamp: float
    log_scans: int

    @property
    def options(self) -> Union[_core.SubmapSlamOptions, _core.GridFastSlamOptions]:
        """The run's options (a copy of the SLAM object's)."""
        return self.mapper.options


class RunInterrupted(KeyboardInterrupt):
    """``run_slam`` interrupted (Ctrl-C): ``saved`` the run file written (None when nothing was
    saved: no ``save`` or no scan processed), with ``scans_done`` of the log's ``log_scans``."""

    def __init__(self, saved: Optional[str], scans_done: int, log_scans: int) -> None:
        super().__init__("interrupted")
        self.saved, self.scans_done, self.log_scans = saved, scans_done, log_scans


@contextlib.contextmanager
def _interrupts_deferred():
    """Ctrl-C held back until the block ends (then raised as KeyboardInterrupt), so that a save
    is never cut half-way."""
    # Only the main thread receives signals, and a handler installed outside Python cannot be put back.
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is None:
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt


def check_save_path(path: PathLike, arg: str = "save") -> str:
    """The path a run file will be written to, checked before a run that may take minutes:
    ValueError naming ``arg`` for a directory, a missing folder or a place that cannot be written
    (tried by creating and removing the temporary file ``save_run`` writes through)."""
    path = file_path(path, arg)
    if os.path.isdir(path):
        raise ValueError(f"{arg}: {path} is a directory, not a file name")
    folder = os.path.dirname(path) or "."
    if not os.path.isdir(folder):
        raise ValueError(f"{arg}: {path}: folder {folder} does not exist")
    tmp = path + ".tmp"
    try:
        with open(tmp, "xb"):
            pass
        os.remove(tmp)
    except FileExistsError:
        pass  # a temporary left by an older version; save_run overwrites it
    except OSError as e:
        raise ValueError(f"{arg}: cannot write {path} ({e.strerror})") from None
    return path


def save_run(run: SlamRun, path: PathLike) -> None:
    """Writes run to path (docs/file_format.md, "Run files"): the magic, the layout version, the
    metadata as JSON, then the SLAM object's state file, bit for bit. It goes through PATH.tmp,
    renamed over path, and Ctrl-C waits for it: path holds the old run or the new one, whole, and
    no temporary is left (ValueError naming path when it cannot be written)."""
    path = file_path(path, "save")
    if run.mapper.num_scans != run.scans_done:
        raise ValueError(f"save: the object holds {run.mapper.num_scans} scans, the run {run.scans_done}")
    meta = dict(format=RUN_FORMAT_VERSION, method=run.method, scans_done=int(run.scans_done),
                first_timestamp=float(run.first_timestamp), last_timestamp=float(run.last_timestamp),
                log_scans=int(run.log_scans))
    head = json.dumps(meta, allow_nan=True).encode("utf-8")
    tmp = path + ".tmp"
    with _interrupts_deferred():
        state = run.mapper.__getstate__()
        try:
            with open(tmp, "wb") as f:
                f.write(RUN_MAGIC + struct.pack("<II", RUN_FORMAT_VERSION, len(head)) + head + state)
            os.replace(tmp, path)
        except OSError as e:
            with contextlib.suppress(OSError):
                os.remove(tmp)
            raise ValueError(f"save: cannot write {path} ({e.strerror})") from None


def load_run(path: PathLike) -> SlamRun:
    """The run saved at path; ValueError naming the path for anything but a complete, undamaged
    run file (the object's state is checked as its class's ``load`` checks it)."""
    path = file_path(path)
    require_regular_file(path)
    with open(path, "rb") as f:
        data = f.read()
    if not data.startswith(RUN_MAGIC):
        raise ValueError(f"{path}: not a probslam run file (no PSLRUN magic)")
    if len(data) < len(RUN_MAGIC) + 8:
        raise ValueError(f"{path}: truncated run file")
    version, size = struct.unpack_from("<II", data, len(RUN_MAGIC))
    if version != RUN_FORMAT_VERSION:
        raise ValueError(f"{path}: run file version {version} is not supported (this build reads version "
                         f"{RUN_FORMAT_VERSION})")
    start = len(RUN_MAGIC) + 8
    if size > MAX_RUN_METADATA_BYTES or start + size > len(data):
        raise ValueError(f"{path}: truncated or corrupt run metadata")
    try:
        meta = json.loads(data[start:start + size].decode("utf-8"))
        method = meta["method"]
        scans_done = meta["scans_done"]
        first, last, log_scans = float(meta["first_timestamp"]), float(meta["last_timestamp"]), meta["log_scans"]
    except (ValueError, KeyError, TypeError, UnicodeDecodeError, OverflowError) as e:
        raise ValueError(f"{path}: corrupt run metadata ({e})") from None
    except RecursionError:
        raise ValueError(f"{path}: corrupt run metadata (nested too deeply)") from None
    if not isinstance(method, str) or method not in _RUN_CLASSES or not isinstance(scans_done, int) or not isinstance(log_scans, int) \
            or not 1 <= scans_done <= log_scans:
        raise ValueError(f"{path}: corrupt run metadata")
    cls = getattr(_core, _RUN_CLASSES[method])
    mapper = cls.__new__(cls)
    try:
        mapper.__setstate__(data[start + size:])
    except ValueError as e:
        raise ValueError(f"{path}: {str(e).split(': ', 1)[-1]}") from None
    if mapper.num_scans != scans_done:
        raise ValueError(f"{path}: the run's object holds {mapper.num_scans} scans, its metadata {scans_done}")
    return SlamRun(mapper=mapper, method=method, scans_done=scans_done, first_timestamp=first, last_timestamp=last,
                   log_scans=log_scans)


def _check_resume(run: SlamRun, scans: LaserScans, source: str) -> None:
    """ValueError unless scans is the log run was made from (same first scan, the same scan at
    the last processed index)."""
    t = scans.timestamps
    n = run.scans_done
    same = len(scans) >= n and t[0] == run.first_timestamp and t[n - 1] == run.last_timestamp
    ipc = scans.ipc_timestamps
    if not same and len(scans) >= n and ipc[0] == run.first_timestamp and ipc[n - 1] == run.last_timestamp:
        raise ValueError(f"{source}: the run was saved when CARMEN scans were timed by their ipc stamp; they are "
                         "timed by their logger stamp now, and a resumed run would mix the two clocks: run it again")
    if not same:
        got = f"{len(scans)} scans from t={t[0]:.6f}" if len(scans) else "no scans"
        raise ValueError(f"{source}: the saved run processed {n} scans of a log of {run.log_scans} scans from "
                         f"t={run.first_timestamp:.6f} (scan {n - 1} at t={run.last_timestamp:.6f}); this log has "
                         f"{got}: not the log the run was made from")


#: What ``initial_map`` / ``probslam slam --map`` read.
INITIAL_MAP = "a saved map: a map_server .yaml (with its image), as map and slam write, or an OccupancyGrid2D state file"


def load_initial_map(source: Union[PathLike, _core.OccupancyGrid2D]) -> _core.OccupancyGrid2D:
    """The map a run starts from: an ``OccupancyGrid2D``, a map_server ``.yaml`` (with its image;
    ``io.load_ros_map``) or an ``OccupancyGrid2D`` state file (``OccupancyGrid2D.save``).
    FileNotFoundError for a missing file, ValueError for one that is neither."""
    if isinstance(source, _core.OccupancyGrid2D):
        return source
    path = file_path(source, "initial_map")
    if path.lower().endswith((".yaml", ".yml")):
        from .io.maps import load_ros_map

        return load_ros_map(path)
    require_regular_file(path, "initial_map")
    try:
        return _core.OccupancyGrid2D.load(path)
    except ValueError as e:
        raise ValueError(f"initial_map: {e} (expected {INITIAL_MAP})") from None


def scans_of(log: Union[PathLike, CarmenLog, LaserScans]) -> LaserScans:
    """The laser scans of a log given as a path (CARMEN log or ROS bag), a ``CarmenLog`` or its
    ``LaserScans``: TypeError for anything else, ValueError for a log without scans."""
    if isinstance(log, (str, os.PathLike)):
        log = read_laser_log(log)
    scans = log.scans if isinstance(log, CarmenLog) else log
    if not isinstance(scans, LaserScans):
        raise TypeError("log must be a path, a CarmenLog or LaserScans")
    if len(scans) == 0:
        raise ValueError("log has no laser scans")
    return scans


def default_options(log: Union[PathLike, CarmenLog, LaserScans], method: str = "graph", *,
                    initial_map: Optional[_core.OccupancyGrid2D] = None
                    ) -> Union[_core.SubmapSlamOptions, _core.GridFastSlamOptions]:
    """The options ``run_slam`` runs ``method`` with on ``log`` (a CARMEN or ROS bag path, a
    ``CarmenLog`` or its ``LaserScans``): the defaults of ``SubmapSlamOptions`` ("graph") or
    ``GridFastSlamOptions`` ("rbpf") with what the log itself says (the one place the defaults
    depend on the robot): the sensor's range limit (``LaserScans.no_return_range``: readings at it are no
    returns, and hits are used up to it) and whether the log has odometry. Without odometry
    (GraphSLAM only) every scan is matched, each predicted by the last matched motion (constant
    velocity, its spread the odometry model's, in the score as odometry would be once five
    matched motions give a velocity: "no motion" made the path shrink where the scans do not fix
    the motion, issue 51; the Stage-like robot in the simulated office: GraphSLAM 2.95 m ATE and
    the map 29 % small before, 0.23 m and 1.4 %), in a window wide enough for a change of
    velocity between scans. The frontend's match_fraction (the share
    of the range matched) is left at its default, every hit.

    Where the log states how noisy its odometry is (``LaserScans.odometry_noise``: a simulation
    does, and the CARMEN log it writes; a real robot's log or a bag as read today does not), that noise is the odometry model
    (``odometry``, both methods): the match's prior is the odometry's Mahalanobis term with
    its own noise, so that good odometry is kept (the Stage-like robot in the simulated office
    with the truth as odometry: GraphSLAM 1.02 m ATE with the fixed model, 0.005 m with the
    stated one). Otherwise the fixed model, 10 % of the distance (``OdometryNoise``).

    ``initial_map`` (an ``OccupancyGrid2D``, as ``load_initial_map`` gives): the resolution is
    the map's (a run started from it draws on its lattice)."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    scans = scans_of(log)
    options = OPTIONS_CLASSES[method]()
    # GraphSLAM's scan matching settings are its frontend's; GridFastSlam's are its own.
    scan_matching = options.frontend if method == "graph" else options
    no_return = scans.no_return_range()
    if np.isfinite(no_return):
        scan_matching.filter.max_range = no_return
    stated = np.asarray(scans.odometry_noise, dtype=float)
    if stated.shape != (len(scans), ODOMETRY_NOISE_SIZE):
        raise ValueError(f"odometry_noise: LaserScans.odometry_noise must be ({len(scans)}, {ODOMETRY_NOISE_SIZE}) "
                         f"(one statement per scan, NaN where none), got shape {stated.shape}")
    odometry = has_odometry(scans)
    if len(stated) and np.isfinite(stated).all() and odometry:
        # Where the scans state different noises, the loosest: one model serves the whole run.
        names = ("trans_per_metre", "trans_per_radian", "trans_floor", "rot_per_radian", "rot_per_metre", "rot_floor")
        scan_matching.odometry = _core.OdometryNoise(**dict(zip(names, (float(v) for v in stated.max(axis=0)))))
    if method == "graph" and not odometry:
        frontend = options.frontend
        frontend.constant_velocity = True
        frontend.update = _core.UpdateTrigger(distance=0.0, angle=0.0)
        frontend.match.window = _core.SearchWindow(linear=0.5, angular=0.5)
    if initial_map is not None:
        if not isinstance(initial_map, _core.OccupancyGrid2D):
            raise TypeError(f"initial_map: expected an OccupancyGrid2D, got {type(initial_map).__name__}")
        scan_matching.resolution = initial_map.resolution
    options.validate()
    return options


def with_fields(options: Any, values: Dict[str, Any]) -> Any:
    """A validated copy of an options object with each field named by its path set
    (``{"frontend.filter.max_range": 8.0, "num_particles": 50}``): ``options.replace`` with the
    groups' fields nested as dicts. Errors name the path (TypeError, ValueError)."""
    nested: Dict[str, Any] = {}
    for path, value in values.items():
        *groups, name = path.split(".")
        level = nested
        for group in groups:
            level = level.setdefault(group, {})
        level[name] = value
    return options.replace(**nested)


def _beam_angle_rows(scans: LaserScans) -> np.ndarray:
    """The scans' beam angles as add_scans takes them: (B,) shared by every scan when their start
    angle and step are the same (every scan of a log from one laser; the (S, B) matrix would hold
    S copies of it: 10 MB on ACES, 20 MB on Intel), else (S, B), a row per scan."""
    if len(scans) > 0 and (np.all(scans.start_angles == scans.start_angles[0])
                           and np.all(scans.angular_resolutions == scans.angular_resolutions[0])):
        beams = np.arange(scans.ranges.shape[1], dtype=float)
        return scans.start_angles[0] + scans.angular_resolutions[0] * beams
    return scans.beam_angles()


def run_slam(log: Union[PathLike, CarmenLog, LaserScans], *, method: Optional[str] = None,
             progress: Optional[bool] = None, chunk: Optional[int] = None, resume: Optional[PathLike] = None,
             save: Optional[PathLike] = None, initial_map: Optional[Union[PathLike, _core.OccupancyGrid2D]] = None,
             initial_pose: Optional[Any] = None,
             options: Union[_core.SubmapSlamOptions, _core.GridFastSlamOptions, None] = None) -> SlamResult:
    """Turns a raw log (a CARMEN or ROS bag path, a ``CarmenLog`` such as ``io.read_rosbag``'s, or
    its ``LaserScans``) into a consistent map.

    ``method="graph"`` (default): GraphSLAM over submaps (``SubmapSlam2D``), ``options`` a
    ``SubmapSlamOptions``. ``method="rbpf"``: grid-based FastSLAM (``GridFastSlam``), ``options``
    a ``GridFastSlamOptions``; it needs odometry. ``method=None`` is the one ``options`` is for
    ("graph" without options). ``options=None`` takes ``default_options(log, method)`` (the
    defaults with the log's no-return reading, stated odometry noise, and for a log without
    odometry scan matching alone, every scan matched and predicted by the last matched motion);
    given options are used as they are (start from ``default_options`` to keep what the log says).
    Options of the other method's class: TypeError naming ``options``.

    ``progress=None`` shows a bar only on a terminal.

    ``chunk``: scans per ``add_scans`` call (all or nothing each). None: 200 for "graph"; 1 for
    "rbpf", whose batch snapshot holds the particles' tiles, the corrector's open grid and field
    of the batch's start alive until it ends (about 100 MB more at the peak on Intel; a single
    scan is all or nothing without one). The result is the same for every chunk.

    ``save``: a path; the run's state (the SLAM object before GraphSLAM's final ``finish``, the
    number of scans processed, see ``save_run``) is written there at the end, or when the run is
    interrupted (KeyboardInterrupt: the scans of the chunks completed so far). ``resume``: a run
    file; the run continues with the log's next scan, with the saved object and its options
    (``options`` must then be None; ``method`` defaults to the saved one). A resumed run gives
    the uninterrupted run's result bit for bit.

    ``initial_map``: start from a saved map (``load_initial_map``: an ``OccupancyGrid2D``, a
    map_server ``.yaml`` or a grid state file); the run's frame is the map's, and the log's
    first scan is matched against the map around ``initial_pose`` (x, y, theta in the map's
    frame, default (0, 0, 0); a guess within the scan matcher's window, 0.3 m and 0.35 rad by
    default). ``method="graph"``: the map is the graph's first submap, its node fixed at the
    map's origin; the scans of the first ``submap_distance`` of travel are matched against and
    drawn into it, and later loop closures search it whole. ``method="rbpf"``: every particle's
    map starts as the saved map (its tiles shared) with the first scan drawn in. Either way the
    result's grid is the saved map with the log drawn in, on its lattice; the default options'
    resolution is the map's. ``SubmapSlam2D.start_from_map`` / ``GridFastSlam.start_from_map`` say
    what is refused. A saved run (``save``) holds the map; ``resume`` takes neither argument.
    """
    if initial_pose is not None and initial_map is None:
        raise ValueError("initial_pose: only with initial_map (where the log starts in the saved map)")
    if initial_map is not None:
        if resume is not None:
            raise ValueError("initial_map: a resumed run continues on the map its run file holds")
        initial_map = load_initial_map(initial_map)
    run: Optional[SlamRun] = None
    if resume is not None:
        run = load_run(resume)
        if method is not None and method != run.method:
            raise ValueError(f"resume: {file_path(resume)} holds a {run.method!r} run, not {method!r}")
        if options is not None:
            raise ValueError("options: a resumed run keeps its saved options")
        method = run.method
    if save is not None:
        save = check_save_path(save)
    if method is None:
        method = next((m for m, cls in OPTIONS_CLASSES.items() if isinstance(options, cls)), "graph")
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if options is not None and not isinstance(options, OPTIONS_CLASSES[method]):
        raise TypeError(f"options: expected a {OPTIONS_CLASSES[method].__name__} for method {method!r}, "
                        f"got {type(options).__name__}")
    scans = scans_of(log)
    chunk = require_integer(DEFAULT_CHUNK[method] if chunk is None else chunk, "chunk", lowest=1)
    odometry = has_odometry(scans)
    if not odometry and method == "rbpf":
        raise ValueError("log has no odometry (its laser poses never move): method 'rbpf' samples the "
                         "odometry motion model; use method 'graph', which runs on scan matching alone")
    start = 0
    if run is not None:
        _check_resume(run, scans, str(file_path(resume)))
        mapper, start = run.mapper, run.scans_done
    else:
        if options is None:
            options = default_options(scans, method, initial_map=initial_map)
        mapper = getattr(_core, _RUN_CLASSES[method])(options=options)
        if initial_map is not None:
            mapper.start_from_map(initial_map, (0.0, 0.0, 0.0) if initial_pose is None else initial_pose)
    angles = _beam_angle_rows(scans)
    t0 = time.perf_counter()

    written = [-1]  # the scans of the file last written

    def save_state() -> Optional[str]:
        # The object is the count: add_scans is all or nothing, and a Ctrl-C that arrives while it
        # runs is raised when it returns, before the loop could count its scans.
        done = mapper.num_scans
        if save is None or done == 0:
            return None
        if done == written[0]:
            return save
        with _interrupts_deferred():  # a KeyboardInterrupt out of here comes after the file is written
            save_run(SlamRun(mapper=mapper, method=method, scans_done=done, first_timestamp=float(scans.timestamps[0]),
                             last_timestamp=float(scans.timestamps[done - 1]), log_scans=len(scans)),
                     save)
            written[0] = done
        return save

    # As map_laser_log: disable=None lets tqdm show the bar only on a terminal.
    try:
        with tqdm(total=len(scans), initial=start, unit="scan", desc=method,
                  disable=(None if progress is None else not progress)) as bar:
            for a in range(start, len(scans), chunk):
                b = min(len(scans), a + chunk)
                mapper.add_scans(scans.ranges[a:b], angles if angles.ndim == 1 else angles[a:b],
                                 scans.laser_poses[a:b], scans.timestamps[a:b])
                bar.update(b - a)
        save_state()
    except KeyboardInterrupt:
        try:
            saved = save_state()
        except KeyboardInterrupt:  # Ctrl-C again, held back until the file was written
            saved = save if save is not None and mapper.num_scans > 0 else None
        raise RunInterrupted(saved, mapper.num_scans, len(scans)) from None
    t = scans.timestamps
    duration = float(np.nanmax(t) - np.nanmin(t)) if np.isfinite(t).any() else 0.0
    if method == "rbpf":
        grid = mapper.map()
        seconds = time.perf_counter() - t0
        return SlamResult(timestamps=mapper.timestamps, poses=mapper.scan_poses, frontend_poses=None,
                          submap_poses=None, grid=grid, graph=None, constraints=None, summary=mapper.summary,
                          seconds=seconds, log_duration=duration, odometry=odometry, options=mapper.options,
                          method=method, tile_sharing=mapper.tile_sharing, timings=mapper.timings)
    frontend = mapper.frontend_poses
    mapper.finish()
    grid = mapper.map()
    seconds = time.perf_counter() - t0
    return SlamResult(timestamps=mapper.timestamps, poses=mapper.scan_poses, frontend_poses=frontend,
                      submap_poses=mapper.submap_poses, grid=grid, graph=mapper.graph(),
                      constraints=mapper.constraints, summary=mapper.summary, seconds=seconds, log_duration=duration,
                      odometry=odometry, options=mapper.options, method=method, timings=mapper.timings,
                      memory=mapper.memory)


def write_trajectory(timestamps: np.ndarray, poses: np.ndarray, path: PathLike) -> None:
    """One line per pose: ``timestamp x y theta`` (s, m, m, rad) after a ``#`` header, the layout
    ``probslam`` commands wrote before TUM (``io.write_trajectory(..., format="xyt")``, which this
    calls; TUM and KITTI are there too). timestamps (N,), poses (N, 3), finite (TypeError /
    ValueError naming them); the trajectory first and the path last, as every writer."""
    write_trajectory_file(timestamps, poses, path, format="xyt")


__all__ = ["DEFAULT_CHUNK", "INITIAL_MAP", "METHODS", "OPTIONS_CLASSES", "RunInterrupted", "SlamResult", "SlamRun", "check_save_path", "default_options",
           "load_initial_map", "load_run", "run_slam", "save_run",
           "scans_of", "with_fields", "write_trajectory"]
