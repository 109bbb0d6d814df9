"""The kinds of run a sweep can make, as a registry: each kind says how its typed options are
made (``options()``: the defaults, set by name from the sweep), how one run goes on the library's
pipelines (``run``: a pure function of the run's inputs, no CLI), and which metrics its rows hold.
Adding a command to ``probslam batch`` is one ``register(RunKind(...))``.
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Mapping, Optional, Sequence, Tuple

import numpy as np

from .. import io
from .._core import GridFastSlamOptions, MonteCarloLocalizationOptions, SubmapSlamOptions
from ..datasets.landmark_dataset import LandmarkDataset
from ..io.laser_log import read_laser_log
from ..io.maps import FREE_THRESH, OCCUPIED_THRESH
from ..io.rosbag import is_bag
from ..localization import default_options
from ..pipelines import (EvaluationOptions, GraphFileOptions, LandmarkRunOptions, LogPiece, MapOptions, localize_log,
                         map_log, optimize_file, run_landmark_dataset, slam_log)
from ..pipelines._options import option_names
from ..slam import default_options as slam_default_options


@dataclass
class Outcome:
    """What a run gives back: its metrics (name -> a number, bool or text) and, when it makes a
    trajectory, how to write it (``write_trajectory(prefix) -> path``, for the score against a
    reference); ``also_scored``: other trajectories of the run scored against the same
    reference (name -> writer; their metrics named ``NAME_METRIC``: GraphSLAM's frontend alone);
    ``raw_log``: the CARMEN log whose scans the trajectories' rows are, row for row (a relations
    file's times and a corrected log's scans are then taken from it, ``EvaluationOptions.raw_log``,
    unless the sweep's evaluation names one)."""

    metrics: Dict[str, Any]
    write_trajectory: Optional[Callable[[str], str]] = None
    also_scored: Mapping[str, Callable[[str], str]] = field(default_factory=dict)
    raw_log: Optional[str] = None


@dataclass(frozen=True)
class RunKind:
    """A command of a sweep.

    name: as sweeps name it (the CLI command's name).
    options: the default options object of the kind (a pipeline's ``Options`` dataclass or a C++
        options class), whose fields a sweep sets by name.
    run: ``run(dataset, values, inputs) -> Outcome``: the run on a worker; ``values``: the
        sweep's options (name or dotted path -> value, the seed included), which it sets
        (``set_options``) on its defaults for the dataset.
    metrics: the names of the metrics its ``Outcome`` holds (the table's columns, in order).
    inputs: the kind's own keys in a sweep's group besides the dataset (name -> required).
    inputs_are_paths: which of those name files (resolved as datasets are).
    seeded: whether its options have a seed (a sweep's seeds set it; else seeds are refused).
    seed_option: the option (a dotted path) the seeds set: ``seed``, or the group's that holds it.
    scored: whether its runs make a trajectory to score against a reference (else one is refused).
    reads_reference: whether its run reads the reference too (``inputs["reference"]``: the path,
        or None; ``inputs["evaluation"]``: the score's EvaluationOptions fields), for what it
        scores itself or starts from.
    """

    name: str
    options: Callable[[], Any]
    run: Callable[[str, Any, Mapping[str, Any]], Outcome]
    metrics: Tuple[str, ...]
    inputs: Mapping[str, bool] = field(default_factory=dict)
    inputs_are_paths: Mapping[str, bool] = field(default_factory=dict)
    seeded: bool = False
    scored: bool = True
    seed_option: str = "seed"
    reads_reference: bool = False


#: Every kind by name, in the order registered.
KINDS: Dict[str, RunKind] = {}


def register(kind: RunKind) -> RunKind:
    """Adds (or replaces) ``kind`` in KINDS; returns it."""
    KINDS[kind.name] = kind
    return kind


def set_options(options: Any, values: Mapping[str, Any]) -> Any:
    """A validated copy of ``options`` with ``values`` set (name or dotted path into a
    sub-structure -> value): ValueError / TypeError naming the option."""
    for path, value in values.items():
        options = _set(options, path.split("."), value, path)
    return options


def _set(options: Any, parts: Sequence[str], value: Any, path: str) -> Any:
    name = parts[0]
    names = option_names(options)
    if name not in names:
        close = difflib.get_close_matches(name, names, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ValueError(f"unknown option {path!r} (the options here: {', '.join(names)}){hint}")
    if len(parts) > 1:
        value = _set(getattr(options, name), parts[1:], value, path)
    try:
        return options.replace(**{name: value})
    except (ValueError, TypeError) as exc:
        message = str(exc)
        raise type(exc)(message if path in message else f"{path}: {message}") from None


def _optimize(dataset: str, values, inputs) -> Outcome:
    run = optimize_file(dataset, set_options(GraphFileOptions(), values))
    report = run.report
    return Outcome({"poses": len(run.graph.pose_ids), "chi2_initial": run.initial_chi2, "chi2": run.graph.chi2(),
                    "iterations": int(report.iterations), "converged": run.converged},
                   lambda prefix: run.write(prefix)[-1])


class LocalizeOptions:
    """The localize kind's options: the filter's (``MonteCarloLocalizationOptions``) and the piece
    of the log it runs on (``pipelines.LogPiece``: ``start_scan``, ``segment_seconds``,
    ``splice_scan``), set by name side by side (``max_particles``, ``odometry.alpha1``,
    ``start_scan``)."""

    def __init__(self, filter: Optional[MonteCarloLocalizationOptions] = None, piece: Optional[LogPiece] = None):
        self.filter = MonteCarloLocalizationOptions() if filter is None else filter
        self.piece = LogPiece() if piece is None else piece

    def as_dict(self) -> Dict[str, Any]:
        return {**self.filter.as_dict(), **dataclasses.asdict(self.piece)}

    def replace(self, **fields) -> "LocalizeOptions":
        """A checked copy with ``fields`` set, each on the part that has it."""
        piece = {k: fields.pop(k) for k in PIECE_FIELDS if k in fields}
        return LocalizeOptions(self.filter.replace(**fields) if fields else self.filter, self.piece.replace(**piece))

    def __getattr__(self, name: str) -> Any:  # a sub-structure of the filter's (odometry.alpha1)
        if name in ("filter", "piece"):
            raise AttributeError(name)
        return getattr(self.filter, name)


#: The options of the localize kind that say which scans it runs on.
PIECE_FIELDS = tuple(f.name for f in dataclasses.fields(LogPiece))


def _localize(dataset: str, values, inputs) -> Outcome:
    log = read_laser_log(dataset)
    # The sweep's options over the log's own defaults (its no-return reading as max_range). A
    # piece without a seed of the sweep's is seeded by its start scan: each segment its own draws.
    options = set_options(LocalizeOptions(default_options(log)), values)
    filter_options, piece = options.filter, options.piece
    if "seed" not in values:
        filter_options = filter_options.replace(seed=piece.start_scan)
    run = localize_log(log, inputs["map"], filter_options, initial_pose=inputs.get("initial_pose"),
                       piece=None if piece == LogPiece() else piece, reference=inputs.get("reference"),
                       progress=False)
    r = run.result
    metrics = {"scans": len(r.timestamps), "updates": int(np.sum(r.updated)), "converged": run.converged,
               "convergence_time_s": r.convergence_time, "converged_fraction": r.converged_fraction,
               "particles_median": float(np.median(r.num_particles)), "particles_max": int(np.max(r.num_particles)),
               "particles_last": int(r.num_particles[-1]), "seconds": float(r.seconds),
               "real_time_factor": float(r.real_time_factor)}
    if run.reference is not None:  # aligned as the row's ATE is (the map's frame: align = false)
        metrics.update(run.reference_metrics(align=EvaluationOptions(**inputs.get("evaluation", {})).aligned))
    return Outcome(metrics, lambda prefix: run.write(prefix)[0])


def _map(dataset: str, values, inputs) -> Outcome:
    run = map_log(dataset, set_options(MapOptions(), values), progress=False)
    # Cells counted as its map file (io.save_ros_map, map_saver's thresholds) has them.
    p, m = run.grid.probability(), run.mapping
    return Outcome({"scans": int(m.scans), "beams": int(m.beams), "cells_updated": int(m.cells_updated),
                    "width": run.grid.width, "height": run.grid.height,
                    "occupied_cells": int(np.sum(p > OCCUPIED_THRESH)), "free_cells": int(np.sum(p < FREE_THRESH))})


#: The name GraphSLAM's frontend trajectory (incremental scan matching alone) is scored under.
FRONTEND = "frontend"


def _slam(method: str):
    def run(dataset: str, values, inputs) -> Outcome:
        log = read_laser_log(dataset)
        # The sweep's options over the log's own defaults (slam.default_options: its range, odometry).
        run = slam_log(log, set_options(slam_default_options(log, method), values), progress=False)
        r, s = run.result, run.result.summary
        metrics = {"scans": int(s.scans), "seconds": float(r.seconds), "real_time_factor": float(r.real_time_factor)}
        if method == "graph":
            metrics.update(submaps=int(s.submaps), closures_accepted=int(s.closures_accepted),
                           closures_rejected=int(s.closures_rejected))
        else:
            metrics.update(updates=int(s.updates), resamples=int(s.resamples))

        def writer(poses, name):
            return lambda prefix: io.write_trajectory(r.timestamps, poses, f"{prefix}_{name}.tum")[0]

        also = {} if r.frontend_poses is None else {FRONTEND: writer(r.frontend_poses, "frontend")}
        # A CARMEN log's trajectory has a pose per scan: relations and a corrected log are read against its scans.
        raw_log = None if is_bag(dataset) else dataset
        return Outcome(metrics, writer(r.poses, "trajectory"), also, raw_log)
    return run


def _landmarks(method: str):
    def run(dataset: str, values, inputs) -> Outcome:
        lr = run_landmark_dataset(dataset, set_options(LandmarkRunOptions(method=method), values), progress=False)
        r = lr.result
        metrics = {"poses": len(r.poses), "landmarks": len(r.landmarks), "filter_cpu_s": float(lr.cpu_seconds),
                   **lr.metrics}  # what the dataset's own reference scores, and the refinement's figures
        return Outcome(metrics, lambda prefix: io.write_trajectory(r.times, r.poses, prefix + "_trajectory.tum")[0])
    return run


register(RunKind("optimize", GraphFileOptions, _optimize, ("poses", "chi2_initial", "chi2", "iterations", "converged")))
register(RunKind("localize", LocalizeOptions, _localize,
                 ("scans", "updates", "converged", "convergence_time_s", "converged_fraction", "particles_median",
                  "particles_max", "particles_last", "seconds", "real_time_factor", "converged_to_reference",
                  "time_to_converge_s", "travel_to_converge_m", "error_median_m", "error_max_m",
                  "heading_error_median_deg", "jump_m", "tracked_before_jump"),
                 inputs={"map": True, "initial_pose": False}, inputs_are_paths={"map": True}, seeded=True,
                 reads_reference=True))
register(RunKind("map", MapOptions, _map,
                 ("scans", "beams", "cells_updated", "width", "height", "occupied_cells", "free_cells"), scored=False))
register(RunKind("slam", SubmapSlamOptions, _slam("graph"),
                 ("scans", "seconds", "real_time_factor", "submaps", "closures_accepted", "closures_rejected")))
register(RunKind("slam-rbpf", GridFastSlamOptions, _slam("rbpf"),
                 ("scans", "seconds", "real_time_factor", "updates", "resamples"), seeded=True))
LANDMARK_METRICS = ("poses", "landmarks", "filter_cpu_s") + LandmarkDataset.METRICS
register(RunKind("ekf-slam", lambda: LandmarkRunOptions(method="ekf"), _landmarks("ekf"), LANDMARK_METRICS))
register(RunKind("fastslam", lambda: LandmarkRunOptions(method="fastslam"), _landmarks("fastslam"), LANDMARK_METRICS,
                 seeded=True, seed_option="fastslam.seed"))


__all__ = ["KINDS", "LocalizeOptions", "Outcome", "PIECE_FIELDS", "RunKind", "option_names", "register", "set_options"]
