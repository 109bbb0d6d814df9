"""The ``probslam`` command line's parser: one subcommand per pipeline, the flags that set an
options field made from the field's description (``described``), usage errors as one line that
names the subcommand's -h and the option or choice meant."""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import functools
import os
import re
from typing import Dict, List, Optional

from .. import __version__
from .._core import GridFastSlamOptions, MonteCarloLocalizationOptions, SubmapSlamOptions
from ..datasets import mrclam
from ..io.trajectory import TRAJECTORY_FORMATS
from ..mapping import DEFAULT_MAX_RANGE as MAP_MAX_RANGE, DEFAULT_RESOLUTION as MAP_RESOLUTION
from ..pipelines import EvaluationOptions, GraphFileOptions, LandmarkRunOptions, MapOptions
from .messages import EPILOG, EXIT_USER_ERROR

#: How close a misspelt option or choice must be to one of the parser's to be suggested
#: (difflib's ratio: 0.6, its own default, takes --partcles for --particles, not --seed for --robot).
SUGGESTION_CUTOFF = 0.6
#: slam's option fields by method (SubmapSlamOptions / GridFastSlamOptions paths), each set by the
#: flag of its last name (FLAG_NAMES where the flag's name differs).
SLAM_FIELDS = {"graph": ("frontend.resolution", "frontend.filter.max_range", "frontend.submap_distance",
                         "closures.enabled"),
               "rbpf": ("num_particles", "proposal", "seed", "threads", "resolution", "filter.max_range")}
#: ekf-slam's and fastslam's own option fields by method (LandmarkRunOptions paths, its groups' fields
#: by dotted path), each set by the flag of its last name (FLAG_NAMES where the flag's name differs);
#: LANDMARK_SHARED_FIELDS are both commands'.
LANDMARK_FIELDS = {"ekf": ("association", "hypotheses.bearing_offset_sigma"),
                   "fastslam": ("fastslam.num_particles", "fastslam.version", "fastslam.seed", "fastslam.threads")}
LANDMARK_SHARED_FIELDS = ("robot", "seconds", "raw_ranges", "sigma_v", "sigma_w", "sigma_r", "sigma_phi", "refine")
FLAG_NAMES = {"num_particles": "--particles", "version": "--variant", "closures.enabled": "--no-loop-closures",
              "raw_log": "--log", "hypotheses.bearing_offset_sigma": "--bearing-offset"}


def flag(path: str) -> str:
    """The flag that sets the option field at ``path`` (FLAG_NAMES by path, else by last name)."""
    name = path.rsplit(".", 1)[-1]
    return FLAG_NAMES.get(path) or FLAG_NAMES.get(name) or "--" + name.replace("_", "-")


def dest(option: str) -> str:
    """The dest of a long option (--no-loop-closures: no_loop_closures)."""
    return option[2:].replace("-", "_")


#: slam's flags by method: the option path each sets (the library's messages, which name the path,
#: told as the flag). A flag's value is its dest's (--no-loop-closures stores False).
SLAM_FLAGS = {method: {path: flag(path) for path in paths} for method, paths in SLAM_FIELDS.items()}
#: ekf-slam's and fastslam's flags by method: the option path each sets.
LANDMARK_FLAGS = {method: {path: flag(path) for path in ("unknown",) + paths + LANDMARK_SHARED_FIELDS}
                  for method, paths in LANDMARK_FIELDS.items()}


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Every option that takes a value shows its default ("none": off unless given), unless its
    help says it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if (not action.option_strings or action.nargs == 0 or action.default is argparse.SUPPRESS
                or "default" in text.lower()):
            return text
        return text + (" (default: none)" if action.default is None else " (default: %(default)s)")


class Parser(argparse.ArgumentParser):
    """argparse with its usage errors as one line on stderr (exit status 2), like every other user
    error, naming the subcommand's -h and the option or choice meant when one is close."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, formatter_class=_HelpFormatter, **kwargs)

    def error(self, message: str):
        choice = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if choice:
            message += _did_you_mean(choice.group(1), re.findall(r"'([^']*)'", choice.group(2)))
        self.exit(EXIT_USER_ERROR, f"{self.prog}: error: {message} (see '{self.prog} -h')\n")

    def parse_args(self, args=None, namespace=None):
        """An unknown option reported by the subcommand's parser, with the nearest of its options."""
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            parser = self.command_parser(parsed)
            options = [o for p in (parser, self) for a in p._actions for o in a.option_strings]
            unknown = next((word.split("=", 1)[0] for word in extras if word.startswith("-")), "")
            parser.error(f"unrecognized arguments: {' '.join(extras)}"
                         + (_did_you_mean(unknown, options) if unknown else ""))
        return parsed

    def command_parser(self, parsed: argparse.Namespace) -> argparse.ArgumentParser:
        """The parser of the subcommand in ``parsed`` (this one without)."""
        sub = next(a for a in self._actions if isinstance(a, argparse._SubParsersAction))
        return sub.choices.get(getattr(parsed, sub.dest, None), self)


