"""The ``probslam`` command line: each command parses its flags, calls one pipeline and prints
what the pipeline's run says, writes and draws. The flags that set an options field are made from
the field's description; the library checks the values and its messages, which name the field,
are told as the flag that gave it."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import difflib
import functools
import os
import re
import shlex
import sys
import time
import warnings
from typing import Dict, Iterator, List, Optional, Tuple

from . import __version__
from .data import path as _data_path
from .datasets import mrclam
from ._core import GridFastSlamOptions, MonteCarloLocalizationOptions, SubmapSlamOptions
from .pipelines.landmark_run import LandmarkRun, LandmarkRunOptions
from .pipelines.optimize_file import GraphFileOptions, GraphFileRun
from .io.trajectory import TRAJECTORY_FORMATS
from . import localization
from .mapping import DEFAULT_MAX_RANGE as MAP_MAX_RANGE, DEFAULT_RESOLUTION as MAP_RESOLUTION
from .pipelines.localize_log import localize_log
from .pipelines.map_log import MapOptions, MapRun
from .pipelines.evaluate_trajectory import EvaluationOptions, TrajectoryEvaluation
from .pipelines.inputs import (BAG_OPTIONS, CARMEN_LOG, READ_ERRORS,
                               REFERENCE_FILES, TRAJECTORY_FILE, InputError, name_pattern, one_line,
                               read_log, reading)

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
#: Exit status: a run that finished but did not converge; Ctrl-C (128 + SIGINT, as shells report
#: it); the reader of the output pipe stopped (128 + SIGPIPE, as a tool killed by it has).
EXIT_NOT_CONVERGED, EXIT_INTERRUPTED, EXIT_BROKEN_PIPE = 3, 130, 141
#: How close a misspelt option or choice must be to one of the parser's to be suggested
#: (difflib's ratio: 0.6, its own default, takes --partcles for --particles, not --seed for --robot).
SUGGESTION_CUTOFF = 0.6
#: slam's option fields by method (SubmapSlamOptions / GridFastSlamOptions paths), each set by the
#: flag of its last name (FLAG_NAMES where the flag's name differs).
SLAM_FIELDS = {"graph": ("frontend.resolution", "frontend.filter.max_range", "frontend.submap_distance",
                         "closures.enabled"),
               "rbpf": ("num_particles", "proposal", "seed", "threads", "resolution", "filter.max_range")}
FLAG_NAMES = {"num_particles": "--particles", "version": "--variant", "closures.enabled": "--no-loop-closures",
              "raw_log": "--log"}


def _flag(path: str) -> str:
    return FLAG_NAMES.get(path, "--" + path.rsplit(".", 1)[-1].replace("_", "-"))


#: slam's flags by method: the option path each sets (the library's messages, which name the path,
#: told as the flag). A flag's value is its dest's (--no-loop-closures stores False).
SLAM_FLAGS = {method: {path: _flag(path) for path in paths} for method, paths in SLAM_FIELDS.items()}


class UserError(Exception):
    """An input or usage error: printed as one line on stderr, exit status 2."""


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Every option that takes a value shows its default ("none": off unless given), unless its
    help says it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if (not action.option_strings or action.nargs == 0 or action.default is argparse.SUPPRESS
                or "default" in text.lower()):
            return text
        return text + (" (default: none)" if action.default is None else " (default: %(default)s)")


class _Parser(argparse.ArgumentParser):
    """argparse with its usage errors as one line on stderr (exit status 2), like every other user
    error, naming the subcommand's -h and the option or choice meant when one is close."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, formatter_class=_HelpFormatter, **kwargs)

    def error(self, message: str):
        choice = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if choice:
            message += _did_you_mean(choice.group(1), re.findall(r"'([^']*)'", choice.group(2)))
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} -h')\n")

    def parse_args(self, args=None, namespace=None):
        """An unknown option reported by the subcommand's parser, with the nearest of its options."""
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
        sub = next(a for a in self._actions if isinstance(a, argparse._SubParsersAction))
        return sub.choices.get(getattr(parsed, sub.dest, None), self)


def _did_you_mean(word: str, candidates: List[str]) -> str:
    close = difflib.get_close_matches(word, candidates, n=1, cutoff=SUGGESTION_CUTOFF)
    return f"; did you mean {close[0]}?" if close else ""


def _bundled_log(name: str = BUNDLED_LOG) -> str:
    return _data_path(name)


