"""The ``probslam`` command line."""

from __future__ import annotations

import argparse
import contextlib
import difflib
import math
import os
import re
import shlex
import stat
import sys
import time
import warnings
from typing import Dict, Iterator, List, Optional, Tuple

from . import __version__, io
from .data import path as _data_path
from .datasets import carmen, mrclam
from ._core import MonteCarloLocalizationOptions
from .pipelines.landmark_run import ASSOCIATIONS, LandmarkRun, LandmarkRunOptions
from .pipelines.optimize_file import INITIALIZATIONS, NOISE_CONVENTIONS, GraphFileOptions
from .io.trajectory import TRAJECTORY_FORMATS
from .localization import default_options
from .mapping import DEFAULT_MAX_RANGE as MAP_MAX_RANGE, DEFAULT_RESOLUTION as MAP_RESOLUTION
from .pipelines.localize_log import localize_log
from .pipelines.map_log import MapOptions, MapRun
from .pipelines.evaluate_trajectory import REFERENCE_FORMATS, EvaluationOptions, TrajectoryEvaluation
from ._progress import progress_bar

BUNDLED_LOG = "intel_excerpt.log.gz"
#: A raw log (odometry and scans, no corrected poses): the Intel Research Lab's first loop, short of
#: its start (``probslam localize``'s default, in its map BUNDLED_LOCALIZATION_MAP).
BUNDLED_RAW_LOG = "intel_raw_loop.log.gz"
#: ``probslam slam``'s default: the Intel Research Lab's first lap, which comes back past its start,
#: so that the first run shows loop closures.
BUNDLED_SLAM_LOG = "intel_raw_lap.log.gz"
#: The default of ``probslam optimize``: the first 400 poses of the Intel Research Lab graph.
BUNDLED_GRAPH = "intel_400.g2o"
#: The default of ``probslam ekf-slam`` / ``fastslam``: MRCLAM Dataset 7, robot 1, 120 s.
BUNDLED_LANDMARKS = "mrclam7_robot1_120s"
#: ``probslam localize`` without a LOG: the bundled raw loop in its map made by ``probslam slam``.
BUNDLED_LOCALIZATION_MAP = "intel_raw_loop_map.yaml"

#: The --particles defaults. They differ because the particles do: a particle of grid-based
#: FastSLAM (``slam --method rbpf``) carries a grid map, and 30 meet the ACES target (0.047 m;
#: 100 cost 3.5-4x the time and memory for the same relations error), while a landmark
#: FastSLAM particle (``fastslam``) holds a few landmarks and 100 cost seconds.
RBPF_PARTICLES = 30
#: slam's cell size (m) without --resolution or --map.
DEFAULT_RESOLUTION = 0.05
FASTSLAM_PARTICLES = LandmarkRunOptions.num_particles

#: What each kind of input file must be, for the error messages.
CARMEN_LOG = "a CARMEN laser log (.log/.clf, optionally .gz/.bz2/.xz)"
ROS_BAG = "a ROS bag (ROS 1 .bag, a ROS 2 bag folder, or its .db3 / .mcap)"
LANDMARK_DATASET = ("a UTIAS MRCLAM folder (Barcodes.dat, Landmark_Groundtruth.dat, RobotN_Odometry.dat, "
                    "RobotN_Measurement.dat) or a Victoria Park file in iSAM/GTSAM text format")
POSE_GRAPH = "a 2-D pose graph: g2o (VERTEX_SE2/EDGE_SE2), TORO .graph (VERTEX2/EDGE2) or iSAM text"
POSE_GRAPH_3D = ("a 3-D pose graph: g2o (VERTEX_SE3:QUAT/EDGE_SE3:QUAT), iSAM/GTSAM text (EDGE3) or TORO 3-D "
                 "(VERTEX3/EDGE3)")
ANY_POSE_GRAPH = "a 2-D or 3-D pose graph (g2o, TORO or iSAM text)"
EPILOG = """exit status:
  0  success
  1  an unexpected error (a bug: please report it)
  2  a user or input error: a bad option, a missing, empty or unreadable file, an output folder
     that does not exist or cannot be written (one line on stderr)
  3  optimize did not converge within --max-iterations, or localize's estimate never converged
     (the result is written all the same)
  130  interrupted (Ctrl-C); optimize writes the graph of its last completed iteration first
  141  the output's reader stopped (probslam ... | head -1), nothing said, as other tools

Without a dataset argument every command runs on small excerpts of public datasets bundled with
the package (probslam.data.path(NAME) gives their paths). Plots need matplotlib (optional: pip
install 'probslam[plot]'); without it they are skipped with a notice."""


class UserError(Exception):
    """An input or usage error: printed as one line on stderr, exit status 2."""


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Every option that takes a value shows its default: " (default: X)" after its help (X
    "none" for an option that is off unless given), unless the help says it already (the word
    "default")."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if (not action.option_strings or action.nargs == 0 or action.default is argparse.SUPPRESS
                or "default" in text.lower()):
            return text
        return text + (" (default: none)" if action.default is None else " (default: %(default)s)")


#: How close a misspelt option or choice must be to one of the parser's to be suggested
#: (difflib's ratio: 0.6, its own default, takes --partcles for --particles, not --seed for --robot).
SUGGESTION_CUTOFF = 0.6


