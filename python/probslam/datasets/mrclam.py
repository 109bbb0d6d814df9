"""UTIAS MRCLAM (Leung et al. 2011): one robot's run, read (``load``), driven through EKF SLAM or
FastSLAM (``run_ekf``, ``run_fastslam``), and the dataset's own forensics: the camera's
perceptual field, the scale of its depth readings, survey labels that contradict the barcodes.

The robot's odometry is (t, v, w) commands at irregular stamps and its sightings come in scans
(the measurements of one time stamp). The file reader is ``probslam.io.read_mrclam``; the scores
(``score_mrclam``, ``score_landmarks``, ``association_accuracy``) are in ``probslam.eval``.
Units: metres, radians, seconds.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import pathlib
import time
from typing import Dict, Iterator, List, Optional, Tuple, Union

import numpy as np

from .._args import differing_field, options_over, positive_real, real_array, require_fields, require_instance
from .._progress import progress_bar
from .._core import (FastSlam, FastSlamOptions, MultiHypothesisOptions, chi_square_quantile, velocity_motion,
                     velocity_motion_control_jacobian)
from ..ekf import AssociationResult, EkfSlam, MapManagement, MultiHypothesisEkfSlam
from ..eval import association_accuracy, majority_labels, score_landmarks, score_mrclam, truth_positions
from ..fastslam import AssociationHistories, dataset_options, result_of
from ..geometry import accumulate
from ..io._files import file_path
from ..io.landmark_datasets import MRCLAM_RANGE_SCALE, Mrclam, read_mrclam
from .._core import velocity_increments
from ..landmark_refine import (RefinementInput, RunRefinement, compose_increments, floor_covariances, poses_at_nodes,
                               run_labels)
from ..landmark_slam import Associations, LandmarkSlamResult, ekf_landmarks
from .landmark_dataset import LandmarkDataset, DatasetScore, association_line, association_metrics, fastslam_lines

PathLike = Union[str, "os.PathLike[str]"]

#: MRCLAM datasets hold robots 1 to 5.
ROBOTS = 5

#: The control noise of one 10 ms command, standard deviations (sigma_v m/s, sigma_w rad/s):
#: Dataset 7's odometry against its Vicon ground truth gives 0.11 m/s and 0.43 rad/s, inflated
#: ~1.4x for the turn rate's bias (docs/ekf_slam.md). The default of every driver here and of
#: the CLI's --sigma-v / --sigma-w; ``MOTION_NOISE`` is its covariance.
MOTION_SIGMA = (0.15, 0.6)
MOTION_NOISE = np.diag(np.square(MOTION_SIGMA))
#: The sensor noise, standard deviations (sigma_r m, sigma_phi rad): sigma_phi 0.018 rad against
#: Vicon, mostly an offset shared by one scan's sightings, and sigma_r 0.02 m as distances,
#: inflated for the correlated errors the filters do not model (the hidden-barcode runs need the
#: room). The CLI's --sigma-r / --sigma-phi; ``MEASUREMENT_NOISE`` is its covariance.
MEASUREMENT_SIGMA = (0.15, 0.04)
MEASUREMENT_NOISE = np.diag(np.square(MEASUREMENT_SIGMA))
#: MRCLAM's command period (s): ``MOTION_NOISE`` is the noise of one command.
COMMAND_PERIOD = 0.01

#: Outlier gate on the NIS of known-correspondence updates: the chi-square quantile at this
#: probability (2 dof). MRCLAM holds 0.5-3.6% gross outliers (wrong barcodes, reflections).
OUTLIER_PROBABILITY = 0.999

#: The share of a robot's sightings inside the perceptual field that negative information uses
#: with hidden correspondences (``perceptual_field``). A landmark is penalised for not
#: being seen only where the camera nearly always sees one: 10% of the sightings lie beyond
#: this field's range or bearing limits, where detection is unreliable (MRCLAM's camera sees
#: landmarks up to 7-9 m, but half its sightings are within 3.3 m).
PERCEPTUAL_FIELD_QUANTILE = 0.9

#: The multiple-hypothesis EKF on MRCLAM (``run_ekf(association="mht")``): a landmark in
#: the camera's perceptual field (``perceptual_field``) is seen with this probability, so
#: a hypothesis pays -2 ln(1 - P_D) = 1.39 for each such landmark a scan misses; and a new
#: landmark costs this much (NIS units, below the library's 27.6). Chosen over all ten shipped
#: robots (benchmarks/sweeps/mrclam_association.toml; docs/landmark_fastslam.md has the sweep).
MHT_DETECTION_PROBABILITY = 0.5
MHT_NEW_LANDMARK_COST = 21.0

#: A surveyed landmark whose distances to the landmarks sighted in the same scans disagree with
#: the readings by more than this (median over its pairs) has a survey label that is not its
#: barcode's. Honest labels give medians of 0.01-0.17 m on Datasets 1 and 7 (camera noise over
#: two readings); a wrong label gives metres, the landmarks standing 1-10 m apart.
SURVEY_RESIDUAL_LIMIT = 0.5  # m


def first_seconds(data: Mrclam, seconds: float) -> Mrclam:
    """A copy holding the odometry, measurements and ground truth of the first ``seconds`` of
    the run (from the first odometry stamp): a short run of a long dataset."""
    seconds = float(seconds)
    if not (np.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds: must be finite and > 0, got {seconds}")
    if len(data.odometry) == 0:
        raise ValueError("data: no odometry")
    end = data.odometry[0, 0] + seconds
    keep = lambda rows: rows if rows is None else rows[rows[:, 0] <= end]  # noqa: E731
    return dataclasses.replace(data, odometry=keep(data.odometry), measurements=keep(data.measurements),
                               groundtruth=keep(data.groundtruth))


def load(folder: PathLike, robot: int = 1, seconds: Optional[float] = None, raw_ranges: bool = False) -> Mrclam:
    """Robot ``robot`` of the MRCLAM folder, ready to run: its first ``seconds`` (None: all), its
    readings turned into distances (``Mrclam.with_euclidean_ranges``) unless ``raw_ranges``.
    Besides the reader's errors (``io.read_mrclam``), a ValueError naming the folder when the
    robot has no odometry, no landmark measurement (within the window), the survey no landmark,
    or its ground-truth file no row within the window: there would be nothing to run or score."""
    folder = pathlib.Path(file_path(folder, "folder"))
    data = read_mrclam(folder, robot=robot)
    if len(data.odometry) == 0:
        raise ValueError(f"{folder}: no odometry rows for robot {robot}")
    within = ""
    if seconds is not None:
        data = first_seconds(data, seconds)
        within = f" within the first {seconds:g} s"
    if not data.landmark_positions:
        raise ValueError(f"{folder}: Landmark_Groundtruth.dat lists no landmark")
    if len(data.measurements) == 0:
        raise ValueError(f"{folder}: no landmark measurements for robot {robot}{within}")
    if data.groundtruth is not None and len(data.groundtruth) == 0:
        raise ValueError(f"{folder}: Robot{robot}_Groundtruth has no row{within or ' within the odometry'}")
    return data if raw_ranges else data.with_euclidean_ranges()


def perceptual_field(data: Mrclam, quantile: float = PERCEPTUAL_FIELD_QUANTILE) -> Tuple[float, float]:
    """(range m, full field-of-view angle rad) of the camera, from the robot's own sightings:
    the ``quantile`` of their ranges, and twice that of their absolute bearings."""
    require_instance(data, Mrclam, "data")
    if not (isinstance(quantile, (int, float)) and 0.0 < quantile <= 1.0):
        raise ValueError(f"quantile must be in (0, 1], got {quantile!r}")
    m = data.measurements
    if len(m) == 0:
        raise ValueError("data: the robot has no landmark measurements")
    return float(np.quantile(m[:, 2], quantile)), float(2.0 * np.quantile(np.abs(m[:, 3]), quantile))


def start_pose(data: Mrclam) -> np.ndarray:
    """Where the drivers start the robot: its ground-truth pose at the first control, or the
    origin without ground truth (the map's frame is then the start pose's)."""
    if data.groundtruth is None:
        return np.zeros(3)
    g = data.groundtruth
    k = int(np.searchsorted(g[:, 0], data.odometry[0, 0]))
    return g[min(k, len(g) - 1), 1:4]


def _timeline(data: Mrclam, with_scans: bool = True, progress: Optional[bool] = False,
              desc: str = "") -> Iterator[tuple]:
    """The run in the order a filter takes it: ``("move", v, w, t, dt)``, the command (v, w) held
    for dt seconds from t; ``("scan", rows)``, the measurement rows (k, 4) of one stamp; and
    ``("control", k, t)`` once control k has been applied up to t (the next control's stamp).
    Scans before the first control are skipped; without ``with_scans``, all of them. A progress
    bar ``desc`` counts the controls (``progress`` as ``run_slam``'s)."""
    with progress_bar(len(data.odometry), desc, "control", progress) as bar:
        for event in _events(data, with_scans):
            yield event
            if event[0] == "control":
                bar.update(1)


def _events(data: Mrclam, with_scans: bool) -> Iterator[tuple]:
    """``_timeline``'s events, without the bar."""
    odo, meas = data.odometry, data.measurements
    scan_rows = data.scans()
    starts = np.array([r.start for r in scan_rows], dtype=np.int64)
    s = int(np.searchsorted(meas[starts, 0], odo[0, 0]))
    t_now = odo[0, 0]
    for k in range(len(odo)):
        v, w = odo[k, 1], odo[k, 2]
        t_next = odo[k + 1, 0] if k + 1 < len(odo) else odo[k, 0]
        while with_scans and s < len(starts) and meas[starts[s], 0] < t_next:
            rows = meas[scan_rows[s]]
            if rows[0, 0] > t_now:
                yield "move", v, w, t_now, rows[0, 0] - t_now
                t_now = rows[0, 0]
            yield "scan", rows
            s += 1
        if t_next > t_now:
            yield "move", v, w, t_now, t_next - t_now
            t_now = t_next
        yield "control", k, t_now


def _require_odometry(data: Mrclam) -> None:
    require_instance(data, Mrclam, "data")
    if len(data.odometry) == 0:
        raise ValueError("data: the robot has no odometry")


def run_ekf(data: Mrclam, motion_noise=None, measurement_noise=None, *, known: bool = True,
            gate: Optional[float] = None, alpha: Optional[float] = None, alpha_new: Optional[float] = None,
            initial_pose=None, map_management: Optional[MapManagement] = None, gate_distance: float = 1.0,
            dead_reckoning: bool = False, command_period: float = COMMAND_PERIOD, association: str = "jcbb",
            hypotheses: Optional[MultiHypothesisOptions] = None, before_scan=None,
            progress: Optional[bool] = False) -> LandmarkSlamResult:
    """EKF SLAM over an MRCLAM robot: odometry (v, w) between stamps, the measurements of one
    time stamp as one scan. ``motion_noise`` (2, 2; default ``MOTION_NOISE``) is the control
    noise of one command period (MRCLAM's ~10 ms); the stamps are irregular (gaps up to 1 s), so
    it is applied as a white velocity noise, M * command_period / dt for a step of dt, whose pose
    variance grows linearly with time whatever the stamps. ``measurement_noise`` (2, 2; default
    ``MEASUREMENT_NOISE``). ``known``: the barcodes give the correspondences (gated by ``gate``,
    default the chi-square ``OUTLIER_PROBABILITY`` quantile); else Table 10.2 (barcodes hidden)
    with ``association``: "jcbb" or "ml" (see ``EkfSlam.update_unknown``), or "mht", a beam of
    filters (``MultiHypothesisEkfSlam``, options ``hypotheses``: a MultiHypothesisOptions whose
    fields left at their defaults take MRCLAM's, missed detections in the camera's perceptual
    field, ``MHT_DETECTION_PROBABILITY`` and ``MHT_NEW_LANDMARK_COST``) whose best one is returned
    (method "mht"), clutter left out of its map (id -1 in ``associations``).
    ``dead_reckoning``: predictions only (method "dead-reckoning"). The start pose defaults to
    ``start_pose(data)``. ``before_scan(filter, rows)``, if given, sees the filter (the EkfSlam,
    or the MultiHypothesisEkfSlam) and each scan's measurement rows (k, 4) just before it takes
    them. ``times`` (one per control) are the stamps up to which each control was applied.
    ``progress``: a bar over the controls (None: on a terminal only)."""
    _require_odometry(data)
    motion_noise = MOTION_NOISE if motion_noise is None else motion_noise
    measurement_noise = MEASUREMENT_NOISE if measurement_noise is None else measurement_noise
    initial_pose = start_pose(data) if initial_pose is None else initial_pose
    gate = chi_square_quantile(OUTLIER_PROBABILITY, 2) if gate is None else gate
    t0 = time.perf_counter()
    ekf = EkfSlam(motion_noise, measurement_noise, use_signatures=False, initial_pose=initial_pose,
                  map_management=map_management, gate_distance=gate_distance)
    mht = None
    if not known and association == "mht":
        own = dict(new_landmark_cost=MHT_NEW_LANDMARK_COST, detection_probability=MHT_DETECTION_PROBABILITY)
        if len(data.measurements):
            own["sensor_range"], own["sensor_fov"] = perceptual_field(data)
        else:
            own["detection_probability"] = 0.0
        mht = MultiHypothesisEkfSlam(ekf, options=options_over(MultiHypothesisOptions, hypotheses, {}, own,
                                                               "hypotheses"))
        ekf = mht  # predict() goes to every filter
    odo = data.odometry
    times, poses = np.empty(len(odo)), np.empty((len(odo), 3))
    m_rate = np.asarray(motion_noise, float) * command_period
    rejected, innovations, sighted, results = 0, [], [], []
    desc = "dead reckoning" if dead_reckoning else ("EKF SLAM" if mht is None else "MHT EKF SLAM")
    for event in _timeline(data, with_scans=not dead_reckoning, progress=progress, desc=desc):
        if event[0] == "move":
            _, v, w, _, dt = event
            ekf.predict(v, w, dt, m_rate / dt)
        elif event[0] == "control":
            _, k, t = event
            times[k], poses[k] = t, ekf.pose
        else:
            rows = event[1]
            if before_scan is not None:
                before_scan(ekf, rows)
            if known:
                report = ekf.update(rows[:, 2:4], rows[:, 1].astype(np.int64), gate)
                rejected += int(np.count_nonzero(~report.used))
                innovations.append(np.column_stack([rows[:, :2], report.nis, report.used]))
                continue
            sighted.append(rows[:, :2])
            if mht is not None:
                mht.update(rows[:, 2:4])
            else:
                result = ekf.update_unknown(rows[:, 2:4], alpha, alpha_new, association)
                results.append(np.where(result.outcome <= AssociationResult.NEW_LANDMARK, result.ids, -1))
    method = "dead-reckoning" if dead_reckoning else ("ekf" if mht is None else "mht")
    if mht is not None:
        ekf = mht.best
        results = _applied_ids(mht.history())
    associations = None
    if not known and not dead_reckoning:
        rows = np.vstack(sighted) if sighted else np.empty((0, 2))
        ids = np.concatenate(results) if results else np.empty(0)
        associations = Associations(rows[:, 0], rows[:, 1].astype(np.int64), ids.astype(np.int64))
    return LandmarkSlamResult(method, times, poses, ekf_landmarks(ekf), ekf, time.perf_counter() - t0,
                              associations, rejected, np.vstack(innovations) if innovations else np.empty((0, 4)))


def _applied_ids(history) -> List[np.ndarray]:
    """The landmark id of each sighting, per scan, in a multiple-hypothesis filter's final
    history, -1 for clutter."""
    return [np.where(np.asarray(ids) >= 0, ids, -1) for ids in history]


def outlier_density(measurement_noise) -> float:
    """FastSLAM's outlier density (1 / (m rad)) for known correspondences that rejects what
    ``run_ekf``'s gate rejects: the Gaussian density N(z - z_hat; 0, Q) on the chi-square
    ``OUTLIER_PROBABILITY`` contour of Q (the landmark's own covariance, small after a few
    sightings, left out), so a measurement beyond the EKF's gate is more likely an outlier."""
    q = np.asarray(measurement_noise, float)[:2, :2]
    gate = chi_square_quantile(OUTLIER_PROBABILITY, 2)
    return float(np.exp(-0.5 * gate) / (2 * np.pi * np.sqrt(np.linalg.det(q))))


def fastslam_options(data: Mrclam, measurement_noise=None, known: bool = True,
                     options: Optional[FastSlamOptions] = None, **fields) -> FastSlamOptions:
    """The FastSlamOptions ``run_fastslam`` runs with (``fastslam.dataset_options``): ``options``
    and ``fields`` over MRCLAM's own: with ``known`` correspondences the ``outlier_density`` of
    ``measurement_noise`` (default ``MEASUREMENT_NOISE``), with hidden ones negative information
    in the camera's field (``perceptual_field``), p_new ``DEFAULT_P_NEW``."""
    measurement_noise = MEASUREMENT_NOISE if measurement_noise is None else measurement_noise
    own = {}
    if known:
        own["outlier_density"] = outlier_density(measurement_noise)
    elif len(data.measurements):
        field_range, field_fov = perceptual_field(data)
        own = {"negative_information": True, "sensor_range": field_range, "sensor_fov": field_fov}
    return dataset_options(options, fields, **own)


def run_fastslam(data: Mrclam, motion_noise=None, measurement_noise=None, *, known: bool = True,
                 options: Optional[FastSlamOptions] = None, initial_pose=None, command_period: float = COMMAND_PERIOD,
                 progress: Optional[bool] = False, **fields) -> LandmarkSlamResult:
    """FastSLAM over an MRCLAM robot, as ``run_ekf`` runs the EKF: odometry (v, w) between
    stamps; the control noise ``motion_noise`` (2, 2; default ``MOTION_NOISE``) is that of one
    command period, applied as white velocity noise (pose noise V (M period / dt) V^T for a step
    of dt); the measurements of one stamp form one scan. ``known``: the barcodes are the
    correspondences; else each particle associates by maximum likelihood
    (``FastSlam.update_unknown``).

    ``options``: a FastSlamOptions, ``fields`` fields of it by keyword (num_particles, version,
    seed, threads, ...); where they hold FastSlamOptions' defaults the dataset's own apply
    (``fastslam_options``): p_new ``DEFAULT_P_NEW``; with known correspondences outliers rejected
    as ``run_ekf`` does (``outlier_density``); with hidden ones negative information in the
    camera's field (``perceptual_field``): a landmark there that a scan does not see loses
    existence, and a particle's duplicates, never seen again, are removed. The start pose defaults
    to ``start_pose(data)``. ``times`` are the stamps of the best particle's path: the start,
    then one per prediction. ``progress``: a bar over the controls (None: on a terminal only)."""
    _require_odometry(data)
    motion_noise = MOTION_NOISE if motion_noise is None else motion_noise
    measurement_noise = MEASUREMENT_NOISE if measurement_noise is None else measurement_noise
    o = fastslam_options(data, measurement_noise, known, options, **fields)
    initial_pose = start_pose(data) if initial_pose is None else initial_pose
    m_rate = np.asarray(motion_noise, float) * command_period
    f = FastSlam(np.eye(3) * 0.0, measurement_noise, initial_pose=initial_pose, options=o)
    histories = None if known else AssociationHistories()
    times = [data.odometry[0, 0]]  # of the path's poses: the start, then one per prediction
    zero = np.zeros(3)
    t0 = time.perf_counter()
    for event in _timeline(data, progress=progress, desc=f"FastSLAM {o.version}.0"):
        if event[0] == "move":
            # Robot-frame motion and its covariance: V (M period / dt) V^T at the origin.
            _, v, w, t, dt = event
            delta = velocity_motion(zero, v, w, dt)
            jac = velocity_motion_control_jacobian(zero, v, w, dt)
            f.predict_odometry(delta, jac @ (m_rate / dt) @ jac.T)
            times.append(t + dt)
        elif event[0] == "scan":
            rows = event[1]
            truth = rows[:, 1].astype(np.int64)
            if known:
                f.update(rows[:, 2:4], truth)
            else:
                ids = f.update_unknown(rows[:, 2:4]).ids
                histories.add(f, ids, truth, rows[0, 0])
    return result_of(f, np.array(times), time.perf_counter() - t0, histories)


def fit_range_scale(data: Mrclam) -> float:
    """The scale k of MRCLAM's depth readings (distance = k * range / cos(bearing), see
    ``io.MRCLAM_RANGE_SCALE``) fitted against the ground truth: the median over the sightings of
    true distance * cos(bearing) / range, the true distance measured from the interpolated
    ground-truth pose to the surveyed landmark."""
    require_instance(data, Mrclam, "data")
    if data.groundtruth is None:
        raise ValueError("data: fitting the range scale needs the robot's ground truth")
    surveyed = data.landmark_positions
    m = data.measurements[[int(s) in surveyed for s in data.measurements[:, 1]]]
    m = m[m[:, 2] > 0]
    if len(m) == 0:
        raise ValueError("data: no sightings of surveyed landmarks with a positive range")
    truth = np.array([surveyed[int(s)] for s in m[:, 1]])
    distance = np.hypot(*(truth - truth_positions(data.groundtruth, m[:, 0])).T)
    return float(np.median(distance * np.cos(m[:, 3]) / m[:, 2]))


def same_scan_residuals(data: Mrclam) -> Dict[int, np.ndarray]:
    """A check of the survey against the barcodes that needs no robot pose: for two landmarks
    sighted in one scan, their distance computed from the two range-bearing readings minus their
    surveyed distance. Returns subject -> residuals (m) of the pairs it is part of."""
    require_instance(data, Mrclam, "data")
    surveyed = data.landmark_positions
    out: Dict[int, list] = {s: [] for s in surveyed}
    for rows in data.scans():
        m = data.measurements[rows]
        points = m[:, 2:3] * np.column_stack([np.cos(m[:, 3]), np.sin(m[:, 3])])
        for a, b in itertools.combinations(range(len(m)), 2):
            i, j = int(m[a, 1]), int(m[b, 1])
            if i != j and i in surveyed and j in surveyed:
                r = np.hypot(*(points[a] - points[b])) - np.hypot(*(surveyed[i] - surveyed[j]))
                out[i].append(r)
                out[j].append(r)
    return {s: np.array(r) for s, r in out.items()}


def survey_label_swaps(data: Mrclam, limit: float = SURVEY_RESIDUAL_LIMIT) -> List[Tuple[int, int]]:
    """Pairs of subjects whose surveyed positions are exchanged relative to their barcodes: each
    round takes, among the swaps of two subjects failing the same-scan distance check (median
    |residual| > ``limit``) that make both pass, the one with the smallest sum of medians; a
    wrong label spoils its partners' pairs too, so the whole map is rechecked each round.
    MRCLAM Dataset 1: [(11, 17)]."""
    require_instance(data, Mrclam, "data")

    def median_error(swaps: List[Tuple[int, int]]) -> Dict[int, float]:
        residuals = same_scan_residuals(data.with_survey_swapped(swaps))
        return {s: float(np.median(np.abs(r))) if len(r) else 0.0 for s, r in residuals.items()}

    swaps: List[Tuple[int, int]] = []
    while True:
        bad = sorted(s for s, e in median_error(swaps).items() if e > limit)
        best, smallest = None, np.inf
        for a, b in itertools.combinations(bad, 2):
            errors = median_error(swaps + [(a, b)])
            if errors[a] <= limit and errors[b] <= limit and sum(errors.values()) < smallest:
                best, smallest = (a, b), sum(errors.values())
        if best is None:
            return swaps
        swaps.append(best)


def dead_reckoning(odometry: np.ndarray, initial_pose) -> np.ndarray:
    """(M, 3) poses integrating (t, v, w) rows with the velocity motion model."""
    poses = np.empty((len(odometry), 3))
    x = np.asarray(initial_pose, float)
    for k in range(len(odometry)):
        poses[k] = x
        if k + 1 < len(odometry) and odometry[k + 1, 0] > odometry[k, 0]:
            x = velocity_motion(x, odometry[k, 1], odometry[k, 2], odometry[k + 1, 0] - odometry[k, 0])
    return poses


def dead_reckoning_map(data: Mrclam, initial_pose=(0.0, 0.0, 0.0)) -> Dict[int, np.ndarray]:
    """Subject -> mean of the points where its sightings land from the dead-reckoned pose: the map
    odometry alone would draw, the baseline for a SLAM map when there is no robot ground truth."""
    require_instance(data, Mrclam, "data")
    odo, meas = data.odometry, data.measurements
    poses = dead_reckoning(odo, initial_pose)
    placed: Dict[int, list] = {}
    for t, subject, r, phi in meas:
        k = int(np.searchsorted(odo[:, 0], t, side="right")) - 1
        if k < 0:
            continue  # before the first control
        x = velocity_motion(poses[k], odo[k, 1], odo[k, 2], t - odo[k, 0]) if t > odo[k, 0] else poses[k]
        placed.setdefault(int(subject), []).append(x[:2] + r * np.array([np.cos(x[2] + phi), np.sin(x[2] + phi)]))
    return {s: np.mean(p, axis=0) for s, p in placed.items()}


def refinement_input(run: LandmarkSlamResult, data: Mrclam, motion_noise, measurement_noise,
                     command_period: float = COMMAND_PERIOD) -> RefinementInput:
    """The arrays of ``landmark_refine.refine_landmarks`` from a filter run over an MRCLAM robot
    (``run_ekf`` / ``run_fastslam``): ``motion_noise`` (2, 2) and ``measurement_noise`` (2, 2) the
    noise the run used (per ``command_period`` of control, as the runs take it). The poses are the
    start (held) and one per scan, the odometry between them the controls integrated as the
    filters predict them (``probslam.velocity_increments``)."""
    require_fields(run, ("times", "poses", "landmarks", "associations"), "run", "a LandmarkSlamResult")
    require_instance(data, Mrclam, "data")
    motion_noise = real_array(motion_noise, "motion_noise", (2, 2))
    measurement_noise = real_array(measurement_noise, "measurement_noise", (2, 2))
    command_period = positive_real(command_period, "command_period")
    odo, meas = data.odometry, data.measurements
    if len(odo) < 2:
        raise ValueError("data: the robot needs at least two odometry rows")
    # The sightings the filters take: scans stamped from the first control to before the last.
    scan_rows = [r for r in data.scans() if odo[0, 0] <= meas[r.start, 0] < odo[-1, 0]]
    rows = np.concatenate([np.arange(r.start, r.stop) for r in scan_rows]) if scan_rows else np.empty(0, np.int64)
    scan_times = np.array([meas[r.start, 0] for r in scan_rows])
    truth = meas[rows, 1].astype(np.int64)
    labels = run_labels(run, truth)
    # The motion pieces the filters predict over: each control from its stamp to the next event.
    events = np.unique(np.concatenate([odo[:, 0], scan_times]))
    control = np.searchsorted(odo[:, 0], events[:-1], side="right") - 1
    dt = np.diff(events)
    noise = np.asarray(motion_noise, float)[None] * (command_period / dt)[:, None, None]
    deltas, covs = velocity_increments(odo[control, 1], odo[control, 2], dt, noise)
    nodes = np.concatenate([[0], np.searchsorted(events, scan_times)])
    odometry, odometry_cov = compose_increments(deltas, covs, nodes)
    # The run's poses at the nodes, from the dead-reckoned chain between its records.
    chain = accumulate(np.zeros(3), deltas)
    times, recorded = np.asarray(run.times, float), np.asarray(run.poses, float)
    poses = poses_at_nodes(times, recorded, events, chain)[nodes]
    scan_of_row = np.repeat(np.arange(1, len(scan_rows) + 1), [r.stop - r.start for r in scan_rows])
    return RefinementInput(np.concatenate([[odo[0, 0]], scan_times]), poses, odometry, floor_covariances(odometry_cov),
                           scan_of_row.astype(np.int64), meas[rows, 2:4], labels, measurement_noise,
                           {int(k): np.asarray(v, float) for k, v in run.landmarks.items()}, rows, truth)



#: The EKF's association with hidden correspondences on MRCLAM when none is named: the
#: multiple-hypothesis EKF, the one association that holds on every robot of Datasets 1 and 7
#: (JCBB builds 40 landmarks for 15 on Dataset 1 robot 1, docs/ekf_slam.md).
DEFAULT_ASSOCIATION = "mht"


class MrclamRobot(LandmarkDataset):
    """One MRCLAM robot as a landmark run sees it (``landmark_dataset.LandmarkDataset``): its
    barcodes as labels, ``MOTION_SIGMA`` / ``MEASUREMENT_SIGMA`` as the noise unless the options
    name others, scored against the robot's ground truth and the landmark survey (the survey alone
    where the dataset has no robot ground truth, Dataset 1)."""

    OPTIONS = ("robot", "seconds", "raw_ranges", "sigma_v", "sigma_w", "sigma_r", "sigma_phi")
    LABEL = "UTIAS MRCLAM"

    DATA = Mrclam

    def __init__(self, data: Mrclam, path: Optional[PathLike] = None, robot: int = 1, seconds: Optional[float] = None,
                 raw_ranges: bool = False):
        super().__init__(data, path)
        self.robot, self.seconds, self.raw_ranges = robot, seconds, raw_ranges

    @classmethod
    def check(cls, options, path) -> None:
        """As ``LandmarkDataset.check``; and the options of ``hypotheses`` need the
        multiple-hypothesis EKF, refine hidden correspondences."""
        super().check(options, path)
        changed = differing_field(options.hypotheses, MultiHypothesisOptions())
        if changed is not None and not (options.unknown and options.association in (None, "mht")):
            raise ValueError(f"hypotheses.{changed} needs unknown correspondences and association mht")
        if options.refine != "none" and not options.unknown:
            raise ValueError("refine graphslam needs unknown correspondences (with known ones there is nothing to "
                             "refine)")

    @classmethod
    def load(cls, path, options) -> "MrclamRobot":
        """The robot of ``options.robot`` (1 when None), its window and ranges (``load``)."""
        robot = 1 if options.robot is None else options.robot
        return cls(load(path, robot, options.seconds, options.raw_ranges), path, robot, options.seconds,
                   options.raw_ranges)

    def noise(self, options) -> dict:
        """The (2, 2) covariances of the sigma options, MOTION_SIGMA / MEASUREMENT_SIGMA where unset."""
        sigma = [d if v is None else v for v, d in zip((options.sigma_v, options.sigma_w, options.sigma_r,
                                                         options.sigma_phi), MOTION_SIGMA + MEASUREMENT_SIGMA)]
        return dict(motion_noise=np.diag([sigma[0] ** 2, sigma[1] ** 2]),
                    measurement_noise=np.diag([sigma[2] ** 2, sigma[3] ** 2]))

    def association(self, options) -> str:
        """The option, or ``DEFAULT_ASSOCIATION``."""
        return options.association or DEFAULT_ASSOCIATION

    def run(self, options, progress: Optional[bool] = None) -> LandmarkSlamResult:
        """``run_ekf`` (EKF or the multiple-hypothesis EKF) or ``run_fastslam`` with the options' noise."""
        noise = self.noise(options)
        if options.method == "fastslam":
            return self.run_filter("fastslam", known=not options.unknown, options=options.fastslam,
                                   progress=progress, **noise)
        association = self.association(options)
        mht = options.unknown and association == "mht"
        return self.run_filter("mht" if mht else "ekf", known=not options.unknown, association=association,
                               hypotheses=options.hypotheses if mht else None, progress=progress, **noise)

    def _run_filter(self, method, known, motion_noise, measurement_noise, association, hypotheses, fastslam,
                    progress) -> LandmarkSlamResult:
        if method == "fastslam":
            return run_fastslam(self.data, motion_noise, measurement_noise, known=known, progress=progress, **fastslam)
        return run_ekf(self.data, motion_noise, measurement_noise, known=known or method == "dead-reckoning",
                       association="mht" if method == "mht" else association, hypotheses=hypotheses,
                       dead_reckoning=method == "dead-reckoning", progress=progress)

    def summary(self, result: LandmarkSlamResult, options, seconds: float) -> List[str]:
        """The robot, its correspondences and readings, what the filter took and mapped."""
        data, source = self.data, f"UTIAS MRCLAM {self.path} robot {self.robot}"
        if options.method == "fastslam":
            return ([f"dataset:       {source}, {'unknown' if options.unknown else 'known'} correspondences"]
                    + fastslam_lines(result, options) + association_line(result))
        association = self.association(options)
        sigma = options.hypotheses.bearing_offset_sigma
        offset = f"bearing offset {sigma:g} rad per scan, " if sigma and options.unknown and association == "mht" else ""
        ranges = "raw depth readings" if self.raw_ranges else f"ranges from depth x {MRCLAM_RANGE_SCALE}"
        return [f"dataset:       {source}, {'unknown (' + association + ')' if options.unknown else 'known'} "
                f"correspondences, {offset}{ranges}",
                f"odometry:      {len(data.odometry)} controls; measurements: {len(data.measurements)} of landmarks "
                f"({data.robot_measurements} of robots dropped), {result.rejected} gated as outliers",
                f"landmarks:     {len(result.landmarks)} in the map; filter time {result.seconds:.2f} s",
                *association_line(result, "barcode", len(data.measurements))]

    def refinement_input(self, run: LandmarkSlamResult, motion_noise=None, measurement_noise=None,
                         command_period: float = COMMAND_PERIOD) -> RefinementInput:
        """``refinement_input`` of the run (the noise it ran with: both needed)."""
        if motion_noise is None or measurement_noise is None:
            raise ValueError("motion_noise, measurement_noise: MRCLAM runs need the noise they were run with")
        return refinement_input(run, self.data, motion_noise, measurement_noise, command_period)

    def score(self, result: LandmarkSlamResult, options) -> DatasetScore:
        """The path and map errors against the ground truth and survey (``eval.score_mrclam``), and
        the dead reckoning's; without robot ground truth (Dataset 1) the map alone, aligned onto the
        survey after the survey labels that contradict the barcodes have been exchanged
        (``eval.score_landmarks``). ValueError when a score is not finite (no mapped landmark in the
        survey, or coordinates too large to square)."""
        dead = self.run_filter("dead-reckoning", progress=False, **self.noise(options))
        labels = majority_labels(result) if result.associations is not None else None
        if self.data.groundtruth is None:
            return self._survey_score(result, dead, labels)
        from ..plot import ALIGNED_SUFFIX

        with np.errstate(over="ignore", invalid="ignore"):  # huge coordinates: refused just below
            s, d = score_mrclam(result, self.data, labels), score_mrclam(dead, self.data)
        _require_finite(s.path_rmse, s.path_rmse_aligned, s.landmark_rmse, s.landmark_rmse_aligned)
        lines = [f"path RMSE:     {s.path_rmse:.3f} m raw, {s.path_rmse_aligned:.3f} m aligned "
                 f"(dead reckoning {d.path_rmse:.3f} / {d.path_rmse_aligned:.3f} m)",
                 f"landmark RMSE: {s.landmark_rmse:.3f} m raw, {s.landmark_rmse_aligned:.3f} m aligned"]
        reference = dict(dead_reckoning=dead.poses[:, :2] @ d.rotation.T + d.translation,
                         truth_landmarks_label="surveyed landmarks", truth_path=self.data.groundtruth[:, 1:3],
                         truth_landmarks=self.data.landmark_positions, align=(s.rotation, s.translation),
                         dead_reckoning_label="dead reckoning" + ALIGNED_SUFFIX)
        metrics = dict(path_rmse_m=float(s.path_rmse), path_rmse_aligned_m=float(s.path_rmse_aligned),
                       landmark_rmse_m=float(s.landmark_rmse), landmark_rmse_aligned_m=float(s.landmark_rmse_aligned),
                       dead_reckoning_rmse_m=float(d.path_rmse), dead_reckoning_rmse_aligned_m=float(d.path_rmse_aligned),
                       **self._map_metrics(result, labels, self._survey_rmse(result, labels)))
        return DatasetScore(lines, reference, dict(score=s, dead_reckoning=d), metrics)

    def _survey_rmse(self, result: LandmarkSlamResult, labels) -> float:
        """The map's RMSE after aligning it onto the survey, its labels that contradict the barcodes
        exchanged (as ``_survey_score`` has it without robot ground truth); NaN when no landmark
        of the map is in the survey."""
        fixed = self.data.with_survey_swapped(survey_label_swaps(self.data))
        try:
            return score_landmarks(result.landmarks, fixed, labels).rmse_aligned
        except ValueError:
            return float("nan")

    def _map_metrics(self, result: LandmarkSlamResult, labels, survey_rmse: float) -> Dict[str, float]:
        """The association table's measures: the map's RMSE aligned onto the survey, the robot's
        sightings and the surveyed landmarks they name, and with hidden correspondences the share
        of sightings whose landmark's majority barcode is their own and ``association_metrics``."""
        seen = set(self.data.measurements[:, 1].astype(int).tolist()) & set(self.data.landmark_positions)
        out = {"map_rmse_survey_aligned_m": float(survey_rmse), "sightings": len(self.data.measurements),
               "landmarks_seen": len(seen)}
        if labels is not None:
            out["association_correct"] = float(association_accuracy(result))
        return {**out, **association_metrics(result)}

    def refinement_metrics(self, refined: RunRefinement, cpu_seconds: float) -> Dict[str, object]:
        """As ``LandmarkDataset.refinement_metrics``; with robot ground truth also the filter's path
        at the refinement's poses (one per scan), aligned onto it: what the refined run's
        path_rmse_aligned_m is measured against."""
        out = super().refinement_metrics(refined, cpu_seconds)
        if self.data.groundtruth is not None:
            start = refined.input
            filtered = LandmarkSlamResult("filter", start.times, start.poses, start.landmarks, None)
            with np.errstate(over="ignore", invalid="ignore"):
                out["filter_path_rmse_aligned_m"] = float(score_mrclam(filtered, self.data).path_rmse_aligned)
        return out

    def _survey_score(self, result: LandmarkSlamResult, dead: LandmarkSlamResult, labels) -> DatasetScore:
        swaps = survey_label_swaps(self.data)
        lines = [f"survey:        positions of subjects {', '.join(f'{a}<->{b}' for a, b in swaps)} exchanged "
                 f"(their surveyed distances contradict the readings of the same scans)"] if swaps else []
        fixed = self.data.with_survey_swapped(swaps)
        with np.errstate(over="ignore", invalid="ignore"):  # huge coordinates: refused just below
            s = score_landmarks(result.landmarks, fixed, labels)
            d = score_landmarks(dead_reckoning_map(self.data), fixed)
        _require_finite(s.rmse_aligned)
        lines.append(f"landmark RMSE: {s.rmse_aligned:.3f} m after aligning the map onto the survey "
                     f"(dead-reckoning map {d.rmse_aligned:.3f} m; no robot ground truth)")
        reference = dict(dead_reckoning=dead.poses, truth_landmarks_label="surveyed landmarks (aligned onto the map)",
                         truth_landmarks=s.survey_in_map_frame(fixed))
        return DatasetScore(lines, reference, dict(score=s, dead_reckoning=d),
                            self._map_metrics(result, labels, s.rmse_aligned))

    def title(self, options) -> str:
        """The folder, robot and window, for the picture's title."""
        return f"UTIAS MRCLAM {self.path.name} robot {self.robot}" + (f", {self.seconds:g} s" if self.seconds else "")

    def caption(self, options) -> str:
        """The filter and its association, for the picture's title."""
        if options.method == "ekf" and options.unknown:
            return f"EKF SLAM, unknown correspondences, {self.association(options)}"
        return super().caption(options)


def _require_finite(*scores: float) -> None:
    """ValueError when a score is NaN or inf: no mapped landmark is in the survey, or the survey or
    ground truth holds coordinates too large to square (the run went through, the files did not fit)."""
    if not all(np.isfinite(v) for v in scores):
        raise ValueError("the MRCLAM scores are not finite numbers: no landmark of the map is in "
                         "Landmark_Groundtruth.dat, or its or the ground truth's coordinates are too large")


__all__ = ["COMMAND_PERIOD", "DEFAULT_ASSOCIATION", "MEASUREMENT_NOISE", "MrclamRobot", "MEASUREMENT_SIGMA",
           "MHT_DETECTION_PROBABILITY",
           "MHT_NEW_LANDMARK_COST", "MOTION_NOISE", "MOTION_SIGMA",
           "OUTLIER_PROBABILITY", "PERCEPTUAL_FIELD_QUANTILE", "outlier_density", "ROBOTS", "SURVEY_RESIDUAL_LIMIT", "dead_reckoning",
           "dead_reckoning_map", "fastslam_options", "first_seconds", "fit_range_scale", "load", "perceptual_field", "refinement_input", "run_ekf",
           "run_fastslam", "same_scan_residuals", "start_pose", "survey_label_swaps"]
