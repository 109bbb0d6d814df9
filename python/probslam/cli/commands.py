"""The ``probslam`` commands, each: its flags to one pipeline's options, the pipeline run, what its
run says, writes and draws printed (``COMMANDS``: the function of each subcommand)."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from typing import List, Optional

from .. import localization
from ..data import path as data_path
from ..pipelines import (EvaluationOptions, GraphFileOptions, GraphFileRun, LandmarkRun, LandmarkRunOptions,
                         MapOptions, MapRun, TrajectoryEvaluation, localize_log, slam_log)
from ..pipelines.inputs import BAG_OPTIONS, read_log
from ..slam import OPTIONS_CLASSES, RunInterrupted, with_fields
from .messages import EXIT_INTERRUPTED, EXIT_NOT_CONVERGED, UserError, refuse_given, told
from .parser import LANDMARK_FLAGS, SLAM_FLAGS, dest, flag

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
#: A ROS bag's reader parameters (``inputs.read_log``) told as their flags.
BAG_FLAGS = {name: flag(name) for name in BAG_OPTIONS}


def _save_figure(plt, fig, path: str) -> str:
    """`fig` written to `path` (120 dpi, the box fitted to what is drawn, a legend beside included)."""
    fig.tight_layout()
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def _picture(run, args: argparse.Namespace, **draw) -> List[str]:
    """[PREFIX.png] drawn by the run (``draw``), without matplotlib its plain picture if it has one."""
    from ..plot import require_matplotlib

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
    with told(BAG_FLAGS, path=path):
        return read_log(path, **bag)


def _options(options, args: argparse.Namespace):
    """``options.replace`` with the field of each flag given (its dest), refusals told as the flags."""
    fields = options.as_dict() if hasattr(options, "as_dict") else vars(options)
    with told(args.flags, args):
        return options.replace(**{k: getattr(args, k) for k in fields
                                  if k in args.flags and getattr(args, k) is not None})


def _cmd_map(args: argparse.Namespace) -> int:
    options = _options(MapOptions(), args)
    path, t0 = args.log or data_path(BUNDLED_LOG), time.perf_counter()
    log = _read_log(path, args)
    with told(args.flags, args):
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
    for option, value in (("--scan-topic", args.scan_topic), ("--odom-topic", args.odom_topic),
                          ("--trajectory-format", None if args.trajectory_format == "tum" else args.trajectory_format),
                          ("-o", None if args.output == "slam" else args.output)):
        words += [option, value] if value is not None else []
    words += ["--laser-offset"] + [repr(float(v)) for v in args.laser_offset] if args.laser_offset else []
    return shlex.join(words + ["--resume", run_file, "--save", run_file] + ([] if args.plot else ["--no-plot"]))


def _cmd_slam(args: argparse.Namespace) -> int:
    dests = {method: [dest(option) for option in flags.values()] for method, flags in SLAM_FLAGS.items()}
    if args.resume is not None:
        refuse_given(args, ["method", *dests["graph"], *dests["rbpf"]],
                     "does not apply with --resume (the run goes on with its saved options)")
    other = dests["rbpf" if args.method == "graph" else "graph"]
    refuse_given(args, [d for d in other if d not in dests[args.method]], f"does not apply to --method {args.method}")
    flags = SLAM_FLAGS[args.method]
    given = {path: getattr(args, dest(option)) for path, option in flags.items() if option in args.given.values()}
    with told(flags, args):
        with_fields(OPTIONS_CLASSES[args.method](), given)  # the library checks the flags before the log is read
    path = args.log or data_path(BUNDLED_SLAM_LOG)
    log = _read_log(path, args)
    try:
        with told({**flags, "initial_map": "--map", "initial_pose": "--initial-pose", "save": "--save"}, args):
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
        args.log, args.map = data_path(BUNDLED_RAW_LOG), data_path(BUNDLED_LOCALIZATION_MAP)
        print("probslam localize: no LOG given: the bundled raw Intel loop in its bundled map, from a global start "
              "(particles anywhere in free space); give LOG --map MAP.yaml for your own", flush=True)
    elif args.map is None:
        raise UserError("--map: give the map to localize in (a map_server YAML, e.g. probslam slam's PREFIX.yaml)")
    elif args.log is None:
        raise UserError("--map given without a LOG: name the log to localize")
    log = _read_log(args.log, args)
    options = _options(localization.default_options(log.scans), args)
    with told(args.flags, args):
        run = localize_log(log, args.map, options, initial_pose=args.initial_pose, progress=_progress(args))
    written = run.write(args.output, args.trajectory_format) + _picture(
        run, args, title=f"probslam localize: {os.path.basename(args.log)} in {os.path.basename(args.map)}")
    print(run.summary(args.log, args.map, written))
    return 0 if run.converged else EXIT_NOT_CONVERGED


def _cmd_landmarks(args: argparse.Namespace) -> int:
    """ekf-slam and fastslam: ``pipelines.LandmarkRun`` on the dataset argument."""
    flags = {**args.flags, **LANDMARK_FLAGS[args.method]}  # the library's messages name a group's fields by path
    given = {path: getattr(args, path.rsplit(".", 1)[-1]) for path in LANDMARK_FLAGS[args.method]
             if path.rsplit(".", 1)[-1] in args.given}
    with told(flags, args):
        options = with_fields(LandmarkRunOptions(method=args.method), given)
    t0, path = time.perf_counter(), args.dataset or data_path(BUNDLED_LANDMARKS)
    with told(flags, args):
        run = LandmarkRun.read(path, options)
        run.run(_progress(args))
    print(run.summary())
    written = _picture(run, args) + run.write(args.output, args.trajectory_format)
    print(f"time:          {time.perf_counter() - t0:.2f} s total")
    print(f"wrote:         {', '.join(written)}")
    return 0


def _cmd_optimize(args: argparse.Namespace) -> int:
    if not args.plot:
        refuse_given(args, ("edges",), "draws in the picture, which --no-plot leaves out")
    options = _options(GraphFileOptions(), args)
    path = args.graph or data_path(BUNDLED_GRAPH)
    with told(args.flags, args):
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
    run = TrajectoryEvaluation.read_estimate(args.estimate, _options(EvaluationOptions(), args))
    print(run.estimate_summary())
    with told(args.flags, args):
        run.read_reference(args.reference)
    print(run.reference_summary())
    for note in run.notes:
        print(f"probslam: note: {note}", file=sys.stderr)
    with told(args.flags, path=args.estimate):  # the score's messages say the values
        run.score()
    print(run.summary(), end="")
    return 0


def _cmd_batch(args: argparse.Namespace) -> int:
    from .. import batch

    sweep = batch.load(args.sweep)  # its own refusals name its keys, not flags
    try:  # a sweep refused, or dask missing: before a folder is made or a worker started
        with told(args.flags, args):
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


#: The function that runs each subcommand.
COMMANDS = {"map": _cmd_map, "slam": _cmd_slam, "localize": _cmd_localize, "ekf-slam": _cmd_landmarks,
            "fastslam": _cmd_landmarks, "optimize": _cmd_optimize, "eval": _cmd_eval, "batch": _cmd_batch}
