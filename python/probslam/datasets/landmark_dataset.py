"""The face every landmark dataset shows a landmark SLAM run (``probslam.pipelines.landmark_run``):
its name, the options that apply to it, how it is read, its default noise, how a filter runs over
it, what it is scored against (ground truth, survey, GPS) and how its picture is drawn. Each
dataset module holds its own (``mrclam.MrclamRobot``, ``victoria_park.VictoriaParkChain``,
``victoria_park_acfr_run.VictoriaParkRun``); ``LandmarkDataset`` is what they share, so that a run
asks the dataset instead of branching on its kind.

``options`` below is the run's ``probslam.pipelines.LandmarkRunOptions`` (its fields method,
unknown, association, hypotheses (a MultiHypothesisOptions), fastslam (a FastSlamOptions), robot,
seconds, raw_ranges, sigma_v, sigma_w, sigma_r, sigma_phi, refine, refinement (the keywords of
``landmark_refine.refine_landmarks``)).
"""

from __future__ import annotations

import dataclasses
import pathlib
import time
from dataclasses import dataclass, field
from typing import Dict, List, Mapping, Optional, Tuple

import numpy as np

from .. import eval as evaluation
from .._core import FastSlamOptions, MultiHypothesisOptions
from .._args import differing_field, require_instance
from ..landmark_refine import RefinementInput, RunRefinement, refine_landmarks
from ..landmark_slam import LandmarkSlamResult

#: The associations of an EKF with hidden correspondences (``run_filter(method="ekf", known=False)``):
#: joint compatibility over each scan, or maximum likelihood per sighting (``EkfSlam.update_unknown``).
EKF_ASSOCIATIONS = ("jcbb", "ml")
#: The options that only some datasets take (each dataset lists those it takes in ``OPTIONS``).
DATASET_OPTIONS = ("robot", "seconds", "raw_ranges", "sigma_v", "sigma_w", "sigma_r", "sigma_phi")


@dataclass
class DatasetScore:
    """A run's score against its dataset's reference: the lines that say it, and what the
    picture draws it against (keywords of ``plot.landmark_map`` / ``fastslam_map``; empty when
    the dataset has nothing to draw against), the scores themselves (``values``) and those of
    them that are numbers by name (``metrics``: names of ``LandmarkDataset.METRICS``, a sweep's
    row in ``probslam batch``)."""

    lines: List[str] = field(default_factory=list)
    reference: dict = field(default_factory=dict)
    values: Dict[str, object] = field(default_factory=dict)
    metrics: Dict[str, float] = field(default_factory=dict)


@dataclass
class RefinedRun:
    """GraphSLAM's correspondence test over a run (ch. 11.6): the refined run, the refinement
    (``landmark_refine.LandmarkRefinement``), the lines that say what it did and its figures by
    name (``metrics``: names of ``LandmarkDataset.METRICS``)."""

    result: LandmarkSlamResult
    refinement: object
    lines: List[str]
    metrics: Dict[str, object] = field(default_factory=dict)


