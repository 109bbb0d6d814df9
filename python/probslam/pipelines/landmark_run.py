"""A landmark dataset from disk to its map (``probslam ekf-slam`` / ``fastslam``): read it (an
MRCLAM folder, Victoria Park as iSAM / GTSAM text, or the original Victoria Park run), run EKF SLAM
or FastSLAM over it, refine the run by GraphSLAM's correspondence test if asked, score it against
the dataset's reference (ground truth, survey, GPS), then write its trajectory and draw it.
``run_landmark_dataset(path, options)`` runs it all; ``LandmarkRun`` runs it step by step.
Options travel as one ``LandmarkRunOptions``; every refusal names its field. What differs between
the datasets is theirs (``datasets.LandmarkDataset``), not this module's.
"""

from __future__ import annotations

import math
import os
import pathlib
import time
from dataclasses import asdict, dataclass, fields
from typing import Dict, List, Optional, Union

import numpy as np

from ._options import Options, described, described_group, group_message, option_names
from .inputs import LANDMARK_DATASET, reading
from .. import io
from .._args import differing_field, require_instance
from .._core import FastSlamOptions, MultiHypothesisOptions
from ..datasets import LandmarkDataset, DatasetScore, RefinedRun, landmark_dataset_class, mrclam
from ..landmark_refine import MAX_ITERATIONS, MERGE_PROBABILITY, SPLIT_RUN_PROBABILITY, check_options
from ..landmark_slam import LandmarkSlamResult

PathLike = Union[str, "os.PathLike[str]"]

#: The filters: EKF SLAM (with hidden correspondences: JCBB, maximum likelihood or the
#: multiple-hypothesis EKF) and FastSLAM 1.0 / 2.0.
METHODS = ("ekf", "fastslam")
#: The EKF's associations with hidden correspondences (None: the dataset's default, see
#: ``datasets.mrclam.DEFAULT_ASSOCIATION``).
ASSOCIATIONS = ("jcbb", "ml", "mht")
#: What follows the filter: nothing, or GraphSLAM's correspondence test (ch. 11.6).
REFINEMENTS = ("none", "graphslam")
#: The command each method is, for the picture's title.
COMMANDS = {"ekf": "ekf-slam", "fastslam": "fastslam"}
#: The options that say how a path is read (not for a dataset given as read).
READ_OPTIONS = ("robot", "seconds", "raw_ranges")


@dataclass
class RefinementOptions(Options):
    """How ``refine`` graphslam refines a run: ``landmark_refine.refine_landmarks``' options
    (docs/landmark_refine.md)."""

    merge_probability: float = described(MERGE_PROBABILITY, "two landmarks merge when their difference is within "
                                                             "the chi-square quantile at this probability (2 dof)")
    split_probability: float = described(SPLIT_RUN_PROBABILITY, "the split gate's: the probability that no correct "
                                                                 "sighting of the run leaves its landmark")
    max_iterations: int = described(MAX_ITERATIONS, "rounds of optimise, test and change at most")
    estimate_noise: bool = described(True, "rescale the odometry and sensor noise to the first optimum's residuals "
                                           "before the first test")
    new_landmarks: bool = described(False, "a sighting that leaves its landmark and fits no other founds a landmark "
                                           "(else it is left on none)")

    def validate(self) -> None:
        """ValueError / TypeError naming the first field out of range or of the wrong type."""
        check_options(**asdict(self))