class _Parser(argparse.ArgumentParser):
    """argparse with its usage errors as one line on stderr (exit status 2, as argparse's own),
    like every other user error, naming the subcommand's -h and suggesting the option or choice
    meant when one is close; ``-h`` still shows the usage, every option with its default."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        choice = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if choice:
            message += _did_you_mean(choice.group(1), re.findall(r"'([^']*)'", choice.group(2)))
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} -h')\n")

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but an unknown option is reported by the subcommand's parser (whose
        -h lists the options), with the nearest of its options when one is close."""
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            parser = self._command_parser(parsed)
            options = [o for p in (parser, self) for a in p._actions for o in a.option_strings]
            unknown = next((word.split("=", 1)[0] for word in extras if word.startswith("-")), "")
            parser.error(f"unrecognized arguments: {' '.join(extras)}"
                         + (_did_you_mean(unknown, options) if unknown else ""))
        return parsed

    def _command_parser(self, parsed: argparse.Namespace) -> argparse.ArgumentParser:
        """The parser of the subcommand in ``parsed`` (this one without)."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                return action.choices.get(getattr(parsed, action.dest, None), self)
        return self


def _did_you_mean(word: str, candidates: List[str]) -> str:
    close = difflib.get_close_matches(word, candidates, n=1, cutoff=SUGGESTION_CUTOFF)
    return f"; did you mean {close[0]}?" if close else ""


def _bundled_log(name: str = BUNDLED_LOG) -> str:
    return _data_path(name)


def _one_line(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


#: localize's flags, by the MonteCarloLocalizationOptions field each sets; then the run's other
#: arguments the library's messages may name.
LOCALIZE_FLAGS = {"sensor_model": "--sensor-model", "min_particles": "--min-particles",
                  "max_particles": "--max-particles", "max_range": "--max-range", "seed": "--seed",
                  "threads": "--threads"}
LOCALIZE_ARGUMENTS = {**LOCALIZE_FLAGS, "initial_pose": "--initial-pose", "map": "--map"}


def _as_given(text: str, names: Dict[str, str], args: Optional[argparse.Namespace] = None) -> Tuple[str, bool]:
    """A library message told as the command line gave it, and whether it named anything: its
    subject (a leading name of ``names``, the library's parameter or option field) becomes what the
    command line calls it, with the value given (from ``args``) unless the message says it already
    ("min_particles must ..." -> "--min-particles 0: must ..."); the other names it mentions become
    theirs where they cannot be prose (an identifier with an underscore: "4 worker threads" stays)."""
    pattern = r"(?<![-\w.])(" + "|".join(sorted(map(re.escape, names), key=len, reverse=True)) + r")\b(?![.])"
    subject = re.match(pattern, text)
    rest = text[subject.end():] if subject else text
    mentioned = [m.group(1) for m in re.finditer(pattern, rest) if "_" in m.group(1)]
    rest = re.sub(pattern, lambda m: names[m.group(1)] if m.group(1) in mentioned else m.group(1), rest)
    if not subject:
        return rest, bool(mentioned)
    name, colon = subject.group(1), ":" if rest.startswith(":") else ""
    rest = rest.lstrip(": ")
    # The value given: the flag's dest, named as the option (min_particles) or as the flag
    # (frontend.resolution is --resolution's).
    given = None if args is None else getattr(args, name, getattr(args, names[name].lstrip("-").replace("-", "_"), None))
    if isinstance(given, (list, tuple)):
        given = " ".join(map(str, given))
    if given is None or isinstance(given, bool) or rest.startswith(f"{given} ") or f"got {given}" in rest:
        return f"{names[name]}{colon} {rest}", True  # no value to add, or the message says it
    return f"{names[name]} {given}: {rest}", True


@contextlib.contextmanager
def _option_flags(flags: Dict[str, str], args: argparse.Namespace) -> Iterator[None]:
    """The library's errors about an option, told as the flag that set it with its value
    (``_as_given``): the library checks the values; the CLI does not check them again."""
    try:
        yield
    except (TypeError, ValueError) as exc:
        text, named = _as_given(_one_line(exc), flags, args)
        if named:
            raise UserError(text) from None
        raise


def _options(options, flags: Dict[str, str], args: argparse.Namespace):
    """``options.replace`` with the field each flag of ``flags`` sets (a flag not given, None,
    leaves the options' own), the library's refusals told as the flags."""
    with _option_flags(flags, args):
        return options.replace(**{name: getattr(args, name) for name in flags if getattr(args, name) is not None})


def _check_input(path: str, expected: str, folder: bool = False) -> None:
    """UserError naming ``path`` when it is missing, empty, or not a regular file (or a folder,
    with ``folder``)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise UserError(f"{path}: no such file; expected {expected}") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read it ({exc.strerror}); expected {expected}") from None
    if stat.S_ISDIR(mode):
        if not folder:
            raise UserError(f"{path}: is a directory; expected {expected}")
        return
    if not stat.S_ISREG(mode):
        raise UserError(f"{path}: not a regular file; expected {expected}")
    if os.path.getsize(path) == 0:
        raise UserError(f"{path}: empty file; expected {expected}")


@contextlib.contextmanager
def _reading(path: str, expected: str, names: Optional[Dict[str, str]] = None) -> Iterator[None]:
    """Turn a reader's error into a UserError that names ``path`` and what was expected.
    ``names``: what the command line calls the library parameters that an error may name
    (``scan_topic`` -> ``--scan-topic``, ``times_est`` -> the estimate's file): such an error is
    about that option or file, not about the file's format, so it says so without the
    "expected ..." tail."""
    try:
        yield
    except UserError:
        raise
    except (ValueError, OSError, EOFError, UnicodeError, IndexError) as exc:
        message, named = _as_given(_one_line(exc), names) if names else (_one_line(exc), False)
        if path not in message:
            message = f"{path}: {message}"
        raise UserError(message if named else f"{message}; expected {expected}") from None


def _pyplot():
    """matplotlib.pyplot, or None after a one-line notice on stderr when it is not installed."""
    from .plot import require_matplotlib

    try:
        return require_matplotlib()
    except ImportError:
        print("probslam: plot skipped: matplotlib is not installed (pip install 'probslam[plot]')",
              file=sys.stderr)
        return None


def _save_figure(plt, fig, path: str) -> str:
    """Writes `fig` to `path` (120 dpi) and closes it; returns the path. The bounding box is
    fitted to what is drawn, a legend beside the axes included."""
    fig.tight_layout()
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def _picture(run, path: str, **draw) -> str:
    """PATH.png drawn by a pipeline's run (``run.draw(plt, **draw)``); without matplotlib its plain
    picture (``run.write_plain_picture``), after a notice. Returns the path."""
    plt = _pyplot()
    if plt is None:
        return run.write_plain_picture(path)
    return _save_figure(plt, run.draw(plt, **draw), path)


def _read_log(path: str, args: Optional[argparse.Namespace] = None):
    """The CARMEN log or ROS bag at ``path`` (a bag with the topic and offset options of
    ``args``); UserError naming the file, or the option given for a CARMEN log."""
    bag_options = _bag_options(args)
    if io.rosbag.is_bag(path):
        _check_input(path, ROS_BAG, folder=True)
        with _reading(path, ROS_BAG, {name: _bag_option_name(name) for name in BAG_OPTIONS}):
            return io.read_rosbag(path, **bag_options)
    if bag_options:
        raise UserError(f"{_bag_option_name(next(iter(bag_options)))} applies to ROS bags; {path} is read as "
                        f"{CARMEN_LOG}")
    _check_input(path, CARMEN_LOG)
    with _reading(path, CARMEN_LOG):
        return carmen.load(path)


#: read_rosbag's parameters that the command line sets, each by the option of its name.
BAG_OPTIONS = ("scan_topic", "odom_topic", "pose_topic", "laser_offset")


def _bag_option_name(name: str) -> str:
    return "--" + name.replace("_", "-")


def _bag_options(args: Optional[argparse.Namespace]) -> dict:
    """The read_rosbag options given on the command line (topics, --laser-offset), checked."""
    if args is None:
        return {}
    options = {name: getattr(args, name, None) for name in BAG_OPTIONS}
    options = {name: value for name, value in options.items() if value is not None}
    if "laser_offset" in options and not all(math.isfinite(v) for v in options["laser_offset"]):
        raise UserError(f"--laser-offset must be three finite numbers X Y THETA (m, m, rad), "
                        f"got {' '.join(map(str, options['laser_offset']))}")
    return options


#: The exit status of a run that finished but did not converge (optimize).
EXIT_NOT_CONVERGED = 3
#: The exit status after Ctrl-C (128 + SIGINT, as shells report it).
EXIT_INTERRUPTED = 130
#: The exit status when the reader of the output pipe stopped (128 + SIGPIPE, as a tool killed by
#: it has).
EXIT_BROKEN_PIPE = 141


def _check_output(prefix: str) -> None:
    """UserError naming -o when the output prefix's folder is missing or not writable: checked
    before the run, which may take minutes, rather than when the first file is written."""
    folder = os.path.dirname(prefix) or "."
    if not os.path.isdir(folder):
        raise UserError(f"-o {prefix}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UserError(f"-o {prefix}: folder {folder} is not writable")


#: map's flags, by the MapOptions field each sets.
MAP_FLAGS = {"resolution": "--resolution", "max_range": "--max-range", "robot_radius": "--robot-radius",
             "skip_no_return": "--keep-no-return", "inverse_model": "--inverse-model"}


def _cmd_map(args: argparse.Namespace) -> int:
    options = _options(MapOptions(), MAP_FLAGS, args)
    _check_output(args.output)
    path, t0 = args.log or _bundled_log(), time.perf_counter()
    log = _read_log(path, args)
    with _option_flags(MAP_FLAGS, args):
        run = MapRun.prepare(log, options, path, read_seconds=time.perf_counter() - t0)
        if run.start_summary():
            print(run.start_summary(), flush=True)
        run.run(_progress(args))
    written = run.write(args.output)
    if args.plot:
        written.append(_picture(run, args.output + ".png"))
    print(run.summary(path + ("" if args.log else " (bundled Intel Research Lab excerpt)"), written,
                      hint=args.log is not None))
    return 0


def _resume_command(args: argparse.Namespace, run_file: str) -> str:
    """The slam command that continues an interrupted run from run_file: the same log and
    outputs (the saved run keeps its method and options)."""
    words = ["probslam", "slam"] + ([args.log] if args.log else [])
    for flag, value in (("--scan-topic", args.scan_topic), ("--odom-topic", args.odom_topic),
                        ("--trajectory-format", None if args.trajectory_format == "tum" else args.trajectory_format),
                        ("-o", None if args.output == "slam" else args.output)):
        if value is not None:
            words += [flag, value]
    if args.laser_offset is not None:
        words += ["--laser-offset"] + [repr(float(v)) for v in args.laser_offset]
    words += ["--resume", run_file, "--save", run_file] + ([] if args.plot else ["--no-plot"])
    return shlex.join(words)


def _cmd_slam(args: argparse.Namespace) -> int:
    from .pipelines.slam_log import slam_log
    from .slam import (INITIAL_MAP, OPTIONS_CLASSES, RunInterrupted, check_save_path, default_options,
                       load_initial_map, with_fields)

    if args.resume is not None:
        _refuse_given(args, ("method", "particles", "proposal", "submap_distance", "no_loop_closures", "resolution",
                             "max_range", "seed", "threads"),
                      "does not apply with --resume (the run goes on with its saved options)")
    _refuse_given(args, ("particles", "proposal", "seed", "threads") if args.method == "graph"
                  else ("submap_distance", "no_loop_closures"), f"does not apply to --method {args.method}")
    flags = SLAM_FLAGS[args.method]
    given = {path: getattr(args, flag[2:].replace("-", "_")) for path, flag in flags.items()
             if flag in getattr(args, "given", {}).values()}
    with _option_flags(flags, args):
        with_fields(OPTIONS_CLASSES[args.method](), given)  # the library checks the flags before the log is read
    _check_output(args.output)
    path = args.log or _bundled_log(BUNDLED_SLAM_LOG)
    log = _read_log(path, args)
    start = {}
    if args.map is not None:
        if args.resume is not None:
            raise UserError("--map: a resumed run continues on the map its run file holds")
        _check_input(args.map, INITIAL_MAP)
        try:
            start = dict(initial_map=load_initial_map(args.map), initial_pose=args.initial_pose)
        except ValueError as e:
            raise UserError(f"--map: {_one_line(e)}") from None
    elif args.initial_pose is not None:
        raise UserError("--initial-pose: only with --map (where the log starts in the saved map)")
    if args.save is not None:
        try:
            check_save_path(args.save, "--save")
        except ValueError as e:
            raise UserError(str(e)) from None
    try:
        with _option_flags(flags, args):
            # The log's options, each flag given replacing the field it names; a resumed run keeps its own.
            options = None if args.resume is not None else with_fields(
                default_options(log, args.method, initial_map=start.get("initial_map")), given)
            run = slam_log(log, options, path=path, start_map=args.map, resume=args.resume, save=args.save,
                           progress=None if args.progress else False, **start)
    except RunInterrupted as e:
        if e.saved is None:
            raise
        print(f"probslam: interrupted after {e.scans_done} of {e.log_scans} scans; run file {e.saved} written; "
              f"to continue: {_resume_command(args, e.saved)}", file=sys.stderr)
        return EXIT_INTERRUPTED
    written = run.write(args.output, args.trajectory_format)
    if args.plot:
        written.insert(2, _picture(run, args.output + ".png"))
    if args.save is not None:
        written.append(args.save)
    bundled = "" if args.log else " (bundled Intel Research Lab raw excerpt: one lap, back past its start)"
    print(run.summary(path + bundled, written))
    return 0


#: What ``localize --map`` reads.
MAP_FILE = "a map_server map (YAML with its image)"


def _cmd_localize(args: argparse.Namespace) -> int:
    if args.initial_pose is not None and args.global_:
        raise UserError("--initial-pose and --global exclude each other")
    bundled = args.log is None and args.map is None
    if args.initial_pose is None and not args.global_ and not bundled:
        raise UserError("say where the robot starts: --initial-pose X Y THETA, or --global (anywhere in free space)")
    _check_output(args.output)
    if bundled:  # global localization, what MCL can do that a tracker cannot
        args.log, args.map = _data_path(BUNDLED_RAW_LOG), _data_path(BUNDLED_LOCALIZATION_MAP)
        print("probslam localize: no LOG given: the bundled raw Intel loop in its bundled map, from a global start "
              "(particles anywhere in free space); give LOG --map MAP.yaml for your own", flush=True)
    elif args.map is None:
        raise UserError("--map: give the map to localize in (a map_server YAML, e.g. probslam slam's PREFIX.yaml)")
    elif args.log is None:
        raise UserError("--map given without a LOG: name the log to localize")
    _check_input(args.map, MAP_FILE)
    with _reading(args.map, MAP_FILE):
        grid = io.load_ros_map(args.map)
    log = _read_log(args.log, args)
    options = _options(default_options(log.scans), LOCALIZE_FLAGS, args)
    with _option_flags(LOCALIZE_ARGUMENTS, args):
        run = localize_log(log, grid, options, initial_pose=args.initial_pose, progress=_progress(args))
    written = run.write(args.output, args.trajectory_format)
    if args.plot:
        title = f"probslam localize: {os.path.basename(args.log)} in {os.path.basename(args.map)}"
        written.append(_picture(run, args.output + ".png", title=title))
    print(run.summary(args.log, args.map, written))
    return 0 if run.converged else EXIT_NOT_CONVERGED


#: ekf-slam's and fastslam's flags, by the LandmarkRunOptions field each sets.
LANDMARK_FLAGS = {"unknown": "--unknown", "association": "--association", "bearing_offset": "--bearing-offset",
                  "num_particles": "--particles", "version": "--variant", "seed": "--seed", "threads": "--threads",
                  "robot": "--robot", "seconds": "--seconds", "raw_ranges": "--raw-ranges", "sigma_v": "--sigma-v",
                  "sigma_w": "--sigma-w", "sigma_r": "--sigma-r", "sigma_phi": "--sigma-phi", "refine": "--refine"}


def _cmd_landmarks(args: argparse.Namespace) -> int:
    """ekf-slam and fastslam: ``pipelines.LandmarkRun`` on the dataset argument."""
    with _option_flags(LANDMARK_FLAGS, args):
        options = LandmarkRunOptions(method=args.method, **{k: getattr(args, k) for k in LANDMARK_FLAGS if k in args})
        options.validate()
    _check_output(args.output)
    t0 = time.perf_counter()
    path = args.dataset or _data_path(BUNDLED_LANDMARKS)
    _check_input(path, LANDMARK_DATASET, folder=True)
    with _reading(path, LANDMARK_DATASET), _option_flags(LANDMARK_FLAGS, args):
        run = LandmarkRun.read(path, options)
    with _option_flags(LANDMARK_FLAGS, args):
        run.run(_progress(args))
    print(run.summary())
    written = run.write(args.output, args.trajectory_format)
    plt = _pyplot() if args.plot else None
    if plt is not None:
        written.insert(0, _save_figure(plt, run.draw(plt), args.output + ".png"))
    print(f"time:          {time.perf_counter() - t0:.2f} s total")
    print(f"wrote:         {', '.join(written)}")
    return 0


#: The largest count an int option may take: the library's counts are C ints.
MAX_INT_OPTION = 2 ** 31 - 1


def _require_count(value: int, option: str, lowest: int, highest: int = MAX_INT_OPTION) -> None:
    """UserError naming the option unless lowest <= value <= highest (argparse has made it an
    int; beyond 32 bits the bindings would answer with their whole signature)."""
    if not lowest <= value <= highest:
        raise UserError(f"{option} must be an integer in [{lowest}, {highest}], got {value}")




def _require_length(value: Optional[float], option: str, zero: bool = False, what: str = "number") -> None:
    """UserError naming the option unless value (metres, seconds, radians; None: not given) is
    finite and > 0 (>= 0 with ``zero``): checked before any data is read."""
    if value is not None and not (math.isfinite(value) and (value >= 0 if zero else value > 0)):
        raise UserError(f"{option} must be a finite {what} {'>= 0' if zero else '> 0'}, got {value}")


#: slam's flags, by method: the option path each sets in SubmapSlamOptions / GridFastSlamOptions
#: (the library's messages, which name the path, told as the flag). A flag's value is its dest's
#: (--no-loop-closures stores False).
SLAM_FLAGS = {
    "graph": {"frontend.resolution": "--resolution", "frontend.filter.max_range": "--max-range",
              "frontend.submap_distance": "--submap-distance", "closures.enabled": "--no-loop-closures"},
    "rbpf": {"num_particles": "--particles", "proposal": "--proposal", "seed": "--seed", "threads": "--threads",
             "resolution": "--resolution", "filter.max_range": "--max-range"},
}


#: optimize's flags, by the GraphFileOptions field each sets.
OPTIMIZE_FLAGS = {"format": "--format", "noise": "--noise", "init": "--init", "poses_per_step": "--poses-per-step",
                  "algorithm": "--algorithm", "max_iterations": "--max-iterations", "kernel": "--kernel",
                  "kernel_width": "--kernel-width", "linear_solver": "--linear-solver", "ordering": "--ordering",
                  "trajectory_format": "--trajectory-format"}


def _cmd_optimize(args: argparse.Namespace) -> int:
    from .pipelines.optimize_file import GraphFileOptions, GraphFileRun

    if not args.plot:
        _refuse_given(args, ("edges",), "draws in the picture, which --no-plot leaves out")
    fields = {name: getattr(args, name) for name in OPTIMIZE_FLAGS if name != "trajectory_format"}
    with _option_flags(OPTIMIZE_FLAGS, args):
        options = GraphFileOptions().replace(**fields)
    _check_output(args.output)
    path = args.graph or _data_path(BUNDLED_GRAPH)
    _check_input(path, ANY_POSE_GRAPH)
    with _reading(path, ANY_POSE_GRAPH), _option_flags(OPTIMIZE_FLAGS, args):
        run = GraphFileRun.read(path, options)
        if run.dimension == 3 and args.trajectory_format == "xyt":
            raise ValueError("trajectory_format: 'xyt' ('t x y theta') cannot hold a 3-D pose: use tum or kitti")
    print(run.read_summary(path + ("" if args.graph else " (bundled Intel Research Lab excerpt)")))
    run.start()
    if run.start_summary():
        print(run.start_summary())
    with progress_bar(options.max_iterations, "optimize", "it", _progress(args)) as bar:
        def on_iteration(iteration: int, chi2: float) -> bool:
            bar.set_postfix_str(f"chi2 {chi2:.6g}", refresh=False)
            bar.update(1)
            return True

        run.optimize(on_iteration)
    print(run.optimize_summary())
    written = run.write(args.output, args.trajectory_format)
    plt = _pyplot() if args.plot else None
    if plt is not None:
        written.append(_save_figure(plt, run.draw(plt, edges=args.edges), args.output + ".png"))
    print(f"wrote:      {', '.join(written)}")
    if run.interrupted:
        print("probslam: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return 0 if run.converged else EXIT_NOT_CONVERGED


#: What ``probslam eval`` reads.
TRAJECTORY_FILE = "a trajectory: TUM (t x y z qx qy qz qw), KITTI (12 numbers a row) or 't x y theta' rows"
REFERENCE_FILES = {"trajectory": TRAJECTORY_FILE, "carmen": CARMEN_LOG,
                   "relations": "a Freiburg relations file (t1 t2 x y z roll pitch yaw rows)",
                   "positions": "positions with times (t x y rows, e.g. a GPS track)"}
#: eval's flags, by the EvaluationOptions field each sets.
EVAL_FLAGS = {"reference_format": "--reference-format", "rpe": "--rpe", "delta": "--delta",
              "delta_unit": "--delta-unit", "align": "--align", "raw_log": "--log",
              "max_time_difference": "--max-time-difference"}


def _cmd_eval(args: argparse.Namespace) -> int:
    options = _options(EvaluationOptions(), EVAL_FLAGS, args)
    _check_input(args.estimate, TRAJECTORY_FILE)
    with _reading(args.estimate, TRAJECTORY_FILE):
        run = TrajectoryEvaluation.read_estimate(args.estimate, options)
    print(run.estimate_summary())
    _check_input(args.reference, TRAJECTORY_FILE)
    with _reading(args.reference, TRAJECTORY_FILE), _option_flags(EVAL_FLAGS, args):
        kind = run.reference_kind(args.reference)
    with _reading(args.reference, REFERENCE_FILES[kind]):
        run.read_reference()
    if args.raw_log is not None:
        _check_input(args.raw_log, CARMEN_LOG)
    with _reading(args.raw_log, CARMEN_LOG, {"scans": args.raw_log}) if args.raw_log else contextlib.nullcontext():
        run.match_clocks()
    print(run.reference_summary())
    for note in run.notes:
        print(f"probslam: note: {note}", file=sys.stderr)
    # The scores' parameters as the command line gives them: files and options.
    names = {**EVAL_FLAGS, "times_est": args.estimate, "poses_est": args.estimate, "times_ref": args.reference,
             "poses_ref": args.reference, "timestamps": args.estimate, "poses": args.estimate, "relations": "relations"}
    with _reading(args.estimate, TRAJECTORY_FILE, names):
        run.score()
    print(run.summary(), end="")
    return 0


BATCH_FLAGS = {"time_limit": "--time-limit", "scheduler": "--scheduler", "workers": "--workers",
               "memory_limit": "--memory-limit"}


def _cmd_batch(args: argparse.Namespace) -> int:
    from . import batch

    sweep = batch.load(args.sweep)  # its own refusals name its keys, not flags
    try:  # a sweep refused, or dask missing: before a folder is made or a worker started
        with _option_flags(BATCH_FLAGS, args):
            rows = batch.run(sweep, directory=args.directory, time_limit=args.time_limit, scheduler=args.scheduler,
                             workers=args.workers, memory_limit=args.memory_limit, progress=_progress(args),
                             trajectories=args.trajectories)
    except KeyboardInterrupt:
        print(f"probslam batch: {args.directory}/{batch.PARQUET} holds every run that finished; run the same command "
              "again to make the rest", file=sys.stderr)
        raise
    failed = sum(row["status"] != "ok" for row in rows)
    print(batch.summary(rows))
    print(f"\n{len(rows)} runs, {failed} failed: {args.directory}/{batch.PARQUET}, {batch.CSV}")
    if args.plot:
        try:
            figures = batch.plot(rows, args.directory)
        except ImportError as exc:  # the table is whole; the figures need the plot extra
            print(f"probslam batch: no figures: {exc}", file=sys.stderr)
        else:
            print(f"figures: {len(figures)} in {args.directory}/{batch.FIGURES}/")
    return 0


def _bag_input_options(parser: argparse.ArgumentParser, poses: bool) -> None:
    """The options of a ROS bag input (map and slam): topics and the laser's offset."""
    parser.add_argument("--scan-topic", help="ROS bag: the sensor_msgs/LaserScan topic (default: the only one)")
    parser.add_argument("--odom-topic", help="ROS bag: the nav_msgs/Odometry topic (default: the only one; "
                                             "none: tf odom -> base)")
    if poses:
        parser.add_argument("--pose-topic", help="ROS bag: a topic of corrected poses (PoseStamped, "
                                                 "PoseWithCovarianceStamped or Odometry) to map with")
    parser.add_argument("--laser-offset", type=float, nargs=3, metavar=("X", "Y", "THETA"),
                        help="ROS bag: the laser's pose on the robot (m, m, rad; default: from tf_static)")


def _no_plot_option(parser: argparse.ArgumentParser) -> None:
    """--no-plot, on every command that writes a picture."""
    parser.add_argument("--no-plot", dest="plot", action="store_false", help="write no picture")


def _progress(args: argparse.Namespace) -> Optional[bool]:
    """The drivers' ``progress``: a bar on a terminal (None) unless --no-progress."""
    return None if args.progress else False


def _no_progress_option(parser: argparse.ArgumentParser) -> None:
    """--no-progress, on every command that shows a progress bar."""
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="never show a progress bar")


def _trajectory_format_option(parser: argparse.ArgumentParser, times: str) -> None:
    """--trajectory-format, on every command that writes a path; ``times`` says what its
    timestamps are."""
    parser.add_argument("--trajectory-format", choices=TRAJECTORY_FORMATS, default="tum",
                        help="PREFIX_trajectory.tum: TUM rows 't x y z qx qy qz qw' (default; evo reads it), "
                             "PREFIX_trajectory.kitti: KITTI 3x4 [R|t] rows with the times in "
                             f"PREFIX_trajectory_times.txt, or PREFIX_trajectory.txt: 't x y theta'; {times}")


def _landmark_dataset_options(parser: argparse.ArgumentParser, method: str, output: str) -> None:
    """The options ekf-slam and fastslam share: the dataset, the MRCLAM robot and noise, the output."""
    parser.add_argument("dataset", nargs="?", help="a UTIAS MRCLAM folder, Victoria Park in iSAM/GTSAM text format, "
                                                   "or the original Victoria Park run's folder; default: a bundled "
                                                   "MRCLAM excerpt (Dataset 7, robot 1, 120 s)")
    parser.add_argument("--robot", type=int, default=None, help="MRCLAM robot number (default 1)")
    parser.add_argument("--seconds", type=float, default=None,
                        help="MRCLAM: use only the first SECONDS of the robot's odometry (default: all)")
    parser.add_argument("--raw-ranges", action="store_true",
                        help="use MRCLAM's readings as ranges (by default they are taken as the camera's depth "
                             "and turned into distances, see io.MRCLAM_RANGE_SCALE)")
    for flag, sigma, what in (("--sigma-v", mrclam.MOTION_SIGMA[0], "odometry noise, m/s per 10 ms command"),
                              ("--sigma-w", mrclam.MOTION_SIGMA[1], "odometry noise, rad/s per 10 ms command"),
                              ("--sigma-r", mrclam.MEASUREMENT_SIGMA[0], "range noise, m"),
                              ("--sigma-phi", mrclam.MEASUREMENT_SIGMA[1], "bearing noise, rad")):
        parser.add_argument(flag, type=float, default=None, help=f"MRCLAM {what} (default: {sigma})")
    parser.add_argument("-o", "--output", default=output,
                        help=f"output prefix: PREFIX_trajectory.tum, PREFIX.png (default '{output}')")
    _trajectory_format_option(parser, "times in seconds (MRCLAM) or the pose's index (Victoria Park, whose file has "
                                      "no times)")
    parser.add_argument("--refine", choices=("none", "graphslam"), default="none",
                        help="with --unknown (always, on the original Victoria Park run): after the filter, GraphSLAM "
                             "over all sightings with the correspondence test of ch. 11.6 (merge, split, re-associate "
                             "until stable; docs/landmark_refine.md)")
    _no_progress_option(parser)
    _no_plot_option(parser)
    parser.set_defaults(func=_cmd_landmarks, method=method)


def build_parser() -> argparse.ArgumentParser:
    """The ``probslam`` command line: one subcommand per pipeline, each with its options."""
    parser = _Parser(prog="probslam", description="Probabilistic robot mapping and SLAM.", epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"probslam {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("map", help="occupancy grid map of a CARMEN laser log or ROS bag with known (corrected) poses")
    p.add_argument("log", nargs="?", help="CARMEN log (.log/.clf, optionally .gz/.bz2) or ROS bag (.bag, a ROS 2 "
                                          "folder, .db3, .mcap); default: a bundled excerpt of the Intel "
                                          "Research Lab log")
    p.add_argument("--resolution", type=float, default=None,
                   help=f"cell size in metres (default {MAP_RESOLUTION:g}; with --inverse-model the model's own, "
                        "0.1 for the bundled one)")
    p.add_argument("--max-range", type=float, default=None,
                   help=f"readings at or beyond this (metres) only clear space (default {MAP_MAX_RANGE:g}; with "
                        "--inverse-model the model's own, 10 for the bundled one)")
    p.add_argument("--robot-radius", type=float, default=MapOptions().robot_radius,
                   help="clear the robot's footprint (metres)")
    p.add_argument("--keep-no-return", dest="skip_no_return", action="store_false",
                   help="let readings at the sensor maximum clear space (default: skip them)")
    p.add_argument("--inverse-model", default=None, metavar="MODEL.npz",
                   help="map with a learned inverse sensor model (ch. 9.3; probslam.inverse_learning, saved with "
                        "LearnedInverseModel.save) instead of the ray model; 'bundled': the model trained on the "
                        "first half of the Intel corrected log (a 1-degree, 180-beam laser)")
    p.add_argument("-o", "--output", default="map", help="output prefix: PREFIX.yaml/.pgm/.png (default 'map')")
    _bag_input_options(p, poses=True)
    _no_progress_option(p)
    _no_plot_option(p)
    p.set_defaults(func=_cmd_map)

    sl = sub.add_parser("slam", help="map a raw CARMEN laser log or ROS bag (odometry and scans): scan matching into "
                                     "submaps, GraphSLAM over them with loop closures (ch. 11.7)")
    sl.add_argument("log", nargs="?", help="CARMEN log (.log/.clf, optionally .gz/.bz2) or ROS bag (.bag, a ROS 2 "
                                           "folder, .db3, .mcap); default: a bundled raw excerpt of the Intel "
                                           "Research Lab log, one lap that closes its loop")
    sl.add_argument("--resolution", type=float, default=None,
                    help=f"cell size in metres (default {DEFAULT_RESOLUTION}, with --map the map's)")
    sl.add_argument("--max-range", type=float, default=None,
                    help="the sensor's no-return reading in metres (default: from the log)")
    sl.add_argument("--submap-distance", type=float, default=None,
                    help="travel per submap in metres (default 10; 0: one map, scan matching alone)")
    sl.add_argument("--no-loop-closures", action="store_false", default=None,
                    help="scan matching and submaps only")
    sl.add_argument("--method", choices=("graph", "rbpf"), default="graph",
                    help="graph: GraphSLAM over submaps (default); rbpf: grid-based FastSLAM (particle filter)")
    sl.add_argument("--particles", type=int, default=None,
                    help=f"rbpf: number of particles (default {RBPF_PARTICLES}, not fastslam's {FASTSLAM_PARTICLES}: "
                         "each carries a grid map, so time and memory grow with the count; on the bundled log 100 "
                         "take 3.8x the time and 3.5x the map memory of 30, and on ACES's first 2000 scans the "
                         "relations error is 0.042-0.044 m for 1 to 100, docs/grid_fastslam.md)")
    sl.add_argument("--proposal", choices=("scan-matching", "motion", "improved-odometry"), default=None,
                    help="rbpf: scan-matching (GMapping's improved proposal, default), motion (the plain filter) "
                         "or improved-odometry (odometry corrected by scan matching, then the plain filter)")
    sl.add_argument("--seed", type=int, default=None, help="rbpf: random seed (default 0)")
    sl.add_argument("--threads", type=int, default=None,
                    help="rbpf: worker threads, the result identical for any count (default 1)")
    sl.add_argument("-o", "--output", default="slam",
                    help="output prefix: PREFIX.yaml/.pgm/.png, PREFIX_trajectory.tum, PREFIX.g2o (graph only; "
                         "default 'slam')")
    _trajectory_format_option(sl, "the laser poses at the log's scan times (s)")
    _bag_input_options(sl, poses=False)
    sl.add_argument("--save", default=None, metavar="RUN.psl",
                    help="write the run's state (the SLAM object and the scans processed) to RUN.psl at the end, "
                         "or on Ctrl-C, for --resume (docs/cli.md)")
    sl.add_argument("--map", default=None, metavar="MAP",
                    help="start from a saved map (MAP.yaml as map and slam write it, or an OccupancyGrid2D state "
                         "file); the run's frame is the map's and the first scan is matched against it. graph: the "
                         "map is the fixed first submap that loop closures can close onto; rbpf: every particle's "
                         "map starts as it. The written map is MAP with the log drawn in (docs/cli.md)")
    sl.add_argument("--initial-pose", type=float, nargs=3, default=None, metavar=("X", "Y", "THETA"),
                    help="with --map: where the log's first scan is in the map (m, m, rad; default 0 0 0), a guess "
                         "within the scan matcher's window (0.3 m, 0.35 rad by default)")
    sl.add_argument("--resume", default=None, metavar="RUN.psl",
                    help="continue a run saved with --save from the next scan of the same LOG (its method and "
                         "options are the saved ones); the result equals a run that never stopped")
    _no_progress_option(sl)
    _no_plot_option(sl)
    sl.set_defaults(func=_cmd_slam)

    lo = sub.add_parser("localize", help="Monte Carlo localization of a raw CARMEN log or ROS bag in a map "
                                         "(ch. 8.3: KLD sampling, augmented MCL), tracking or global")
    lo.add_argument("log", nargs="?", help=f"{CARMEN_LOG} or {ROS_BAG}; default: the bundled raw Intel loop "
                                           f"(that of 'probslam slam') in its bundled map")
    lo.add_argument("--map", default=None, help="the map: a map_server YAML (e.g. probslam slam's PREFIX.yaml); "
                                                "needed with a LOG")
    lo.add_argument("--initial-pose", type=float, nargs=3, metavar=("X", "Y", "THETA"), default=None,
                    help="the start in the map's frame (m, m, rad): tracking")
    lo.add_argument("--global", dest="global_", action="store_true",
                    help="no start: particles uniform over free space (global localization)")
    mcl = MonteCarloLocalizationOptions()  # the flags' defaults are the library's
    lo.add_argument("--sensor-model", choices=("likelihood-field", "beam"), default=None,
                    help=f"likelihood-field (Table 6.3) or beam (Table 6.1); default {mcl.sensor_model}")
    lo.add_argument("--min-particles", type=int, default=None,
                    help=f"KLD sampling's lower bound (default {mcl.min_particles})")
    lo.add_argument("--max-particles", type=int, default=None,
                    help=f"KLD sampling's upper bound, and the global start's count (default {mcl.max_particles})")
    lo.add_argument("--max-range", type=float, default=None,
                    help="readings at or beyond this (m) are skipped (default: the log's no-return reading)")
    lo.add_argument("--seed", type=int, default=None, help=f"random seed (default {mcl.seed})")
    lo.add_argument("--threads", type=int, default=None,
                    help=f"worker threads, results identical for any count (default {mcl.threads})")
    lo.add_argument("-o", "--output", default="localize",
                    help="output prefix: PREFIX_trajectory.tum, PREFIX.png (default 'localize')")
    _trajectory_format_option(lo, "the laser poses at the log's scan times (s)")
    _bag_input_options(lo, poses=False)
    _no_progress_option(lo)
    _no_plot_option(lo)
    lo.set_defaults(func=_cmd_localize)

    e = sub.add_parser("ekf-slam", help="EKF SLAM on a landmark dataset (MRCLAM folder or Victoria Park file)")
    e.add_argument("--unknown", action="store_true", help="hide the correspondences (Table 10.2)")
    e.add_argument("--association", choices=ASSOCIATIONS, default=None,
                   help="with --unknown on MRCLAM: joint compatibility over each scan, maximum likelihood, or a "
                        "beam of filters (multiple hypotheses, the default: they also pay for landmarks in the "
                        "camera's field that a scan misses, and meet 95%% on every Dataset 1 robot where JCBB "
                        "keeps 19-40 landmarks for 15)")
    e.add_argument("--bearing-offset", type=float, default=0.0, metavar="SIGMA",
                   help="with --association mht on MRCLAM: a bearing offset (rad) shared by each scan's sightings, "
                        "carried by every hypothesis; --sigma-phi is then the part not shared (docs: "
                        "--bearing-offset 0.03 --sigma-phi 0.02 lifts Dataset 7 to 81-90%%)")
    _landmark_dataset_options(e, "ekf", "ekf_slam")

    fsp = sub.add_parser("fastslam", help="FastSLAM 1.0 / 2.0 on a landmark dataset (MRCLAM folder or Victoria "
                                          "Park file)")
    fsp.add_argument("--unknown", action="store_true",
                     help="hide the correspondences: each particle associates by maximum likelihood")
    lro = LandmarkRunOptions()  # the flags' defaults are the pipeline's
    fsp.add_argument("--particles", dest="num_particles", metavar="PARTICLES", type=int, default=lro.num_particles,
                     help=f"number of particles (default {lro.num_particles}, not slam's {RBPF_PARTICLES}: a particle "
                          "holds a few landmarks, not a grid map, so 100 filter MRCLAM Dataset 7 in 2 s)")
    fsp.add_argument("--variant", dest="version", type=int, choices=(1, 2), default=lro.version,
                     help="1: FastSLAM 1.0 (default); 2: FastSLAM 2.0, the proposal that includes the measurements")
    fsp.add_argument("--seed", type=int, default=lro.seed, help="random seed")
    fsp.add_argument("--threads", type=int, default=lro.threads, help="threads (same result for any count)")
    _landmark_dataset_options(fsp, "fastslam", "fastslam")

    o = sub.add_parser("optimize", help="optimise a 2-D pose/landmark graph or a 3-D pose graph (g2o, TORO or "
                                        "iSAM text; the dimension is read from the file)")
    o.add_argument("graph", nargs="?", help="graph file: .g2o, TORO .graph, or iSAM .txt, 2-D or 3-D; default: a "
                                            "bundled excerpt of the Intel Research Lab graph (400 poses; a 3-D one: "
                                            "probslam.data.path('parking_garage_400.g2o'))")
    gfo = GraphFileOptions()  # the flags' defaults are the pipeline's
    o.add_argument("--format", default=gfo.format, choices=["auto", "g2o", "toro", "isam"],
                   help="the graph file's format (auto: from its records)")
    o.add_argument("--noise", default=gfo.noise, choices=NOISE_CONVENTIONS,
                   help="what the edges' noise entries hold (auto: the format's own -- information for g2o and "
                        "TORO, square-root information for iSAM -- except GTSAM's iSAM copies, named '*gtsam*', "
                        "which hold covariances)")
    o.add_argument("--algorithm", default=gfo.algorithm, choices=["gauss-newton", "levenberg-marquardt"],
                   help="the least-squares solver")
    o.add_argument("--init", default=None, choices=list(INITIALIZATIONS),
                   help="starting point: the file's values (the default for 2-D pose graphs; dead reckoning for "
                        "iSAM files), dead reckoning, the EKF SLAM estimate (2-D; the default for a graph with "
                        "landmarks), incremental optimisation (2-D), or the chordal relaxation of the rotations "
                        "(3-D, its default)")
    o.add_argument("--poses-per-step", type=int, default=None,
                   help="with --init incremental: poses per step (default 100)")
    o.add_argument("--max-iterations", type=int, default=gfo.max_iterations,
                   help="iterations at most; a run that has not converged by then exits with status 3")
    o.add_argument("--kernel", default=gfo.kernel, choices=["none", "huber", "cauchy"], help="robust kernel")
    o.add_argument("--kernel-width", type=float, default=None,
                   help="kernel width, in units of sqrt(chi2) (default 1)")
    o.add_argument("--linear-solver", default=None, choices=["simplicial", "supernodal", "auto"],
                   help="sparse Cholesky: default supernodal")
    o.add_argument("--ordering", default=None, choices=["amd", "metis"],
                   help="fill-reducing ordering: default amd for 2-D, metis for 3-D")
    o.add_argument("--edges", action="store_true", help="draw every edge in the picture")
    _no_plot_option(o)
    _no_progress_option(o)
    o.add_argument("-o", "--output", default="optimized",
                   help="output prefix: PREFIX.g2o/.png, PREFIX_trajectory.tum (default 'optimized')")
    _trajectory_format_option(o, "a graph file has no times: each pose's vertex id is its time")
    o.set_defaults(func=_cmd_optimize)

    ev = sub.add_parser("eval", help="score a trajectory against a ground truth: absolute or relative trajectory "
                                     "error (as evo_ape / evo_rpe print them), or the relations error")
    ev.add_argument("estimate", metavar="EST", help="the trajectory to score: TUM, KITTI (times in NAME_times.txt) or 't x y theta' "
                                     "rows, as the commands write it (PREFIX_trajectory.tum)")
    ev.add_argument("reference", metavar="REF", help="the ground truth: a trajectory file as EST, a relations file (a name with "
                                      "'.relations', e.g. aces.relations; scored as 'slam' scores its logs), a "
                                      "CARMEN log with corrected poses (e.g. intel-corrected.log.gz: its laser poses "
                                      "at its scans' times), or positions with times, 't x y' rows (a GPS track: the "
                                      "estimate is interpolated at each fix's time, the error printed as it is and "
                                      "aligned)")
    ev.add_argument("--reference-format", choices=REFERENCE_FORMATS,
                    default="auto",
                    help="what REF is (default: relations when its name has '.relations', a CARMEN log when it "
                         "ends in .log or .clf (optionally .gz/.bz2/.xz), else the trajectory format its rows show)")
    ev.add_argument("--rpe", action="store_true",
                    help="relative pose error over consecutive pairs --delta apart (default: absolute error)")
    ev.add_argument("--delta", type=float, default=None, help="with --rpe: the pairs' distance (default 1)")
    ev.add_argument("--delta-unit", choices=("frames", "m", "s"), default=None,
                    help="with --rpe: delta in poses (default), metres travelled or seconds")
    ev.add_argument("--align", action=argparse.BooleanOptionalAction, default=None,
                    help="move the estimate onto the reference by the best rotation and translation (Umeyama "
                         "without scale) first; default: aligned for the absolute error, not for --rpe (as evo)")
    ev.add_argument("--log", dest="raw_log", metavar="LOG", default=None,
                    help="with a relations file: the raw CARMEN log the estimate was made from (e.g. aces.clf.bz2); "
                         "relations are stamped with its ipc time, the commands write its logger time, so each "
                         "relation time is moved onto the logger time")
    ev.add_argument("--max-time-difference", type=float, default=None,
                    help="poses are paired with the nearest reference pose at most this far in time, s (default "
                         "0.01, evo's)")
    ev.set_defaults(func=_cmd_eval)

    ba = sub.add_parser("batch", help="a sweep of runs (datasets x commands x option grids x seeds) on Dask "
                                      "distributed, one row per run in DIR/results.parquet and results.csv "
                                      "(docs/batch.md; needs 'probslam[batch]')")
    ba.add_argument("sweep", metavar="SWEEP", help="the sweep: a TOML file (docs/batch.md; examples/sweep_demo.toml)")
    ba.add_argument("-o", "--output-dir", dest="directory", metavar="DIR", required=True,
                    help="the folder of the table (made if missing; no default); the runs whose rows are there are not "
                         "made again")
    ba.add_argument("--scheduler", metavar="ADDRESS", default=None,
                    help="a running Dask scheduler (tcp://host:8786); default: DASK_SCHEDULER_ADDRESS, else a local "
                         "cluster")
    ba.add_argument("--workers", type=int, default=None, help="local cluster: worker processes of one thread "
                                                              "(default: one per core)")
    ba.add_argument("--memory-limit", default="auto", help="local cluster: memory per worker, e.g. 4GB; a worker past "
                                                           "it is restarted and its run retried (default: auto, the "
                                                           "memory shared out)")
    ba.add_argument("--time-limit", type=float, default=None, metavar="S",
                    help="seconds a run may take before it is recorded as timeout (default: the sweep's time_limit, "
                         "else none)")
    ba.add_argument("--trajectories", action="store_true",
                    help="keep each run's trajectory in DIR/trajectories (TUM; on a cluster DIR must be storage the "
                         "workers share)")
    _no_plot_option(ba)
    _no_progress_option(ba)
    ba.set_defaults(func=_cmd_batch)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 user or input error, 1 unexpected
    error, 141 when the reader of a pipe stopped). Set PROBSLAM_DEBUG=1 to see the traceback of
    an unexpected error."""
    try:
        status = _run(argv)
        sys.stdout.flush()  # a pipe closed under buffered output shows here, not at exit
        return status
    except BrokenPipeError:
        # The reader stopped (probslam ... | head -1): quiet, with the status a tool killed by
        # SIGPIPE has, as other command-line tools. The output left is dropped, not flushed into
        # the closed pipe at exit (which Python would report).
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


def _run(argv: Optional[List[str]]) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.given = _given_options(argv)
    if getattr(args, "output", None) is not None:
        args.output = _output_prefix(args.output, parser._command_parser(args).get_default("output"))
    format_warning = warnings.formatwarning
    # A reader's warning (a few malformed lines skipped) as one line, without the source line.
    warnings.formatwarning = lambda message, category, *rest, **kw: f"probslam: warning: {message}\n"
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("probslam: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        raise
    except (UserError, ValueError, TypeError, OSError, ImportError) as exc:
        # Bad options (the library names the argument), unreadable or unwritable files.
        print(f"probslam: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - the last resort: one line, not a traceback
        if os.environ.get("PROBSLAM_DEBUG"):
            raise
        print(f"probslam: unexpected error: {type(exc).__name__}: {_one_line(exc)} "
              "(a bug: please report it; PROBSLAM_DEBUG=1 shows the traceback)", file=sys.stderr)
        return 1
    finally:
        warnings.formatwarning = format_warning


def _given_options(argv: Optional[List[str]]) -> Dict[str, str]:
    """dest -> option (its long form) of each option given on the command line, defaults not
    counted: the command line parsed again by a parser in which nothing has a default."""
    parser = build_parser()
    parsers = [parser]
    for p in parsers:
        p._defaults.clear()
        for action in p._actions:
            action.default = argparse.SUPPRESS
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
    given = vars(parser.parse_args(argv))
    flags = {a.dest: next((o for o in a.option_strings if o.startswith("--")), a.option_strings[0])
             for p in parsers for a in p._actions if a.option_strings}
    return {dest: flags.get(dest, dest.upper()) for dest in given}


def _output_prefix(output: str, stem: str) -> str:
    """-o as a prefix: a folder (one that exists, or a name ending in a slash) holds the files
    under the command's own name (-o out/: out/map.yaml, not out/.yaml)."""
    if output.endswith(("/", os.sep)) or os.path.isdir(output):
        return os.path.join(output, stem)
    return output


def _refuse_given(args: argparse.Namespace, dests, why: str) -> None:
    """UserError naming the first of the options ``dests`` given on the command line: it does
    not apply to this run (``why``), and would otherwise pass unnoticed."""
    given = getattr(args, "given", {})
    for dest in dests:
        if dest in given:
            raise UserError(f"{given[dest]} {why}")


if __name__ == "__main__":
    sys.exit(main())
