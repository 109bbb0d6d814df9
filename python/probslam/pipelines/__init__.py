"""Pipelines: a whole run from files to results (read, start, run, score, write, draw), each
taking one typed options object and returning a run that summarises, writes and draws itself.
The command line calls one pipeline per command and prints what it returns."""

from .optimize_file import GraphFileOptions, GraphFileRun, optimize_file
from .landmark_run import LandmarkRun, LandmarkRunOptions, run_landmark_dataset

__all__ = ["GraphFileOptions", "GraphFileRun", "optimize_file",
           "LandmarkRun", "LandmarkRunOptions", "run_landmark_dataset"]