@dataclass
class LandmarkRunOptions(Options):
    """How ``run_landmark_dataset`` runs a landmark dataset. MRCLAM's options (robot, seconds,
    raw_ranges, sigma_*) are refused on Victoria Park, which takes its file's or its sensors' noise.
    The filters' own options are their options objects (``fastslam``, ``hypotheses``), set whole, by
    a dict of their fields, or field by field by dotted path (``fastslam.num_particles`` in a sweep);
    the dataset's own values (its noise, its sensor's field) apply where they hold their defaults."""

    method: str = described("ekf", "EKF SLAM (Tables 10.1 / 10.2) or FastSLAM", choices=METHODS)
    unknown: bool = described(False, "hide the correspondences (always hidden on the original Victoria Park run; "
                                     "its EKF takes the file's)")
    association: Optional[str] = described(None, "with ``unknown``, EKF: joint compatibility, maximum likelihood or "
                                                 "multiple hypotheses (None: mht on MRCLAM, jcbb elsewhere)",
                                           choices=ASSOCIATIONS)
    hypotheses: MultiHypothesisOptions = described_group(
        MultiHypothesisOptions, "MRCLAM, ``association`` mht: the multiple-hypothesis EKF's beam and costs (those left "
                                "at their defaults take MRCLAM's: mrclam.run_ekf)")
    fastslam: FastSlamOptions = described_group(
        FastSlamOptions, "method fastslam: FastSLAM's options (those left at their defaults take the dataset's: "
                         "fastslam.dataset_options)")
    robot: Optional[int] = described(None, "MRCLAM robot number (None: 1)", type=int)
    seconds: Optional[float] = described(None, "MRCLAM: only the first seconds of the robot's odometry (None: all)",
                                         "s", type=float)
    raw_ranges: bool = described(False, "MRCLAM's readings as ranges (by default they are taken as the camera's depth "
                                        "and turned into distances, io.MRCLAM_RANGE_SCALE)")
    sigma_v: Optional[float] = described(None, "MRCLAM odometry noise per 10 ms command (None: mrclam.MOTION_SIGMA)",
                                         "m/s", type=float)
    sigma_w: Optional[float] = described(None, "MRCLAM odometry noise per 10 ms command (None: mrclam.MOTION_SIGMA)",
                                         "rad/s", type=float)
    sigma_r: Optional[float] = described(None, "MRCLAM range noise (None: mrclam.MEASUREMENT_SIGMA)", "m",
                                         type=float)
    sigma_phi: Optional[float] = described(None, "MRCLAM bearing noise (None: mrclam.MEASUREMENT_SIGMA)", "rad",
                                           type=float)
    refine: str = described("none", "with ``unknown``: after the filter, GraphSLAM over all sightings with the "
                                    "correspondence test of ch. 11.6 (docs/landmark_refine.md)", choices=REFINEMENTS)
    refinement: RefinementOptions = described_group(RefinementOptions, "with ``refine`` graphslam: its options")

    def validate(self) -> None:
        """ValueError / TypeError naming the first field that is wrong or does not apply (the
        dataset's own refusals come when it is known: ``LandmarkRun.read``)."""
        for name, choices in (("method", METHODS), ("refine", REFINEMENTS)):
            if getattr(self, name) not in choices:
                raise ValueError(f"{name} must be one of {', '.join(choices)}, got {getattr(self, name)!r}")
        for name in ("unknown", "raw_ranges"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise TypeError(f"{name} must be a bool, got {type(getattr(self, name)).__name__}")
        if self.association is not None:
            if self.association not in ASSOCIATIONS:
                raise ValueError(f"association must be one of {', '.join(ASSOCIATIONS)}, got {self.association!r}")
            if self.method != "ekf":
                raise ValueError("association applies to method ekf only (FastSLAM's particles associate by "
                                 "maximum likelihood)")
            if not self.unknown:
                raise ValueError("association applies with unknown correspondences only (known correspondences need "
                                 "no association)")
        for name, applies, why in (("hypotheses", self.method == "ekf", "applies to method ekf only"),
                                   ("fastslam", self.method == "fastslam", "applies to method fastslam only"),
                                   ("refinement", self.refine != "none", "applies with refine graphslam only")):
            group = getattr(self, name)
            require_instance(group, type(_DEFAULT_GROUPS[name]), name)
            try:
                group.validate()
            except (TypeError, ValueError) as exc:
                raise type(exc)(group_message(name, str(exc), option_names(group))) from None
            changed = differing_field(group, _DEFAULT_GROUPS[name])
            if changed is not None and not applies:
                raise ValueError(f"{name}.{changed} {why}")
        if self.robot is not None:
            _integer(self.robot, "robot", 1, mrclam.ROBOTS, what=f"an MRCLAM robot number 1 to {mrclam.ROBOTS}")
        if self.seconds is not None:
            _real(self.seconds, "seconds")
        for name in ("sigma_v", "sigma_w", "sigma_r", "sigma_phi"):
            value = getattr(self, name)
            sigma = None if value is None else _real(value, name, zero=None)
            # Squared, a negative sigma would pass unnoticed, 1e300 overflow and 1e-200 vanish.
            if sigma is not None and not (0 < sigma < math.inf and 0 < sigma * sigma < math.inf):
                raise ValueError(f"{name} {value} must be a finite standard deviation > 0 with a finite variance > 0")


#: Each group's defaults, which a method that does not take it must leave as they are.
_DEFAULT_GROUPS = {"hypotheses": MultiHypothesisOptions(), "fastslam": FastSlamOptions(),
                   "refinement": RefinementOptions()}
#: Every option by its path (a group's fields as group.field): a message naming one is about the
#: options, not the file read.
_OPTION_PATHS = [f.name for f in fields(LandmarkRunOptions)] + [
    f"{group}.{name}" for group, default in _DEFAULT_GROUPS.items() for name in option_names(default)]


def _integer(value, name: str, lowest: int, highest: Optional[int], what: str = "") -> None:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < lowest or (highest is not None and value > highest):
        bounds = f"in [{lowest}, {highest}]" if highest is not None else f">= {lowest}"
        raise ValueError(f"{name} {value} must be {what or 'an integer ' + bounds}")


def _real(value, name: str, zero: Optional[bool] = False, what: str = "number") -> float:
    """``value`` as a finite float > 0 (>= 0 with ``zero``; any number with ``zero`` None);
    TypeError / ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    if zero is None:
        return float(value)
    if not (math.isfinite(value) and (value >= 0 if zero else value > 0)):
        raise ValueError(f"{name} {value} must be a finite {what} {'>= 0' if zero else '> 0'}")
    return float(value)


@dataclass
class LandmarkRun:
    """One landmark dataset's run, step by step: ``read`` it, ``run`` the filter (and the
    refinement, and the score), then ``summary``, ``write`` and ``draw``.

    dataset: the ``datasets.LandmarkDataset`` read; filtered: the filter's run
    (``LandmarkSlamResult``); result: the run the scores, path and picture are of (the refined
    one after ``refine`` graphslam, else the filter's); refinement: the ``datasets.RefinedRun``
    (None without); score: the ``datasets.DatasetScore`` against the dataset's reference;
    cpu_seconds: the filter's CPU time."""

    dataset: LandmarkDataset
    options: LandmarkRunOptions
    filtered: Optional[LandmarkSlamResult] = None
    result: Optional[LandmarkSlamResult] = None
    refinement: Optional[RefinedRun] = None
    score: Optional[DatasetScore] = None
    cpu_seconds: float = 0.0

    @classmethod
    def read(cls, dataset: Union[PathLike, LandmarkDataset],
             options: Optional[LandmarkRunOptions] = None) -> "LandmarkRun":
        """The dataset at a path (an MRCLAM folder, a Victoria Park file, the original Victoria
        Park run's folder) read with ``options``, or a ``LandmarkDataset`` already read. The
        options are checked first, then against the dataset (ValueError naming the field that
        does not apply), before it is read; the readers' errors name the file and what was expected
        (``inputs.reading``: InputError)."""
        options = LandmarkRunOptions() if options is None else options
        require_instance(options, LandmarkRunOptions, "options")
        options.validate()
        if isinstance(dataset, LandmarkDataset):
            for name in READ_OPTIONS:
                if getattr(options, name) not in (None, False):
                    raise ValueError(f"{name} says how a path is read; the dataset given is read already")
            type(dataset).check(options, dataset.path)
            return cls(dataset, options)
        path = pathlib.Path(os.fspath(dataset))
        with reading(str(path), LANDMARK_DATASET, _OPTION_PATHS, folder=True):
            kind = landmark_dataset_class(path)
            kind.check(options, path)
            return cls(kind.load(path, options), options)

    def run(self, progress: Optional[bool] = None) -> None:
        """The filter, the refinement (``refine``) and the score. ``progress``: a bar over the
        dataset's steps (None: on a terminal only)."""
        cpu = time.process_time()
        self.filtered = self.dataset.run(self.options, progress)
        self.cpu_seconds = time.process_time() - cpu
        self.result = self.filtered
        if self.options.refine != "none":
            self.refinement = self.dataset.refine(self.filtered, self.options)
            self.result = self.refinement.result
        self.score = self.dataset.score(self.result, self.options)

    @property
    def metrics(self) -> Dict[str, object]:
        """The run's figures by name (names of ``LandmarkDataset.METRICS``, a sweep's row): the
        score's against the dataset's reference and the refinement's."""
        return {**self.score.metrics, **({} if self.refinement is None else self.refinement.metrics)}

    def summary(self) -> str:
        """What was read, run, refined and scored, in lines (as ``probslam ekf-slam`` prints them)."""
        lines = self.dataset.read_lines()
        if self.filtered is not None:
            lines += self.dataset.summary(self.filtered, self.options, self.cpu_seconds)
            lines += [] if self.refinement is None else self.refinement.lines
            lines += self.score.lines
        return "\n".join(lines)

    def write(self, prefix: str, trajectory_format: str = "tum") -> List[str]:
        """PREFIX_trajectory.EXT (``io.write_trajectory``: tum, kitti or xyt) of the run's path at
        its times; returns the paths written."""
        path = prefix + "_trajectory" + io.trajectory.EXTENSIONS[trajectory_format]
        return list(io.write_trajectory(self.result.times, self.result.poses, path, format=trajectory_format))

    def title(self, note: str = "") -> str:
        """The picture's title: the command, the data, the filter (``note``: what the drawing adds)."""
        refined = ", GraphSLAM refinement (ch. 11.6)" if self.refinement is not None else ""
        return (f"probslam {COMMANDS[self.options.method]}: {self.dataset.title(self.options)}\n"
                f"{self.dataset.caption(self.options)}{refined}{note}")

    def draw(self, plt):
        """A figure of the run (matplotlib's pyplot given): its path and map over the dataset's
        reference, eight inches of map in the data's own shape and room for the legend beside it."""
        fig, ax = plt.subplots(figsize=(8, 8))
        note = self.dataset.draw(ax, self.result, self.score, self.refinement, self.filtered, self.options)
        ax.set_title(self.title(note), fontsize="medium")
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        # Victoria Park is five times as wide as tall: 3 to 10 inches tall, 3.5 beside for the legend.
        fig.set_size_inches(11.5, min(max(8 * (y1 - y0) / max(x1 - x0, 1e-9), 3.0), 10.0) + 1.0)
        return fig


def run_landmark_dataset(dataset: Union[PathLike, LandmarkDataset], options: Optional[LandmarkRunOptions] = None,
                         progress: Optional[bool] = None) -> LandmarkRun:
    """Reads the landmark dataset (``LandmarkRun.read``) and runs it; the run with its results."""
    run = LandmarkRun.read(dataset, options)
    run.run(progress)
    return run


__all__ = ["ASSOCIATIONS", "LandmarkRun", "LandmarkRunOptions", "METHODS", "REFINEMENTS", "RefinementOptions",
           "run_landmark_dataset"]