class LandmarkDataset:
    """What a landmark dataset tells a run; each dataset's class fills it in.

    ``data``: the dataset as read (``io.Mrclam``, ``io.VictoriaPark``, ``io.VictoriaParkAcfr``);
    ``path``: where it was read from. ``OPTIONS``: the names of ``DATASET_OPTIONS`` that apply to
    it; ``LABEL``: what it is, for the refusal of the others."""

    OPTIONS: Tuple[str, ...] = ()
    #: The names of a score's and a refinement's ``metrics``, over every dataset (a sweep table's
    #: columns): the score's against the dataset's reference (and the dead reckoning's, the
    #: baseline), the association's (sightings on no landmark, the landmarks that hold sightings:
    #: ``association_metrics``) and the refinement's (``refinement_metrics``).
    METRICS: Tuple[str, ...] = ("association_correct", "path_rmse_m", "path_rmse_aligned_m", "landmark_rmse_m",
                                "landmark_rmse_aligned_m", "map_rmse_survey_aligned_m", "sightings", "landmarks_seen",
                                "landmarks_associated", "unassigned", "filter_path_rmse_aligned_m", "refine_cpu_s",
                                "refine_rounds", "refine_merges", "refine_moves", "refine_converged",
                                "dead_reckoning_rmse_m", "dead_reckoning_rmse_aligned_m")
    LABEL = ""
    #: The type of ``data``.
    DATA: type = object
    #: What the dataset is, in the refusal of an option that does not apply to it.
    REFUSAL = "Victoria Park (one vehicle, its noise in the file)"

    def __init__(self, data, path: Optional[pathlib.Path] = None):
        require_instance(data, self.DATA, "data")
        self.data = data
        self.path = pathlib.Path("<data>" if path is None else path)

    # -- before reading -----------------------------------------------------------------------
    @classmethod
    def check(cls, options, path: pathlib.Path) -> None:
        """ValueError naming the first option that does not apply to this dataset."""
        for name in DATASET_OPTIONS:
            if name not in cls.OPTIONS and getattr(options, name) not in (None, False):
                raise ValueError(f"{name} applies to MRCLAM folders only; {path} is {cls.REFUSAL}")

    @classmethod
    def load(cls, path: pathlib.Path, options) -> "LandmarkDataset":
        """The dataset at ``path`` read with the options that apply to it."""
        raise NotImplementedError

    # -- the run ------------------------------------------------------------------------------
    def read_lines(self) -> List[str]:
        """What the reader skipped (a real file is read even with a few bad rows, and says so)."""
        return [skipped_rows_line(self.data.skipped_rows)]

    def noise(self, options) -> dict:
        """The run's noise keywords (``motion_noise``, ``measurement_noise``); {}: the dataset's own."""
        return {}

    def association(self, options) -> str:
        """The EKF's association with hidden correspondences: the option, or the dataset's default."""
        return options.association or "jcbb"

    def run(self, options, progress: Optional[bool] = None) -> LandmarkSlamResult:
        """The filter of ``options`` over the dataset."""
        raise NotImplementedError

    def run_filter(self, method: str, *, known: Optional[bool] = None, motion_noise=None, measurement_noise=None,
                   association: str = "jcbb", hypotheses: Optional[MultiHypothesisOptions] = None,
                   options: Optional[FastSlamOptions] = None, progress: Optional[bool] = None,
                   **fields) -> LandmarkSlamResult:
        """One filter over the dataset, as ``datasets.run_landmark_slam`` describes its arguments
        (``known`` None: True, the dataset's labels). The checks shared by the datasets with labels
        are here; each dataset's ``_run_filter`` runs it."""
        known = True if known is None else known
        if method == "mht" and known:
            raise ValueError("known: method 'mht' finds the correspondences itself; pass known=False")
        if method == "ekf" and not known and association not in EKF_ASSOCIATIONS:
            raise ValueError(f"association must be one of {', '.join(map(repr, EKF_ASSOCIATIONS))}, got "
                             f"{association!r}")
        if hypotheses is not None and method != "mht":
            raise ValueError(f"hypotheses: options of method 'mht', not of {method!r}")
        require_fastslam_options(method, options, fields)
        return self._run_filter(method, known, motion_noise, measurement_noise, association, hypotheses,
                                {"options": options, **fields}, progress)

    def _run_filter(self, method: str, known: bool, motion_noise, measurement_noise, association: str, hypotheses,
                    fastslam: dict, progress: Optional[bool]) -> LandmarkSlamResult:
        """``fastslam``: the FastSLAM run's ``options`` and fields by keyword."""
        raise NotImplementedError

    def summary(self, result: LandmarkSlamResult, options, seconds: float) -> List[str]:
        """The lines that say what ran over what (``seconds``: the filter's CPU time)."""
        raise NotImplementedError

    def refinement_input(self, run: LandmarkSlamResult, motion_noise=None, measurement_noise=None,
                         command_period: Optional[float] = None) -> RefinementInput:
        """The arrays of ``landmark_refine.refine_landmarks`` from a run over the dataset, with the
        noise it ran with (``datasets.refinement_input``)."""
        raise NotImplementedError

    def refine_run(self, run: LandmarkSlamResult, motion_noise=None, measurement_noise=None,
                   command_period: Optional[float] = None, **options) -> RunRefinement:
        """GraphSLAM's correspondence test (``landmark_refine.refine_landmarks``, ch. 11.6) on the
        run (``refinement_input``); ``options`` go to ``refine_landmarks``."""
        period = {} if command_period is None else {"command_period": command_period}
        start = self.refinement_input(run, motion_noise, measurement_noise, **period)
        return RunRefinement(start, refine_landmarks(**start.arguments(), **options))

    def refine(self, result: LandmarkSlamResult, options) -> RefinedRun:
        """GraphSLAM's correspondence test (ch. 11.6) over the run (``refine_run`` with the options'
        ``refinement``), said in a line."""
        noise = self.noise(options)
        cpu = time.process_time()
        refined = self.refine_run(result, noise.get("motion_noise"), noise.get("measurement_noise"),
                                  **refinement_keywords(options))
        cpu = time.process_time() - cpu
        r = refined.result
        out = refined.as_landmark_slam_result(result)
        line = (f"refinement:    GraphSLAM correspondence test (ch. 11.6): {evaluation.association_accuracy(out):.1%} "
                f"correct, {len(r.landmarks)} landmarks, {len(r.merges)} merges, {len(r.splits)} sightings moved, "
                f"{int((r.labels < 0).sum())} unassigned, {r.iterations} rounds, {r.seconds:.2f} s"
                f"{'' if r.converged else ' (stopped at the round limit)'}; the scores, path and picture below are the "
                f"refined ones")
        return RefinedRun(out, r, [line], self.refinement_metrics(refined, cpu))

    def refinement_metrics(self, refined: RunRefinement, cpu_seconds: float) -> Dict[str, object]:
        """The refinement's figures by name (``METRICS``): its CPU seconds (its input built from the
        run included), rounds, merges, sightings moved, and whether it converged (False: it
        stopped at max_iterations)."""
        r = refined.result
        return {"refine_cpu_s": float(cpu_seconds), "refine_rounds": int(r.iterations), "refine_merges": len(r.merges),
                "refine_moves": len(r.splits), "refine_converged": bool(r.converged)}

    def score(self, result: LandmarkSlamResult, options) -> DatasetScore:
        """The run against the dataset's reference (nothing to score against: an empty score)."""
        return DatasetScore()

    # -- the picture --------------------------------------------------------------------------
    def title(self, options) -> str:
        """The data the picture shows, for its title."""
        return f"{self.LABEL} {self.path.name}"

    def caption(self, options) -> str:
        """The filter, for the picture's title."""
        if options.method == "fastslam":
            return (f"FastSLAM {options.fastslam.version}.0, {options.fastslam.num_particles} particles, "
                    f"{'unknown' if options.unknown else 'known'} correspondences")
        return "EKF SLAM, known correspondences"

    def draw(self, ax, result: LandmarkSlamResult, score: DatasetScore,
             refinement: Optional[RefinedRun] = None, filtered: Optional[LandmarkSlamResult] = None,
             options=None) -> str:
        """Draws the run on ``ax``; returns the title's note on what is drawn ("" for none)."""
        from ..plot import fastslam_map, landmark_map

        reference = score.reference
        if refinement is not None:
            r = refinement.refinement
            labels = sorted(r.landmarks)
            means = np.array([r.landmarks[k] for k in labels]).reshape(-1, 2)
            covariances = np.array([r.landmark_covariances[k] for k in labels]).reshape(-1, 2, 2)
            landmark_map(ax, result.poses, path_label="GraphSLAM refinement", landmarks=(means, covariances),
                         **reference)
        elif result.method == "fastslam":
            fastslam_map(ax, result.filter, **reference)
        else:
            landmark_map(ax, result.poses, result.filter, **reference)
        return "; estimate aligned onto ground truth" if reference.get("align") is not None else ""