def _as_given(text: str, names: Dict[str, str], args: Optional[argparse.Namespace] = None) -> Tuple[str, bool]:
    """A library message told as the command line gave it, and whether it named anything: its
    subject (a leading name of ``names``) as the flag with the value given ("min_particles must ..."
    -> "--min-particles 0: must ..."), the other names with an underscore as theirs."""
    pattern = name_pattern(names)
    subject = pattern.match(text)
    rest = text[subject.end():] if subject else text
    mentioned = [m.group(1) for m in pattern.finditer(rest) if "_" in m.group(1)]
    rest = pattern.sub(lambda m: names[m.group(1)] if m.group(1) in mentioned else m.group(1), rest)
    if not subject:
        return rest, bool(mentioned)
    name, colon = subject.group(1), ":" if rest.startswith(":") else ""
    rest = rest.lstrip(": ")
    # The value given: the flag's dest, named as the option (min_particles) or as the flag (--resolution).
    given = getattr(args, name, getattr(args, names[name].lstrip("-").replace("-", "_"), None)) if args else None
    if isinstance(given, (list, tuple)):
        given = " ".join(map(str, given))
    if given is None or isinstance(given, bool) or rest.startswith((f"{given} ", f"{given}:")) or f"got {given}" in rest:
        return f"{names[name]}{colon} {rest}", True  # no value to add, or the message says it
    return f"{names[name]} {given}: {rest}", True


@contextlib.contextmanager
def _option_flags(args: argparse.Namespace, names: Optional[Dict[str, str]] = None) -> Iterator[None]:
    """The library's errors about an option told as the flag that set it (``_as_given``; ``names``:
    field -> flag, default each option's dest -> its flag): the CLI does not check values again."""
    try:
        yield
    except InputError:
        raise
    except (TypeError, ValueError) as exc:
        text, named = _as_given(one_line(exc), names or args.flags, args)
        if named:
            raise UserError(text) from None
        raise


def _options(options, args: argparse.Namespace):
    """``options.replace`` with the field of each flag given (its dest), refusals told as the flags."""
    fields = options.as_dict() if hasattr(options, "as_dict") else vars(options)
    with _option_flags(args):
        return options.replace(**{k: getattr(args, k) for k in fields
                                  if k in args.flags and getattr(args, k) is not None})


@contextlib.contextmanager
def _told(path: str, names: Dict[str, str]) -> Iterator[None]:
    """A reader's error about a parameter of ``names`` (``inputs.reading`` passes it on: not the
    file's) told as it (``scan_topic`` -> ``--scan-topic``), naming ``path``."""
    try:
        yield
    except InputError:
        raise
    except READ_ERRORS as exc:
        text, named = _as_given(one_line(exc), names) if names else ("", False)
        if not named:
            raise
        raise UserError(text if path in text else f"{path}: {text}") from None


@contextlib.contextmanager
def _reading(path: str, expected: str, names: Optional[Dict[str, str]] = None, folder: bool = False) -> Iterator[None]:
    """``inputs.reading``: errors naming ``path`` and what was ``expected``, or a parameter of ``names``."""
    with _told(path, names or {}), reading(path, expected, tuple(names or ()), folder):
        yield


def _save_figure(plt, fig, path: str) -> str:
    """`fig` written to `path` (120 dpi, the box fitted to what is drawn, a legend beside included)."""
    fig.tight_layout()
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def _picture(run, args: argparse.Namespace, **draw) -> List[str]:
    """[PREFIX.png] drawn by the run (``draw``), without matplotlib its plain picture if it has one."""
    from .plot import require_matplotlib

    if not args.plot:
        return []
    try:
        plt = require_matplotlib()
    except ImportError:
        print("probslam: plot skipped: matplotlib is not installed (pip install 'probslam[plot]')", file=sys.stderr)
        plain = getattr(run, "write_plain_picture", None)
        return [plain(args.output + ".png")] if plain else []
    return [_save_figure(plt, run.draw(plt, **draw), args.output + ".png")]


def _progress(args: argparse.Namespace) -> Optional[bool]:
    """The drivers' ``progress``: a bar on a terminal (None) unless --no-progress."""
    return None if args.progress else False


