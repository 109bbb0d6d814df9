"""Pipelines: a whole run from files to results (read, start, run, score, write, draw), each
taking one typed options object and returning a run that summarises, writes and draws itself.
The command line calls one pipeline per command and prints what it returns. Each module is named
for what it runs (``graph_file``, ``map_run``, ``localization_run``, ``evaluation``,
``landmark_run``, ``slam_run``), never as a function the package exports, so that
``pipelines.optimize_file`` is the function and ``pipelines.graph_file`` its module."""

from .graph_file import GraphFileOptions, GraphFileRun, optimize_file
from .map_run import MapOptions, MapRun, map_log
from .localization_run import (CLOCK_JUMP, FROM_REFERENCE, SNAPSHOT_TRAVEL, TRACK_JUMP, LocalizationRun, LogPiece,
                               convergence_report, converged_track, localize_log, reference_poses, snapshot_times,
                               span_end, splice)
from .evaluation import EvaluationOptions, TrajectoryEvaluation, evaluate_trajectory, reference_kind
from .landmark_run import LandmarkRun, LandmarkRunOptions, RefinementOptions, run_landmark_dataset
from .slam_run import SlamLogRun, slam_log

__all__ = ["GraphFileOptions", "GraphFileRun", "optimize_file",
           "MapOptions", "MapRun", "map_log",
           "CLOCK_JUMP", "FROM_REFERENCE", "LocalizationRun", "LogPiece", "SNAPSHOT_TRAVEL", "TRACK_JUMP",
           "convergence_report", "converged_track", "localize_log", "reference_poses", "snapshot_times", "span_end",
           "splice",
           "EvaluationOptions", "TrajectoryEvaluation", "evaluate_trajectory", "reference_kind",
           "LandmarkRun", "LandmarkRunOptions", "RefinementOptions", "run_landmark_dataset",
           "SlamLogRun", "slam_log"]