def _did_you_mean(word: str, candidates: List[str]) -> str:
    close = difflib.get_close_matches(word, candidates, n=1, cutoff=SUGGESTION_CUTOFF)
    return f"; did you mean {close[0]}?" if close else ""


def build_parser() -> Parser:
    """The ``probslam`` command line: one subcommand per pipeline, each with its options (what they
    do on whole datasets: docs/cli.md); ``commands.COMMANDS`` runs each."""
    parser = Parser(prog="probslam", description="Probabilistic robot mapping and SLAM.", epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"probslam {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("map", help="occupancy grid map of a CARMEN laser log or ROS bag with known (corrected) poses")
    _log_input(p, "a bundled excerpt of the Intel Research Lab log", poses=True)
    _described(p, MapOptions(), ("resolution", "max_range", "robot_radius", "inverse_model"),
               defaults={"resolution": f"{MAP_RESOLUTION:g}; with --inverse-model the model's own",
                         "max_range": f"{MAP_MAX_RANGE:g}; with --inverse-model the model's own"})
    p.add_argument("--keep-no-return", dest="skip_no_return", action="store_false",
                   help="let readings at the sensor maximum clear space (default: skip them)")
    _outputs(p, "map", "PREFIX.yaml/.pgm/.png")

    sl = sub.add_parser("slam", help="map a raw CARMEN laser log or ROS bag (odometry and scans): scan matching "
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
                    f"fastslam's {LandmarkRunOptions().fastslam.num_particles}: each carries a grid map; docs/cli.md)")
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

    lo = sub.add_parser("localize", help="Monte Carlo localization of a raw CARMEN log or ROS bag in a map (ch. 8.3: "
                        "KLD sampling, augmented MCL), tracking or global")
    _log_input(lo, "the bundled raw Intel loop (that of 'probslam slam') in its bundled map")
    lo.add_argument("--map", help="the map: a map_server YAML (e.g. probslam slam's PREFIX.yaml); needed with a LOG")
    lo.add_argument("--initial-pose", type=float, nargs=3, metavar=("X", "Y", "THETA"),
                    help="the start in the map's frame (m, m, rad): tracking")
    lo.add_argument("--global", dest="global_", action="store_true",
                    help="no start: particles uniform over free space (global localization)")
    _described(lo, MonteCarloLocalizationOptions(), ("sensor_model", "min_particles", "max_particles", "max_range",
                                                     "seed", "threads"), defaults={"max_range": "from the log"})
    _outputs(lo, "localize", "PREFIX_trajectory.tum, PREFIX.png", "the laser poses at the log's scan times (s)")

    _landmark_parser(sub, "ekf-slam", "ekf", "EKF SLAM")
    _landmark_parser(sub, "fastslam", "fastslam", "FastSLAM 1.0 / 2.0")

    o = sub.add_parser("optimize", help="optimise a 2-D pose/landmark graph or a 3-D pose graph (g2o, TORO or iSAM "
                       "text; the dimension is read from the file)")
    o.add_argument("graph", nargs="?", help="graph file: .g2o, TORO .graph or iSAM .txt, 2-D or 3-D; default: the "
                   "Intel graph's first 400 poses (3-D: probslam.data.path('parking_garage_400.g2o'))")
    _described(o, GraphFileOptions(), [f.name for f in dataclasses.fields(GraphFileOptions)])
    o.add_argument("--edges", action="store_true", help="draw every edge in the picture")
    _outputs(o, "optimized", "PREFIX.g2o/.png, PREFIX_trajectory.tum",
             "a graph file has no times: each pose's vertex id is its time")

    ev = sub.add_parser("eval", help="score a trajectory against a ground truth: absolute or relative trajectory "
                        "error (as evo_ape / evo_rpe print them), or the relations error")
    ev.add_argument("estimate", metavar="EST", help="the trajectory to score: TUM, KITTI (times in NAME_times.txt) or "
                    "'t x y theta' rows, as the commands write it (PREFIX_trajectory.tum)")
    ev.add_argument("reference", metavar="REF", help="the ground truth: a trajectory file as EST, a relations file "
                    "(aces.relations), a CARMEN log with corrected poses, or 't x y' rows (a GPS track; docs/cli.md)")
    _described(ev, EvaluationOptions(), [f.name for f in dataclasses.fields(EvaluationOptions)])

    ba = sub.add_parser("batch", help="a sweep of runs (datasets x commands x option grids x seeds) on Dask "
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


def _landmark_parser(sub, name: str, method: str, what: str) -> None:
    """ekf-slam's or fastslam's parser: the dataset, the method's LandmarkRunOptions fields
    (LANDMARK_FLAGS) and the shared ones."""
    p = sub.add_parser(name, help=f"{what} on a landmark dataset (MRCLAM folder or Victoria Park file)")
    p.set_defaults(method=method)
    p.add_argument("dataset", nargs="?", help="a UTIAS MRCLAM folder, Victoria Park in iSAM/GTSAM text format, or the "
                                              "original Victoria Park run's folder; default: a bundled MRCLAM excerpt "
                                              "(Dataset 7, robot 1, 120 s)")
    sigmas = dict(zip(("sigma_v", "sigma_w", "sigma_r", "sigma_phi"), mrclam.MOTION_SIGMA + mrclam.MEASUREMENT_SIGMA))
    _described(p, LandmarkRunOptions(), LANDMARK_FLAGS[method], defaults=sigmas, overrides={
        "hypotheses.bearing_offset_sigma": dict(prefix="MRCLAM, --association mht: "),
        "fastslam.num_particles": dict(doc="number of particles (a particle holds a few landmarks, not a grid map)"),
        "fastslam.version": dict(choices=(1, 2))})
    _outputs(p, name.replace("-", "_"), "PREFIX_trajectory.tum, PREFIX.png", "times in seconds (MRCLAM) or the pose's "
             "index (Victoria Park, whose file has no times)")


def _described(parser: argparse.ArgumentParser, options, paths, prefix: str = "",
               defaults: Optional[Dict[str, str]] = None, overrides: Optional[Dict[str, dict]] = None):
    """A flag (``flag``, dest the field's name) for each field at ``paths`` of ``options`` (a bound
    options class's or pipeline options dataclass's instance: the defaults shown, ``defaults`` the
    text of those the run sets) from the field's description (``overrides``: a path's own doc,
    choices or prefix, where the library's text says less on this command); None until given (the
    run's own)."""
    for path in paths:
        *groups, name = path.split(".")
        owner = functools.reduce(getattr, groups, options)
        value, meta = getattr(owner, name), {**_description(owner, name), **(overrides or {}).get(path, {})}
        doc = re.sub(r"``(\w+)``", lambda m: flag(m.group(1)) if hasattr(owner, m.group(1)) else m.group(1),
                     meta.get("prefix", prefix) + meta["doc"].replace("%", "%%"))
        none = re.search(r" ?\(None: ([^)]*)\)", doc) if value is None else None  # what None means: the default
        doc, shown = (doc.replace(none.group(0), ""), none.group(1)) if none else (doc, value)
        shown = (defaults or {}).get(path, shown)
        text = doc + (f", {meta['unit']}" if meta["unit"] else "") + ("" if shown is None or (
            value is False) else f" (default: {shown})")
        kind = meta.get("type") or (str if value is None else type(value))
        if kind is bool:  # off by default, or None (--X / --no-X); a field on by default is written by hand
            action = argparse.BooleanOptionalAction if value is None else "store_true"
            parser.add_argument(flag(path), dest=name, action=action, help=text)
            continue
        # A bound options class's text field: the names its doc quotes (a dataclass field has its own).
        quoted = re.findall(r'"([^"]+)"', doc) if kind is str and "type" not in meta else None
        choices = meta.get("choices") or quoted or None
        parser.add_argument(flag(path), dest=name, default=None, choices=choices, type=None if kind is str else kind,
                            metavar=None if choices else dest(flag(path)).upper(), help=text)


def _description(owner, name: str) -> dict:
    """A field's doc, unit, choices, type: a dataclass's (``described``) or a bound class's property doc."""
    if dataclasses.is_dataclass(owner):
        return next(f.metadata for f in dataclasses.fields(owner) if f.name == name)
    unit, doc = re.match(r"\w+(?: \((.*?)\))?: (.*)", getattr(type(owner), name).__doc__, re.S).groups()
    return dict(doc=doc, unit=unit or "")


def _outputs(parser, name: str, files: str, times: Optional[str] = None) -> None:
    """-o (``name``: default prefix, ``files``), --trajectory-format (``times``), --no-plot, --no-progress."""
    if name:
        parser.add_argument("-o", "--output", default=name, help=f"output prefix: {files} (default '{name}')")
    if times:
        parser.add_argument("--trajectory-format", choices=TRAJECTORY_FORMATS, default="tum",
                            help="PREFIX_trajectory.tum: TUM rows 't x y z qx qy qz qw' (default; evo reads it), "
                                 "PREFIX_trajectory.kitti: KITTI 3x4 [R|t] rows with the times in "
                                 f"PREFIX_trajectory_times.txt, or PREFIX_trajectory.txt: 't x y theta'; {times}")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="never show a progress bar")
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


def long_options(*parsers: argparse.ArgumentParser) -> Dict[str, str]:
    """dest -> option (its long form) of every option of ``parsers``."""
    return {a.dest: next((o for o in a.option_strings if o.startswith("--")), a.option_strings[0])
            for p in parsers for a in p._actions if a.option_strings}


def given_options(argv: Optional[List[str]]) -> Dict[str, str]:
    """dest -> option (its long form) of each option given: parsed again with no defaults."""
    parsers = [build_parser()]
    for p in parsers:
        p._defaults.clear()
        for action in p._actions:
            action.default = argparse.SUPPRESS
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
    flags = long_options(*parsers)
    return {d: flags.get(d, d.upper()) for d in vars(parsers[0].parse_args(argv))}


def output_prefix(output: str, stem: str) -> str:
    """-o as a prefix: a folder (existing, or ending in a slash) holds files of the command's name."""
    if output.endswith(("/", os.sep)) or os.path.isdir(output):
        return os.path.join(output, stem)
    return output
