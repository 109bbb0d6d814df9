"""Pipelines: a whole run from files to results (read, start, run, score, write, draw), each
taking one typed options object and returning a run that summarises, writes and draws itself.
The command line calls one pipeline per command and prints what it returns."""

from .optimize_file import GraphFileOptions, GraphFileRun, optimize_file
from .map_log import MapOptions, MapRun, map_log
from .localize_log import (SNAPSHOT_TRAVEL, TRACK_JUMP, LocalizationRun, convergence_report, converged_track,
                           localize_log, snapshot_times)
from .evaluate_trajectory import EvaluationOptions, TrajectoryEvaluation, evaluate_trajectory, reference_kind
from .landmark_run import LandmarkRun, LandmarkRunOptions, run_landmark_dataset
from .slam_log import SlamLogRun, slam_log

__all__ = ["GraphFileOptions", "GraphFileRun", "optimize_file",
           "MapOptions", "MapRun", "map_log",
           "LocalizationRun", "SNAPSHOT_TRAVEL", "TRACK_JUMP", "convergence_report", "converged_track", "localize_log",
           "snapshot_times",
           "EvaluationOptions", "TrajectoryEvaluation", "evaluate_trajectory", "reference_kind",
           "LandmarkRun", "LandmarkRunOptions", "run_landmark_dataset",
           "SlamLogRun", "slam_log"]