def require_fastslam_options(method: str, options: Optional[FastSlamOptions], fields: Mapping) -> None:
    """ValueError naming the first FastSLAM option given to another method."""
    if method != "fastslam" and (options is not None or fields):
        name = "options" if options is not None else next(iter(fields))
        raise ValueError(f"{name}: FastSLAM's options apply to method 'fastslam' only, not to {method!r}")


def refuse_hypotheses(options) -> None:
    """ValueError naming the first field of the options' ``hypotheses`` that is set: the
    multiple-hypothesis EKF runs on MRCLAM only."""
    changed = differing_field(options.hypotheses, MultiHypothesisOptions())
    if changed is not None:
        raise ValueError(f"hypotheses.{changed} applies to MRCLAM folders (with unknown, association mht)")


def refinement_keywords(options) -> dict:
    """``landmark_refine.refine_landmarks``' keywords of a ``LandmarkRunOptions`` (its ``refinement``)."""
    return dataclasses.asdict(options.refinement)


def association_metrics(result: LandmarkSlamResult) -> Dict[str, int]:
    """A run's association figures by name (``LandmarkDataset.METRICS``; hidden correspondences
    only, else none): ``unassigned``, the sightings it put on no landmark (discarded as clutter,
    left provisional, or, refined, left by the split test for no other), and
    ``landmarks_associated``, the landmarks that hold sightings (a particle filter's include those
    its map has dropped since)."""
    if result.associations is None:
        return {}
    ids = np.asarray(result.associations.ids)
    return {"unassigned": int(np.count_nonzero(ids < 0)), "landmarks_associated": len(np.unique(ids[ids >= 0]))}


def skipped_rows_line(skipped: Dict[str, int]) -> str:
    """The rows a reader skipped, by reason, in a line."""
    if not skipped:
        return "skipped rows:  0"
    return (f"skipped rows:  {sum(skipped.values())} "
            f"({'; '.join(f'{reason}: {count}' for reason, count in sorted(skipped.items()))})")


def fastslam_lines(result: LandmarkSlamResult, options) -> List[str]:
    """What a FastSLAM run did: its particles, resamplings, time and map, in lines."""
    return [f"filter:        FastSLAM {options.fastslam.version}.0, {options.fastslam.num_particles} particles, "
            f"{result.filter.num_resamples} resamplings; filter time {result.seconds:.2f} s",
            f"landmarks:     {len(result.landmarks)} in the best particle's map"]


def association_line(result: LandmarkSlamResult, what: str = "label", applied: Optional[int] = None) -> List[str]:
    """The associations' accuracy (hidden correspondences only), in a line."""
    if result.associations is None:
        return []
    tail = "" if applied is None else f", {result.associations.applied} of {applied} sightings applied"
    return [f"associations:  {evaluation.association_accuracy(result):.1%} correct (each landmark's majority "
            f"{what}){tail}"]


__all__ = ["DATASET_OPTIONS", "EKF_ASSOCIATIONS", "LandmarkDataset", "DatasetScore", "RefinedRun", "association_line",
           "association_metrics", "fastslam_lines", "refinement_keywords", "refuse_hypotheses",
           "require_fastslam_options",
           "skipped_rows_line"]
