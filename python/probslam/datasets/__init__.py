"""The public datasets the package runs on, one module each: what is particular to a dataset
(its defaults, its checks, how its records drive a filter, its forensics) lives here, the file
readers in ``probslam.io``, the scores in ``probslam.eval``.

- ``mrclam``: UTIAS MRCLAM, one robot's odometry, sightings and ground truth;
- ``victoria_park``: Victoria Park as iSAM / GTSAM text, a chain of odometry edges and sightings;
- ``victoria_park_acfr``: the original Victoria Park run (ACFR): the car's speed and steering,
  every tree detection, GPS.

Laser logs (CARMEN, ROS bags) are read by ``probslam.io.read_laser_log``.

``run_landmark_slam`` runs a landmark filter (EKF, multiple-hypothesis EKF, FastSLAM) over an
MRCLAM robot or Victoria Park, given as read (``load_landmark_dataset``) or as a path.
"""

from __future__ import annotations

import os
import pathlib
from typing import Optional, Union

from .._args import require_fields, require_instance
from .._core import FastSlamOptions, MultiHypothesisOptions
from ..io._files import file_path
from ..io.landmark_datasets import Mrclam, VictoriaPark, VictoriaParkAcfr
from ..landmark_refine import RefinementInput, RunRefinement
from ..landmark_slam import METHODS, Associations, LandmarkSlamResult
from . import mrclam, victoria_park, victoria_park_acfr, victoria_park_acfr_run
from .landmark_dataset import EKF_ASSOCIATIONS, LandmarkDataset, DatasetScore, RefinedRun

PathLike = Union[str, "os.PathLike[str]"]


def landmark_dataset_kind(path: PathLike) -> str:
    """What the path holds, judged before reading it: "mrclam" for a folder holding
    Barcodes.dat, "victoria_park_acfr" for a folder holding inputs.dat and measurements.dat (the
    original Victoria Park run), "victoria_park" for a file (not empty). A missing path raises
    ``FileNotFoundError``, a folder holding neither or an empty file ``ValueError`` naming the
    path."""
    path = pathlib.Path(file_path(path))
    if not path.exists():
        raise FileNotFoundError(f"path: no such file or folder: {str(path)!r}")
    if path.is_dir():
        if (path / "Barcodes.dat").exists():
            return "mrclam"
        if victoria_park_acfr.is_run_folder(path):
            return "victoria_park_acfr"
        raise ValueError(f"{path}: a folder without Barcodes.dat (MRCLAM) or inputs.dat and measurements.dat "
                         f"(the original Victoria Park run)")
    if path.is_file() and path.stat().st_size == 0:
        raise ValueError(f"{path}: empty file")
    return "victoria_park"


#: Each kind of ``landmark_dataset_kind``, by the class that shows it to a landmark run.
LANDMARK_DATASETS = {"mrclam": mrclam.MrclamRobot, "victoria_park": victoria_park.VictoriaParkChain,
                     "victoria_park_acfr": victoria_park_acfr_run.VictoriaParkRun}


def landmark_dataset_class(path: PathLike) -> type:
    """The ``LandmarkDataset`` class of the data at ``path`` (``landmark_dataset_kind``'s errors)."""
    return LANDMARK_DATASETS[landmark_dataset_kind(path)]


def load_landmark_dataset(path: PathLike, *, robot: int = 1, seconds: Optional[float] = None,
                          raw_ranges: bool = False) -> Union[Mrclam, VictoriaPark, VictoriaParkAcfr]:
    """The landmark dataset at ``path`` (``landmark_dataset_kind``), read and checked: UTIAS
    MRCLAM's robot ``robot``, its first ``seconds`` (None: all), readings as distances unless
    ``raw_ranges`` (``mrclam.load``), Victoria Park in iSAM / GTSAM text
    (``victoria_park.load``) or the original Victoria Park run (``victoria_park_acfr.load``;
    ``robot``, ``seconds`` and ``raw_ranges`` are MRCLAM's only).

    Errors: those of ``landmark_dataset_kind``, the readers' (``FileNotFoundError`` for a
    missing file, ``ValueError`` naming the file and line), and ``ValueError`` naming the path
    for data with nothing to run (no odometry, no sighting)."""
    kind = landmark_dataset_kind(path)
    if kind == "mrclam":
        return mrclam.load(path, robot, seconds, raw_ranges)
    if kind == "victoria_park_acfr":
        return victoria_park_acfr.load(path)
    return victoria_park.load(path)