def _read_log(path: str, args: argparse.Namespace):
    """The CARMEN log or ROS bag at ``path`` (a bag with the topic and offset flags given)."""
    bag = {name: getattr(args, name) for name in BAG_OPTIONS if getattr(args, name, None) is not None}
    with _told(path, {name: "--" + name.replace("_", "-") for name in BAG_OPTIONS}):
        return read_log(path, **bag)


def _check_output(prefix: str) -> None:
    """UserError naming -o when its folder is missing or not writable: before a run of minutes."""
    folder = os.path.dirname(prefix) or "."
    if not os.path.isdir(folder):
        raise UserError(f"-o {prefix}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UserError(f"-o {prefix}: folder {folder} is not writable")


def _cmd_map(args: argparse.Namespace) -> int:
    options = _options(MapOptions(), args)
    path, t0 = args.log or _bundled_log(), time.perf_counter()
    log = _read_log(path, args)
    with _option_flags(args):
        run = MapRun.prepare(log, options, path, read_seconds=time.perf_counter() - t0)
        if run.start_summary():
            print(run.start_summary(), flush=True)
        run.run(_progress(args))
    written = run.write(args.output) + _picture(run, args)
    print(run.summary(path + ("" if args.log else " (bundled Intel Research Lab excerpt)"), written,
                      hint=args.log is not None))
    return 0


def _resume_command(args: argparse.Namespace, run_file: str) -> str:
    """The slam command that continues from run_file: the same log and outputs."""
    words = ["probslam", "slam"] + ([args.log] if args.log else [])
    for flag, value in (("--scan-topic", args.scan_topic), ("--odom-topic", args.odom_topic),
                        ("--trajectory-format", None if args.trajectory_format == "tum" else args.trajectory_format),
                        ("-o", None if args.output == "slam" else args.output)):
        words += [flag, value] if value is not None else []
    words += ["--laser-offset"] + [repr(float(v)) for v in args.laser_offset] if args.laser_offset else []
    return shlex.join(words + ["--resume", run_file, "--save", run_file] + ([] if args.plot else ["--no-plot"]))


def _cmd_slam(args: argparse.Namespace) -> int:
    from .pipelines.slam_log import slam_log
    from .slam import OPTIONS_CLASSES, RunInterrupted, with_fields

    dests = {m: [flag[2:].replace("-", "_") for flag in SLAM_FLAGS[m].values()] for m in SLAM_FLAGS}
    if args.resume is not None:
        _refuse_given(args, ["method", *dests["graph"], *dests["rbpf"]],
                      "does not apply with --resume (the run goes on with its saved options)")
    other = dests["rbpf" if args.method == "graph" else "graph"]
    _refuse_given(args, [d for d in other if d not in dests[args.method]], f"does not apply to --method {args.method}")
    flags = SLAM_FLAGS[args.method]
    given = {path: getattr(args, flag[2:].replace("-", "_")) for path, flag in flags.items()
             if flag in args.given.values()}
    with _option_flags(args, flags):
        with_fields(OPTIONS_CLASSES[args.method](), given)  # the library checks the flags before the log is read
    path = args.log or _bundled_log(BUNDLED_SLAM_LOG)
    log = _read_log(path, args)
    names = {**flags, "initial_map": "--map", "initial_pose": "--initial-pose", "save": "--save"}
    try:
        with _option_flags(args, names):
            run = slam_log(log, method=args.method, fields=given, path=path, initial_map=args.map,
                           initial_pose=args.initial_pose, resume=args.resume, save=args.save, progress=_progress(args))
    except RunInterrupted as e:
        if e.saved is None:
            raise
        print(f"probslam: interrupted after {e.scans_done} of {e.log_scans} scans; run file {e.saved} written; "
              f"to continue: {_resume_command(args, e.saved)}", file=sys.stderr)
        return EXIT_INTERRUPTED
    written = run.write(args.output, args.trajectory_format)
    written[2:2] = _picture(run, args)
    bundled = "" if args.log else " (bundled Intel Research Lab raw excerpt: one lap, back past its start)"
    print(run.summary(path + bundled, written + ([args.save] if args.save is not None else [])))
    return 0


def _cmd_localize(args: argparse.Namespace) -> int:
    if args.initial_pose is not None and args.global_:
        raise UserError("--initial-pose and --global exclude each other")
    bundled = args.log is None and args.map is None
    if args.initial_pose is None and not args.global_ and not bundled:
        raise UserError("say where the robot starts: --initial-pose X Y THETA, or --global (anywhere in free space)")
    if bundled:  # global localization, what MCL can do that a tracker cannot
        args.log, args.map = _data_path(BUNDLED_RAW_LOG), _data_path(BUNDLED_LOCALIZATION_MAP)
        print("probslam localize: no LOG given: the bundled raw Intel loop in its bundled map, from a global start "
              "(particles anywhere in free space); give LOG --map MAP.yaml for your own", flush=True)
    elif args.map is None:
        raise UserError("--map: give the map to localize in (a map_server YAML, e.g. probslam slam's PREFIX.yaml)")
    elif args.log is None:
        raise UserError("--map given without a LOG: name the log to localize")
    log = _read_log(args.log, args)
    options = _options(localization.default_options(log.scans), args)
    with _option_flags(args):
        run = localize_log(log, args.map, options, initial_pose=args.initial_pose, progress=_progress(args))
    written = run.write(args.output, args.trajectory_format) + _picture(
        run, args, title=f"probslam localize: {os.path.basename(args.log)} in {os.path.basename(args.map)}")
    print(run.summary(args.log, args.map, written))
    return 0 if run.converged else EXIT_NOT_CONVERGED


def _cmd_landmarks(args: argparse.Namespace) -> int:
    """ekf-slam and fastslam: ``pipelines.LandmarkRun`` on the dataset argument."""
    options = _options(LandmarkRunOptions(method=args.method), args)
    t0, path = time.perf_counter(), args.dataset or _data_path(BUNDLED_LANDMARKS)
    with _option_flags(args):
        run = LandmarkRun.read(path, options)
    with _option_flags(args):
        run.run(_progress(args))
    print(run.summary())
    written = _picture(run, args) + run.write(args.output, args.trajectory_format)
    print(f"time:          {time.perf_counter() - t0:.2f} s total")
    print(f"wrote:         {', '.join(written)}")
    return 0


def _cmd_optimize(args: argparse.Namespace) -> int:
    if not args.plot:
        _refuse_given(args, ("edges",), "draws in the picture, which --no-plot leaves out")
    options = _options(GraphFileOptions(), args)
    path = args.graph or _data_path(BUNDLED_GRAPH)
    with _option_flags(args):
        run = GraphFileRun.read(path, options)
        if run.dimension == 3 and args.trajectory_format == "xyt":
            raise ValueError("trajectory_format: 'xyt' ('t x y theta') cannot hold a 3-D pose: use tum or kitti")
    print(run.read_summary(path + ("" if args.graph else " (bundled Intel Research Lab excerpt)")))
    run.start()
    if run.start_summary():
        print(run.start_summary())
    run.optimize(progress=_progress(args))
    print(run.optimize_summary())
    written = run.write(args.output, args.trajectory_format) + _picture(run, args, edges=args.edges)
    print(f"wrote:      {', '.join(written)}")
    if run.interrupted:
        print("probslam: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return 0 if run.converged else EXIT_NOT_CONVERGED


def _cmd_eval(args: argparse.Namespace) -> int:
    options = _options(EvaluationOptions(), args)
    with _reading(args.estimate, TRAJECTORY_FILE):
        run = TrajectoryEvaluation.read_estimate(args.estimate, options)
    print(run.estimate_summary())
    with _reading(args.reference, TRAJECTORY_FILE), _option_flags(args):
        kind = run.reference_kind(args.reference)
    with _reading(args.reference, REFERENCE_FILES[kind]):
        run.read_reference()
    with _reading(args.raw_log, CARMEN_LOG, {"scans": args.raw_log}) if args.raw_log else contextlib.nullcontext():
        run.match_clocks()
    print(run.reference_summary())
    for note in run.notes:
        print(f"probslam: note: {note}", file=sys.stderr)
    # The scores' parameters as the command line gives them: files and options.
    files = dict.fromkeys(("times_est", "poses_est", "timestamps", "poses"), args.estimate)
    with _reading(args.estimate, TRAJECTORY_FILE, {**args.flags, **files, "times_ref": args.reference,
                                                   "poses_ref": args.reference, "relations": "relations"}):
        run.score()
    print(run.summary(), end="")
    return 0


def _cmd_batch(args: argparse.Namespace) -> int:
    from . import batch

    sweep = batch.load(args.sweep)  # its own refusals name its keys, not flags
    try:  # a sweep refused, or dask missing: before a folder is made or a worker started
        with _option_flags(args):
            rows = batch.run(sweep, directory=args.directory, time_limit=args.time_limit, scheduler=args.scheduler,
                             workers=args.workers, memory_limit=args.memory_limit, progress=_progress(args),
                             trajectories=args.trajectories)
    except KeyboardInterrupt:
        print(f"probslam batch: {args.directory}/{batch.PARQUET} holds every run that finished; run the same command "
              "again to make the rest", file=sys.stderr)
        raise
    print(batch.summary(rows))
    print(f"\n{len(rows)} runs, {sum(row['status'] != 'ok' for row in rows)} failed: {args.directory}/{batch.PARQUET}, "
          f"{batch.CSV}")
    if args.plot:
        try:
            figures = batch.plot(rows, args.directory)
        except ImportError as exc:  # the table is whole; the figures need the plot extra
            print(f"probslam batch: no figures: {exc}", file=sys.stderr)
        else:
            print(f"figures: {len(figures)} in {args.directory}/{batch.FIGURES}/")
    return 0


def _described(parser: argparse.ArgumentParser, options, paths, prefix: str = "",
               defaults: Optional[Dict[str, str]] = None):
    """A flag (``_flag``, dest the field's name) for each field at ``paths`` of ``options`` (a bound
    options class's or pipeline options dataclass's instance: the defaults shown, ``defaults`` the
    text of those the run sets) from the field's description; None until given (the run's own)."""
    for path in paths:
        *groups, name = path.split(".")
        owner = functools.reduce(getattr, groups, options)
        value, meta = getattr(owner, name), _description(owner, name)
        doc = re.sub(r"``(\w+)``", lambda m: _flag(m.group(1)) if hasattr(owner, m.group(1)) else m.group(1),
                     meta["doc"].replace("%", "%%"))
        none = re.search(r" ?\(None: ([^)]*)\)", doc) if value is None else None  # what None means: the default
        doc, shown = (doc.replace(none.group(0), ""), none.group(1)) if none else (doc, value)
        shown = (defaults or {}).get(path, shown)
        text = prefix + doc + (f", {meta['unit']}" if meta["unit"] else "") + ("" if shown is None or (
            value is False) else f" (default: {shown})")
        kind = meta.get("type") or (str if value is None else type(value))
        if kind is bool:  # off by default, or None (--X / --no-X); a field on by default is written by hand
            action = argparse.BooleanOptionalAction if value is None else "store_true"
            parser.add_argument(_flag(path), dest=name, action=action, help=text)
            continue
        # A bound options class's text field: the names its doc quotes (a dataclass field has its own).
        quoted = re.findall(r'"([^"]+)"', doc) if kind is str and "type" not in meta else None
        choices = meta.get("choices") or quoted or None
        parser.add_argument(_flag(path), dest=name, default=None, choices=choices, type=None if kind is str else kind,
                            metavar=None if choices else _flag(path)[2:].replace("-", "_").upper(), help=text)


def _description(owner, name: str) -> dict:
    """A field's doc, unit, choices, type: a dataclass's (``described``) or a bound class's property doc."""
    if dataclasses.is_dataclass(owner):
        return next(f.metadata for f in dataclasses.fields(owner) if f.name == name)
    unit, doc = re.match(r"\w+(?: \((.*?)\))?: (.*)", getattr(type(owner), name).__doc__, re.S).groups()
    return dict(doc=doc, unit=unit or "")


def _outputs(parser, name: str, files: str, times: Optional[str] = None, plot: bool = True, progress: bool = True):
    """-o (``name``: default prefix, ``files``), --trajectory-format (``times``), --no-plot, --no-progress."""
    if name:
        parser.add_argument("-o", "--output", default=name, help=f"output prefix: {files} (default '{name}')")
    if times:
        parser.add_argument("--trajectory-format", choices=TRAJECTORY_FORMATS, default="tum",
                            help="PREFIX_trajectory.tum: TUM rows 't x y z qx qy qz qw' (default; evo reads it), "
                                 "PREFIX_trajectory.kitti: KITTI 3x4 [R|t] rows with the times in "
                                 f"PREFIX_trajectory_times.txt, or PREFIX_trajectory.txt: 't x y theta'; {times}")
    if progress:
        parser.add_argument("--no-progress", dest="progress", action="store_false", help="never show a progress bar")
    if plot:
        parser.add_argument("--no-plot", dest="plot", action="store_false", help="write no picture")


def _log_input(parser, default: str, poses: bool = False) -> None:
    """LOG (``default``: the bundled one) and a ROS bag's options: topics, the laser's offset."""
    parser.add_argument("log", nargs="?", help="CARMEN log (.log/.clf, optionally .gz/.bz2) or ROS bag (.bag, a ROS 2 "
                                               f"folder, .db3, .mcap); default: {default}")
    parser.add_argument("--scan-topic", help="ROS bag: the sensor_msgs/LaserScan topic (default: the only one)")
    parser.add_argument("--odom-topic", help="ROS bag: the nav_msgs/Odometry topic (default: the only one; "
                                             "none: tf odom -> base)")
    if poses:
        parser.add_argument("--pose-topic", help="ROS bag: a topic of corrected poses (PoseStamped, "
                                                 "PoseWithCovarianceStamped or Odometry) to map with")
    parser.add_argument("--laser-offset", type=float, nargs=3, metavar=("X", "Y", "THETA"),
                        help="ROS bag: the laser's pose on the robot (m, m, rad; default: from tf_static)")


def _landmark_parser(sub, name: str, method: str, what: str, fields) -> None:
    """ekf-slam's or fastslam's parser: the dataset, the method's LandmarkRunOptions ``fields`` and
    the shared ones."""
    p = _command(sub, name, _cmd_landmarks, f"{what} on a landmark dataset (MRCLAM folder or Victoria Park file)")
    p.set_defaults(method=method)
    p.add_argument("dataset", nargs="?", help="a UTIAS MRCLAM folder, Victoria Park in iSAM/GTSAM text format, or the "
                                              "original Victoria Park run's folder; default: a bundled MRCLAM excerpt "
                                              "(Dataset 7, robot 1, 120 s)")
    sigmas = dict(zip(("sigma_v", "sigma_w", "sigma_r", "sigma_phi"), mrclam.MOTION_SIGMA + mrclam.MEASUREMENT_SIGMA))
    _described(p, LandmarkRunOptions(), ("unknown",) + fields + ("robot", "seconds", "raw_ranges", *sigmas, "refine"),
               defaults=sigmas)
    _outputs(p, name.replace("-", "_"), "PREFIX_trajectory.tum, PREFIX.png", "times in seconds (MRCLAM) or the pose's "
             "index (Victoria Park, whose file has no times)")


def build_parser() -> argparse.ArgumentParser:
    """The ``probslam`` command line: one subcommand per pipeline, each with its options (what they
    do on whole datasets: docs/cli.md)."""
    parser = _Parser(prog="probslam", description="Probabilistic robot mapping and SLAM.", epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"probslam {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = _command(sub, "map", _cmd_map, "occupancy grid map of a CARMEN laser log or ROS bag with known (corrected) "
                 "poses")
    _log_input(p, "a bundled excerpt of the Intel Research Lab log", poses=True)
    _described(p, MapOptions(), ("resolution", "max_range", "robot_radius", "inverse_model"),
               defaults={"resolution": f"{MAP_RESOLUTION:g}; with --inverse-model the model's own",
                         "max_range": f"{MAP_MAX_RANGE:g}; with --inverse-model the model's own"})
    p.add_argument("--keep-no-return", dest="skip_no_return", action="store_false",
                   help="let readings at the sensor maximum clear space (default: skip them)")
    _outputs(p, "map", "PREFIX.yaml/.pgm/.png")

    sl = _command(sub, "slam", _cmd_slam, "map a raw CARMEN laser log or ROS bag (odometry and scans): scan matching "
                  "into submaps, GraphSLAM over them with loop closures (ch. 11.7)")
    _log_input(sl, "a bundled raw excerpt of the Intel Research Lab log, one lap that closes its loop")
    sl.add_argument("--method", choices=("graph", "rbpf"), default="graph",
                    help="graph: GraphSLAM over submaps (default); rbpf: grid-based FastSLAM (particle filter)")
    graph, rbpf = SubmapSlamOptions(), GridFastSlamOptions()
    _described(sl, graph, SLAM_FIELDS["graph"][:3], defaults={"frontend.filter.max_range": "from the log",
                                                               "frontend.resolution": f"{graph.frontend.resolution}; "
                                                                                      "with --map the map's"})
    sl.add_argument("--no-loop-closures", action="store_false", default=None, help="scan matching and submaps only")
    sl.add_argument("--particles", type=int, help=f"rbpf: number of particles (default {rbpf.num_particles}, not "
                    f"fastslam's {LandmarkRunOptions.num_particles}: each carries a grid map; docs/cli.md)")
    _described(sl, rbpf, ("proposal", "seed", "threads"), prefix="rbpf: ")
    sl.add_argument("--save", metavar="RUN.psl", help="write the run's state to RUN.psl at the end or on Ctrl-C, for "
                                                      "--resume (docs/cli.md)")
    sl.add_argument("--map", metavar="MAP", help="start from a saved map (MAP.yaml, or an OccupancyGrid2D state file), "
                                                 "the run in its frame (docs/cli.md)")
    sl.add_argument("--initial-pose", type=float, nargs=3, metavar=("X", "Y", "THETA"),
                    help="with --map: the log's first scan in the map, m, m, rad (default 0 0 0)")
    sl.add_argument("--resume", metavar="RUN.psl", help="continue a run saved with --save from the next scan of the "
                                                        "same LOG, its method and options the saved ones")
    _outputs(sl, "slam", "PREFIX.yaml/.pgm/.png, PREFIX_trajectory.tum, PREFIX.g2o (graph only)",
             "the laser poses at the log's scan times (s)")

    lo = _command(sub, "localize", _cmd_localize, "Monte Carlo localization of a raw CARMEN log or ROS bag in a map "
                  "(ch. 8.3: KLD sampling, augmented MCL), tracking or global")
    _log_input(lo, "the bundled raw Intel loop (that of 'probslam slam') in its bundled map")
    lo.add_argument("--map", help="the map: a map_server YAML (e.g. probslam slam's PREFIX.yaml); needed with a LOG")
    lo.add_argument("--initial-pose", type=float, nargs=3, metavar=("X", "Y", "THETA"),
                    help="the start in the map's frame (m, m, rad): tracking")
    lo.add_argument("--global", dest="global_", action="store_true",
                    help="no start: particles uniform over free space (global localization)")
    _described(lo, MonteCarloLocalizationOptions(), ("sensor_model", "min_particles", "max_particles", "max_range",
                                                     "seed", "threads"), defaults={"max_range": "from the log"})
    _outputs(lo, "localize", "PREFIX_trajectory.tum, PREFIX.png", "the laser poses at the log's scan times (s)")

    _landmark_parser(sub, "ekf-slam", "ekf", "EKF SLAM", ("association", "bearing_offset"))
    _landmark_parser(sub, "fastslam", "fastslam", "FastSLAM 1.0 / 2.0", ("num_particles", "version", "seed", "threads"))

    o = _command(sub, "optimize", _cmd_optimize, "optimise a 2-D pose/landmark graph or a 3-D pose graph (g2o, TORO "
                 "or iSAM text; the dimension is read from the file)")
    o.add_argument("graph", nargs="?", help="graph file: .g2o, TORO .graph or iSAM .txt, 2-D or 3-D; default: the "
                   "Intel graph's first 400 poses (3-D: probslam.data.path('parking_garage_400.g2o'))")
    _described(o, GraphFileOptions(), [f.name for f in dataclasses.fields(GraphFileOptions)])
    o.add_argument("--edges", action="store_true", help="draw every edge in the picture")
    _outputs(o, "optimized", "PREFIX.g2o/.png, PREFIX_trajectory.tum",
             "a graph file has no times: each pose's vertex id is its time")

    ev = _command(sub, "eval", _cmd_eval, "score a trajectory against a ground truth: absolute or relative trajectory "
                  "error (as evo_ape / evo_rpe print them), or the relations error")
    ev.add_argument("estimate", metavar="EST", help="the trajectory to score: TUM, KITTI (times in NAME_times.txt) or "
                    "'t x y theta' rows, as the commands write it (PREFIX_trajectory.tum)")
    ev.add_argument("reference", metavar="REF", help="the ground truth: a trajectory file as EST, a relations file "
                    "(aces.relations), a CARMEN log with corrected poses, or 't x y' rows (a GPS track; docs/cli.md)")
    _described(ev, EvaluationOptions(), [f.name for f in dataclasses.fields(EvaluationOptions)])

    ba = _command(sub, "batch", _cmd_batch, "a sweep of runs (datasets x commands x option grids x seeds) on Dask "
                  "distributed, one row per run in DIR/results.parquet and results.csv (docs/batch.md; needs "
                  "'probslam[batch]')")
    ba.add_argument("sweep", metavar="SWEEP", help="the sweep: a TOML file (docs/batch.md; examples/sweep_demo.toml)")
    ba.add_argument("-o", "--output-dir", dest="directory", metavar="DIR", required=True, help="the folder of the "
                    "table (made if missing; no default); the runs whose rows are there are not made again")
    ba.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler (tcp://host:8786); default: "
                                                           "DASK_SCHEDULER_ADDRESS, else a local cluster")
    ba.add_argument("--workers", type=int, help="local cluster: worker processes of one thread (default: one per core)")
    ba.add_argument("--memory-limit", default="auto", help="local cluster: memory per worker, e.g. 4GB; a worker past "
                                                           "it is restarted and its run retried")
    ba.add_argument("--time-limit", type=float, metavar="S", help="seconds a run may take before it is recorded as "
                    "timeout (default: the sweep's time_limit, else none)")
    ba.add_argument("--trajectories", action="store_true", help="keep each run's trajectory in DIR/trajectories (TUM; "
                    "on a cluster DIR must be storage the workers share)")
    _outputs(ba, "", "")
    return parser


def _command(sub, name: str, func, text: str) -> argparse.ArgumentParser:
    parser = sub.add_parser(name, help=text)
    parser.set_defaults(func=func)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    """Runs the command line; the exit status (EPILOG). PROBSLAM_DEBUG=1 shows an unexpected error's
    traceback."""
    try:
        status = _run(argv)
        sys.stdout.flush()  # a pipe closed under buffered output shows here, not at exit
        return status
    except BrokenPipeError:
        # The reader stopped (probslam ... | head -1): quiet, the status of a tool killed by SIGPIPE;
        # the output left is dropped, not flushed into the closed pipe at exit.
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


def _run(argv: Optional[List[str]]) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    command = parser._command_parser(args)
    args.given, args.flags = _given_options(argv), _long_options(command)
    format_warning = warnings.formatwarning
    # A reader's warning (a few malformed lines skipped) as one line, without the source line.
    warnings.formatwarning = lambda message, category, *rest, **kw: f"probslam: warning: {message}\n"
    try:
        if getattr(args, "output", None) is not None:
            args.output = _output_prefix(args.output, command.get_default("output"))
            _check_output(args.output)  # before any data is read: a run may take minutes
        return args.func(args)
    except KeyboardInterrupt:
        print("probslam: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        raise
    except (UserError, ValueError, TypeError, OSError, ImportError) as exc:
        # Bad options (the library names the argument), unreadable or unwritable files.
        print(f"probslam: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - the last resort: one line, not a traceback
        if os.environ.get("PROBSLAM_DEBUG"):
            raise
        print(f"probslam: unexpected error: {type(exc).__name__}: {one_line(exc)} "
              "(a bug: please report it; PROBSLAM_DEBUG=1 shows the traceback)", file=sys.stderr)
        return 1
    finally:
        warnings.formatwarning = format_warning


def _long_options(*parsers: argparse.ArgumentParser) -> Dict[str, str]:
    """dest -> option (its long form) of every option of ``parsers``."""
    return {a.dest: next((o for o in a.option_strings if o.startswith("--")), a.option_strings[0])
            for p in parsers for a in p._actions if a.option_strings}


def _given_options(argv: Optional[List[str]]) -> Dict[str, str]:
    """dest -> option (its long form) of each option given: parsed again with no defaults."""
    parsers = [build_parser()]
    for p in parsers:
        p._defaults.clear()
        for action in p._actions:
            action.default = argparse.SUPPRESS
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
    flags = _long_options(*parsers)
    return {dest: flags.get(dest, dest.upper()) for dest in vars(parsers[0].parse_args(argv))}


def _output_prefix(output: str, stem: str) -> str:
    """-o as a prefix: a folder (existing, or ending in a slash) holds files of the command's name."""
    if output.endswith(("/", os.sep)) or os.path.isdir(output):
        return os.path.join(output, stem)
    return output


def _refuse_given(args: argparse.Namespace, dests, why: str) -> None:
    """UserError naming the first of ``dests`` given: it does not apply to this run (``why``)."""
    for dest in dests:
        if dest in args.given:
            raise UserError(f"{args.given[dest]} {why}")


if __name__ == "__main__":
    sys.exit(main())