def run_landmark_slam(dataset: Union[Mrclam, VictoriaPark, VictoriaParkAcfr, PathLike], method: str = "ekf", *,
                      known: Optional[bool] = None, motion_noise=None, measurement_noise=None,
                      association: str = "jcbb", hypotheses: Optional[MultiHypothesisOptions] = None,
                      options: Optional[FastSlamOptions] = None, progress: Optional[bool] = None,
                      **fields) -> LandmarkSlamResult:
    """A landmark SLAM run over a dataset: an ``Mrclam`` robot, ``VictoriaPark`` or the original
    Victoria Park run (``VictoriaParkAcfr``) as read, or a path (read with
    ``load_landmark_dataset``'s defaults).

    ``known``: whether the dataset's labels give the correspondences; None (the default): True
    where the dataset has labels (MRCLAM's barcodes, the iSAM file's landmark numbers), False on
    the original Victoria Park run, whose detections have none (``known=True`` is refused
    there). That run is driven by ``victoria_park_acfr_run`` (the car's model at the inputs'
    40 Hz, the sensors' noise; ``motion_noise`` and ``measurement_noise`` are its own and refused
    here), methods "ekf", "fastslam" and "dead-reckoning".

    ``method``:
      * ``"ekf"``: EKF SLAM (Tables 10.1 / 10.2); with ``known=False`` the correspondences are
        hidden and found by ``association`` (``EKF_ASSOCIATIONS``: "jcbb" joint compatibility over
        each scan, "ml" maximum likelihood). On Victoria Park known correspondences only.
      * ``"mht"``: the multiple-hypothesis EKF, a beam of filters (hidden correspondences,
        ``known=False``; MRCLAM only); ``hypotheses``: a ``MultiHypothesisOptions``, its fields
        left at their defaults taking the dataset's (``mrclam.run_ekf``).
      * ``"fastslam"``: FastSLAM with ``options`` (a ``FastSlamOptions``) and ``fields`` of it by
        keyword (``num_particles=30``, ``version``, ``seed``, ``threads``: the result is the same
        for any count), the dataset's own defaults where they hold FastSlamOptions' (p_new
        ``fastslam.DEFAULT_P_NEW``, MRCLAM's outlier density and camera field: the dataset
        modules' ``run_fastslam``). Only FastSLAM takes them (ValueError naming the first).
      * ``"dead-reckoning"``: the odometry alone (the baseline the maps are compared with).

    Noise: ``motion_noise`` (2, 2), MRCLAM's control noise of one 10 ms command (default
    ``mrclam.MOTION_NOISE``; Victoria Park takes its file's odometry noise, scaled by
    ``victoria_park.ODOMETRY_NOISE_SCALE`` for FastSLAM); ``measurement_noise`` (2, 2) range and
    bearing (default: MRCLAM ``mrclam.MEASUREMENT_NOISE``, Victoria Park the file's noise in
    polar form at the median range).

    ``progress``: a bar over the dataset's steps (MRCLAM's controls, Victoria Park's poses), as
    ``run_slam``'s: None shows it only on a terminal, True always, False never.

    Returns a ``LandmarkSlamResult``; ``probslam.eval`` scores it (``score_mrclam``,
    ``score_landmarks``, ``association_accuracy``). The dataset modules' ``run_ekf`` /
    ``run_fastslam`` take further options (gates, hooks, start pose)."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(map(repr, METHODS))}, got {method!r}")
    if known is not None and not isinstance(known, bool):
        raise TypeError(f"known must be None or a bool, got {type(known).__name__}")
    if isinstance(dataset, (str, bytes, os.PathLike)):
        dataset = load_landmark_dataset(dataset)
    return as_landmark_dataset(dataset, "dataset").run_filter(
        method, known=known, motion_noise=motion_noise, measurement_noise=measurement_noise, association=association,
        hypotheses=hypotheses, options=options, progress=progress, **fields)


def as_landmark_dataset(data: Union[Mrclam, VictoriaPark, VictoriaParkAcfr], name: str = "data") -> LandmarkDataset:
    """A dataset as read (``load_landmark_dataset``), as a landmark run sees it: its
    ``LandmarkDataset`` (with no path: its title names none). TypeError naming ``name`` for
    anything else."""
    classes = tuple(LANDMARK_DATASETS.values())
    require_instance(data, tuple(c.DATA for c in classes), name)
    return next(c for c in classes if isinstance(data, c.DATA))(data)


def refinement_input(run: LandmarkSlamResult, data: Union[Mrclam, VictoriaPark, VictoriaParkAcfr],
                     motion_noise=None, measurement_noise=None, *,
                     command_period: Optional[float] = None) -> RefinementInput:
    """The arrays of ``landmark_refine.refine_landmarks`` from a filter run over a dataset.

    ``run``: a ``LandmarkSlamResult`` (``run_landmark_slam``: EKF, MHT or FastSLAM), known or
    hidden correspondences; ``data``: the dataset it ran on. MRCLAM: ``motion_noise`` (2, 2) and
    ``measurement_noise`` (2, 2), the noise the run used (per ``command_period`` of control, default
    ``mrclam.COMMAND_PERIOD``, as the runs take it; ``mrclam.refinement_input``). Victoria Park: the
    file's odometry and observation covariances, the noise arguments unused
    (``victoria_park.refinement_input``); the original run: its sensors' noise
    (``victoria_park_acfr_run.refinement_input``). A run with known correspondences gives the true
    ids as labels (less an EKF's gated outliers): geometry alone then has nothing to add, and in
    MRCLAM Dataset 7's 0.18 m clusters its moves cost 3% of the sightings (first 200 s of robot 1):
    refine runs with hidden correspondences."""
    require_fields(run, ("times", "poses", "landmarks", "associations"), "run", "a LandmarkSlamResult")
    period = {} if command_period is None else {"command_period": command_period}
    return as_landmark_dataset(data).refinement_input(run, motion_noise, measurement_noise, **period)


def refine_run(run: LandmarkSlamResult, data: Union[Mrclam, VictoriaPark, VictoriaParkAcfr], motion_noise=None,
               measurement_noise=None, *, command_period: Optional[float] = None, **options) -> RunRefinement:
    """GraphSLAM's correspondence test (``landmark_refine.refine_landmarks``, ch. 11.6) on a filter
    run over a dataset (``refinement_input``); ``options`` go to ``refine_landmarks``
    (merge_probability, split_probability, max_iterations, estimate_noise, new_landmarks)."""
    require_fields(run, ("times", "poses", "landmarks", "associations"), "run", "a LandmarkSlamResult")
    return as_landmark_dataset(data).refine_run(run, motion_noise, measurement_noise, command_period, **options)


__all__ = ["Associations", "EKF_ASSOCIATIONS", "LANDMARK_DATASETS", "LandmarkDataset", "DatasetScore",
           "LandmarkSlamResult", "RefinedRun", "as_landmark_dataset", "landmark_dataset_class",
           "landmark_dataset_kind", "refine_run", "refinement_input",
           "load_landmark_dataset", "mrclam", "run_landmark_slam", "victoria_park", "victoria_park_acfr",
           "victoria_park_acfr_run"]
