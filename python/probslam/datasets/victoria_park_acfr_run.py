"""Landmark SLAM over the original Victoria Park run (``datasets.victoria_park_acfr``): the car's
model (``probslam.ackermann_motion``, Guivant and Nebot) stepped at the inputs' own rate, 40 Hz,
each laser scan's detections applied at their stamp (the step that holds a scan is cut there),
correspondences unknown (the detections have no identities), the trunk's diameter as signature.
The noise of the inputs and of the detections is one published configuration for this run (below),
one set for every method; no value was searched on this run's result (docs/landmark_fastslam.md
says which two settings of it were run). Units: metres, radians, seconds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import List, Optional

import numpy as np

from .._args import positive_real, require_fields, require_instance
from .._core import AckermannGeometry, FastSlam, FastSlamOptions, MultiHypothesisOptions, ackermann_increments
from .._progress import progress_bar
from ..ekf import EkfSlam, MapManagement
from ..fastslam import AssociationHistories, dataset_options, result_of
from ..geometry import between, compose
from ..io.landmark_datasets import VictoriaParkAcfr
from ..landmark_refine import UNASSIGNED, RefinementInput, RunRefinement, compose_increments, floor_covariances
from ..landmark_slam import Associations, LandmarkSlamResult, ekf_landmarks
from ..eval import position_error
from . import victoria_park_acfr
from .landmark_dataset import (EKF_ASSOCIATIONS, LandmarkDataset, DatasetScore, RefinedRun, refinement_keywords,
                               refuse_hypotheses, require_fastslam_options)

# The noise of the inputs and detections: RFS-SLAM's FastSLAM configuration for this run
# (kykleung/RFS-SLAM cfg/fastslam_VictoriaPark.xml; its converter made the dataset's files): the
# sensors' variances (speed 0.2 (m/s)^2, steering 0.025 rad^2, range 0.025 m^2, bearing 2.5e-5
# rad^2, diameter 0.002 m^2) times the inflation that configuration runs its filter with (x15 for
# the inputs, x75 for the detections: white noise per reading stands for errors that are not
# white, wheel slip and the trunk's centre seen from different sides). Taken as published,
# not chosen on this run's result.
#: Inflation of the inputs' and the detections' variances (RFS-SLAM's processNoiseInflationFactor
#: and measurementNoiseInflationFactor).
INPUT_INFLATION, DETECTION_INFLATION = 15.0, 75.0
#: Standard deviation (m/s) of one encoder speed reading.
SPEED_SIGMA = float(np.sqrt(0.2 * INPUT_INFLATION))
#: Standard deviation (rad) of one steering reading.
STEERING_SIGMA = float(np.sqrt(0.025 * INPUT_INFLATION))
#: Standard deviations of a detection's range (m), bearing (rad) and trunk diameter (m).
RANGE_SIGMA = float(np.sqrt(0.025 * DETECTION_INFLATION))
BEARING_SIGMA = float(np.sqrt(2.5e-5 * DETECTION_INFLATION))
DIAMETER_SIGMA = float(np.sqrt(0.002 * DETECTION_INFLATION))
#: The provisional-landmark rule of the same published configuration (its landmarkCandidate
#: block: MeasurementCountThreshold 4, MeasurementCheckThreshold 20): a new landmark joins the map
#: once seen in PROVISIONAL_SIGHTINGS scans, and is forgotten after PROVISIONAL_MAX_AGE scans
#: without a sighting before then (``FastSlam(min_sightings=, provisional_max_age=)``,
#: ``MapManagement.provisional``). Off by default: measured on this run it lowered the landmark
#: count but raised the error against GPS (docs/victoria_park.md).
PROVISIONAL_SIGHTINGS, PROVISIONAL_MAX_AGE = 4, 20
#: The detector's field: ranges it reports (m; the detections span 1-75 m), its 180 deg scan.
MAX_RANGE = 75.0
FIELD_OF_VIEW = np.pi


def control_noise() -> np.ndarray:
    """(2, 2) the covariance of one input (speed, steering), held over its step."""
    return np.diag([SPEED_SIGMA ** 2, STEERING_SIGMA ** 2])


def measurement_noise(signatures: bool = False) -> np.ndarray:
    """(2, 2) the covariance of a detection's (range, bearing); (3, 3) with the diameter."""
    sigmas = [RANGE_SIGMA, BEARING_SIGMA] + ([DIAMETER_SIGMA] if signatures else [])
    return np.diag(np.square(sigmas))


def geometry() -> AckermannGeometry:
    """The car's geometry of ``victoria_park_acfr`` (Guivant and Nebot's model)."""
    return AckermannGeometry(victoria_park_acfr.WHEELBASE, victoria_park_acfr.ENCODER_OFFSET,
                             victoria_park_acfr.LASER_AHEAD, victoria_park_acfr.LASER_LEFT)


@dataclass(frozen=True)
class Schedule:
    """The run cut into steps: step k holds input ``control[k]`` from ``ends[k] - dt[k]`` to
    ``ends[k]``, as the relative pose ``deltas[k]`` (the sensor's frame) with covariance
    ``covariances[k]``; scan s is applied after step ``scan_after[s]`` (-1: before any)."""

    ends: np.ndarray
    deltas: np.ndarray
    covariances: np.ndarray
    scan_after: np.ndarray


def schedule(data: VictoriaParkAcfr, noise: Optional[np.ndarray] = None) -> Schedule:
    """The steps of ``data`` at the inputs' rate, cut at every scan's stamp inside the inputs'
    span; scans before the first input are applied at the start, scans after the last at the end."""
    require_instance(data, VictoriaParkAcfr, "data")
    t_in = data.inputs[:, 0]
    if len(t_in) < 2:
        raise ValueError("data: fewer than two inputs, no step to drive")
    scans = data.scan_times
    cuts = np.union1d(t_in, scans[(scans > t_in[0]) & (scans < t_in[-1])])
    control = np.searchsorted(t_in, cuts[:-1], side="right") - 1
    dt = np.diff(cuts)
    deltas, covariances = ackermann_increments(data.inputs[control, 1], data.inputs[control, 2], dt,
                                               control_noise() if noise is None else noise, geometry())
    scan_after = np.searchsorted(cuts[1:], scans, side="left")
    scan_after[scans <= cuts[0]] = -1
    scan_after = np.minimum(scan_after, len(dt) - 1)
    return Schedule(cuts[1:], deltas, covariances, scan_after)


def first_seconds(data: VictoriaParkAcfr, seconds: float) -> VictoriaParkAcfr:
    """The run's first ``seconds`` after its first input: the inputs, scans and GPS fixes before
    then (a prefix to test or show a method on)."""
    require_instance(data, VictoriaParkAcfr, "data")
    seconds = positive_real(seconds, "seconds")
    end = data.inputs[0, 0] + seconds
    m = data.measurements[data.measurements[:, 0] < end]
    starts = np.flatnonzero(np.r_[True, np.diff(m[:, 0]) != 0]) if len(m) else np.empty(0, np.int64)
    gps = None if data.gps is None else data.gps[data.gps[:, 0] < end]
    return VictoriaParkAcfr(data.inputs[data.inputs[:, 0] < end], m, np.r_[starts, len(m)].astype(np.int64), gps,
                            dict(data.skipped_rows))


def _measurements(data: VictoriaParkAcfr, signatures: bool):
    """Each scan's measurement rows: (range, bearing[, diameter])."""
    columns = slice(1, 4 if signatures else 3)
    z = np.ascontiguousarray(data.measurements[:, columns])
    return [z[a:b] for a, b in zip(data.scan_starts[:-1], data.scan_starts[1:])]


def _drive(data, steps: Schedule, predict, update, desc: str, progress: Optional[bool]):
    """Runs the schedule: predict(a, b) for the steps a..b-1 between two scans (one call each:
    the filters' batched predictions), update(s) per scan; the stamps of the poses (the start,
    then one per step)."""
    order = np.argsort(steps.scan_after, kind="stable")
    after = steps.scan_after[order]
    bounds = np.searchsorted(after, np.arange(-1, len(steps.ends) + 1))
    for s in order[bounds[0]:bounds[1]]:
        update(int(s))
    # The steps after which a scan comes, and the run's end: each block of steps ends at one.
    ends = np.unique(np.r_[after[after >= 0], len(steps.ends) - 1])
    start = 0
    with progress_bar(len(steps.ends), desc, "step", progress) as bar:
        for k in ends:
            predict(start, int(k) + 1)
            for s in order[bounds[k + 1]:bounds[k + 2]]:
                update(int(s))
            bar.update(int(k) + 1 - start)
            start = int(k) + 1
    return np.concatenate([[data.inputs[0, 0]], steps.ends])


def run_ekf(data: VictoriaParkAcfr, *, signatures: bool = True, association: str = "jcbb",
            dead_reckoning: bool = False, provisional: bool = False,
            progress: Optional[bool] = False) -> LandmarkSlamResult:
    """EKF SLAM (Table 10.2, unknown correspondences by ``association``: "jcbb" or "ml") over the
    run from ``victoria_park_acfr.start_pose``; ``signatures``: the trunk's diameter joins each
    detection (the default: the detector measures it, and it tells neighbouring trees apart).
    ``dead_reckoning``: predictions only. ``provisional``: new landmarks wait on the provisional
    list (``PROVISIONAL_SIGHTINGS``, ``PROVISIONAL_MAX_AGE``). ``times``: the start, then the end of
    each step; ``poses``: the filter's pose then."""
    steps = schedule(data)
    z = _measurements(data, signatures)
    ekf = EkfSlam(control_noise(), measurement_noise(signatures), use_signatures=signatures,
                  initial_pose=victoria_park_acfr.start_pose(data))
    if provisional:
        ekf.map_management = provisional_list()
    poses = [ekf.pose[None, :]]
    ids = np.full(len(data.measurements), UNASSIGNED, np.int64)
    t0 = time.perf_counter()

    def predict(a, b):
        poses.append(ekf.predict_odometry_batch(steps.deltas[a:b], steps.covariances[a:b]))

    def update(s):
        if not dead_reckoning:
            ids[data.scan_starts[s]:data.scan_starts[s + 1]] = ekf.update_unknown(z[s], association=association).ids

    times = _drive(data, steps, predict, update, "dead reckoning" if dead_reckoning else "EKF SLAM", progress)
    seconds = time.perf_counter() - t0
    return LandmarkSlamResult("dead-reckoning" if dead_reckoning else "ekf", times, np.concatenate(poses),
                              ekf_landmarks(ekf), ekf, seconds, None if dead_reckoning else _record(data, ids))


def _record(data: VictoriaParkAcfr, ids: np.ndarray) -> Associations:
    """The association record of a run: per detection (the data's row order) its scan's stamp,
    no label of its own (``truth`` -1: the detections have no identities) and the filter's
    landmark (-1: none)."""
    return Associations(data.measurements[:, 0].copy(), np.full(len(ids), UNASSIGNED, np.int64), ids)


def provisional_list() -> MapManagement:
    """EkfSlam's provisional list with ``PROVISIONAL_SIGHTINGS`` and ``PROVISIONAL_MAX_AGE`` (no
    bound on a provisional landmark's spread: the rule counts sightings)."""
    m = MapManagement()
    m.provisional, m.min_observations, m.provisional_max_age = True, PROVISIONAL_SIGHTINGS, PROVISIONAL_MAX_AGE
    m.provisional_max_std = float(np.finfo(float).max)
    return m


def run_fastslam(data: VictoriaParkAcfr, *, options: Optional[FastSlamOptions] = None, signatures: bool = True,
                 provisional: bool = False, progress: Optional[bool] = False, **fields) -> LandmarkSlamResult:
    """FastSLAM over the run, unknown correspondences (per particle, joint maximum likelihood),
    from ``victoria_park_acfr.start_pose``; ``signatures``, ``provisional``: as ``run_ekf``'s (the
    provisional list: ``PROVISIONAL_SIGHTINGS``, ``PROVISIONAL_MAX_AGE`` where the options leave
    min_sightings and provisional_max_age at their defaults). ``options``: a FastSlamOptions,
    ``fields`` fields of it by keyword (num_particles, version, seed, threads, ...), p_new
    ``DEFAULT_P_NEW`` where left at FastSlamOptions' default (``fastslam.dataset_options``);
    use_signatures is ``signatures``. ``times``: the start, then the end of each step; ``poses``:
    the best particle's path."""
    steps = schedule(data)
    z = _measurements(data, signatures)
    own = {"min_sightings": PROVISIONAL_SIGHTINGS, "provisional_max_age": PROVISIONAL_MAX_AGE} if provisional else {}
    o = dataset_options(options, {**fields, "use_signatures": signatures}, **own)
    f = FastSlam(np.zeros((3, 3)), measurement_noise(signatures), initial_pose=victoria_park_acfr.start_pose(data),
                 options=o)
    # Each particle's associations, carried along the resamplings (O(1) Python work per scan): the
    # best particle's record is what the GraphSLAM refinement starts from.
    histories = AssociationHistories()
    no_label = np.full(len(data.measurements), UNASSIGNED, np.int64)

    def update(s):
        a, b = data.scan_starts[s], data.scan_starts[s + 1]
        histories.add(f, f.update_unknown(z[s]).ids, no_label[a:b], float(data.measurements[a, 0]))

    t0 = time.perf_counter()
    times = _drive(data, steps, lambda a, b: f.predict_odometry_batch(steps.deltas[a:b], steps.covariances[a:b]),
                   update, f"FastSLAM {o.version}.0", progress)
    return result_of(f, times, time.perf_counter() - t0, histories)


# ---------------------------------------------------------------------------------------------
# GraphSLAM's refinement (``probslam.landmark_refine``) of a run.


def refinement_input(run: LandmarkSlamResult, data: VictoriaParkAcfr) -> RefinementInput:
    """The arrays of ``landmark_refine.refine_landmarks`` from an EKF or FastSLAM run over
    ``data`` (``run_ekf`` / ``run_fastslam``, or ``run_landmark_slam``): one pose per scan's step
    (and the start, held as the gauge), the run's poses there; between two, the car's steps
    (``schedule``: the Ackermann increments, speed and steering noise carried by their Jacobian)
    composed into one motion and its covariance (``compose_increments``, floored as
    ``floor_covariances`` says, for stretches where the car stands); every detection's
    (range, bearing) with the run's noise (``measurement_noise()``) on the run's landmark (its
    association record; UNASSIGNED where it put the detection on none). The diameter is not
    used: the graph is geometry. ``times`` are the poses' stamps, ``rows`` the detections' rows,
    ``truth`` -1 (no identities)."""
    require_fields(run, ("times", "poses", "landmarks", "associations"), "run", "a LandmarkSlamResult")
    require_instance(data, VictoriaParkAcfr, "data")
    steps = schedule(data)
    poses = np.asarray(run.poses, float)
    if poses.shape != (len(steps.ends) + 1, 3):
        raise ValueError(f"run: holds {len(poses)} poses, the data's schedule {len(steps.ends) + 1} "
                         "(was it run on this data?)")
    record = run.associations
    if record is None:
        raise ValueError(f"run: a {run.method} run holds no association record, nothing to refine")
    k = len(data.measurements)
    if len(record) != k or np.any(np.asarray(record.times) != data.measurements[:, 0]):
        raise ValueError("run: its associations do not follow the data's detections (was it run on this data?)")
    node_of_scan = steps.scan_after + 1  # pose 0 is the start, pose j + 1 the end of step j
    nodes = np.unique(np.r_[0, node_of_scan])
    odometry, covariances = compose_increments(steps.deltas, steps.covariances, nodes)
    scan_of_row = np.repeat(np.arange(len(data.scan_starts) - 1), np.diff(data.scan_starts))
    pose_index = np.searchsorted(nodes, node_of_scan)[scan_of_row].astype(np.int64)
    labels = np.where(np.asarray(record.ids) >= 0, record.ids, UNASSIGNED).astype(np.int64)
    # Scans applied at one pose (those past the inputs' end) are one scan to the refinement, which
    # sees distinct landmarks in it: a landmark named twice there keeps its first detection.
    order = np.lexsort((np.arange(k), labels, pose_index))
    repeated = np.r_[False, (np.diff(pose_index[order]) == 0) & (np.diff(labels[order]) == 0)]
    labels[order[repeated & (labels[order] != UNASSIGNED)]] = UNASSIGNED
    return RefinementInput(np.asarray(run.times, float)[nodes], poses[nodes], odometry, floor_covariances(covariances),
                           pose_index, data.measurements[:, 1:3].copy(), labels, measurement_noise(),
                           {int(i): np.asarray(m, float) for i, m in run.landmarks.items()}, np.arange(k),
                           np.asarray(record.truth, np.int64))


def refined_result(refinement: RunRefinement, run: LandmarkSlamResult) -> LandmarkSlamResult:
    """The refinement of ``run`` as a ``LandmarkSlamResult`` at the run's own times: each pose
    between two scans is the refined pose of the scan before it moved on by the run's own motion
    since (the filters' poses between scans are their predictions), the refined map, each
    detection's refined label in ``associations``; ``filter`` stays the run's, ``seconds`` adds
    the refinement's."""
    times, poses = np.asarray(run.times, float), np.asarray(run.poses, float)
    require_fields(refinement, ("input", "result"), "refinement", "a RunRefinement")
    require_fields(run, ("times", "poses", "landmarks", "associations"), "run", "a LandmarkSlamResult")
    nodes = np.minimum(np.searchsorted(times, refinement.input.times), len(times) - 1)
    if run.associations is None or len(run.associations) != len(refinement.input.labels) or \
            np.any(times[nodes] != refinement.input.times) or np.any(poses[nodes] != refinement.input.poses):
        raise ValueError("refinement: was not made from run (its scan poses or detections are not the run's)")
    node = np.searchsorted(nodes, np.arange(len(times)), side="right") - 1
    filled = compose(refinement.result.poses[node], between(poses[nodes[node]], poses))
    record = Associations(refinement.input.times[refinement.input.pose_index], refinement.input.truth,
                          refinement.result.labels.astype(np.int64))
    return LandmarkSlamResult(run.method, times, filled, dict(refinement.result.landmarks), run.filter,
                              run.seconds + refinement.result.seconds, record)


class VictoriaParkRun(LandmarkDataset):
    """The original Victoria Park run as a landmark run sees it (``landmark_dataset.LandmarkDataset``):
    unknown correspondences always (the detections have no identities), the car's model and the
    sensors' noise of this module, scored against the GPS (``eval.position_error``)."""

    LABEL = "Victoria Park (ACFR run)"
    DATA = VictoriaParkAcfr

    @classmethod
    def check(cls, options, path) -> None:
        """As ``LandmarkDataset.check``; and no options of the multiple-hypothesis EKF, the EKF's
        ``EKF_ASSOCIATIONS`` only."""
        super().check(options, path)
        refuse_hypotheses(options)
        if options.association not in (None, *EKF_ASSOCIATIONS):
            raise ValueError(f"association on the original Victoria Park run: {' or '.join(EKF_ASSOCIATIONS)} "
                             "(the EKF's)")

    @classmethod
    def load(cls, path, options) -> "VictoriaParkRun":
        """The run's folder at ``path`` (``victoria_park_acfr.load``)."""
        return cls(victoria_park_acfr.load(path), path)

    def run(self, options, progress: Optional[bool] = None) -> LandmarkSlamResult:
        """``run_fastslam`` or ``run_ekf`` over the run."""
        if options.method == "fastslam":
            return self.run_filter("fastslam", options=options.fastslam, progress=progress)
        return self.run_filter("ekf", association=self.association(options), progress=progress)

    def run_filter(self, method: str, *, known: Optional[bool] = None, motion_noise=None, measurement_noise=None,
                   association: str = "jcbb", hypotheses: Optional[MultiHypothesisOptions] = None,
                   options: Optional[FastSlamOptions] = None, progress: Optional[bool] = None,
                   **fields) -> LandmarkSlamResult:
        """One filter over the run (``known`` None or False: the detections have no identities; the
        noise is the sensors', ``motion_noise`` and ``measurement_noise`` are refused)."""
        if known:
            raise ValueError("known: the original Victoria Park run's detections have no identities (known=False)")
        for name, value in (("motion_noise", motion_noise), ("measurement_noise", measurement_noise)):
            if value is not None:
                raise ValueError(f"{name}: the original Victoria Park run takes its sensors' noise "
                                 "(victoria_park_acfr_run)")
        if method == "mht" or hypotheses is not None:
            raise ValueError("method 'mht' runs on MRCLAM only")
        require_fastslam_options(method, options, fields)
        if method == "fastslam":
            return run_fastslam(self.data, options=options, progress=progress, **fields)
        if association not in EKF_ASSOCIATIONS:
            raise ValueError(f"association must be one of {', '.join(map(repr, EKF_ASSOCIATIONS))}, got "
                             f"{association!r}")
        return run_ekf(self.data, association=association, dead_reckoning=method == "dead-reckoning",
                       progress=progress)

    def title(self, options) -> str:
        """The run, for the picture's title."""
        return self.LABEL

    def caption(self, options) -> str:
        """The filter, for the picture's title."""
        if options.method == "fastslam":
            return (f"FastSLAM {options.fastslam.version}.0, {options.fastslam.num_particles} particles, unknown "
                    "correspondences")
        return f"EKF SLAM, unknown correspondences ({self.association(options)})"

    def _gps_lines(self, result: LandmarkSlamResult, label: str) -> List[str]:
        error = self._gps_error(result)
        if error is None:
            return []
        return [f"{label:<15}RMS {error.rmse:.2f} m as it is, {error.rmse_aligned:.2f} m after SE(2) alignment "
                f"({error.count} fixes)"]

    def _gps_error(self, result: LandmarkSlamResult):
        """The run's position error against the GPS (None without gps.dat)."""
        if self.data.gps is None:
            return None
        return position_error(result.times, result.poses, self.data.gps[:, 0], self.data.gps[:, 1:])

    def summary(self, result: LandmarkSlamResult, options, seconds: float) -> List[str]:
        """The run's inputs, detections and fixes, the filter (with its CPU ``seconds``), the map and
        the error against the GPS."""
        data = self.data
        return [f"dataset:       {self.LABEL} {self.path}: {len(data.inputs)} inputs, {len(data.measurements)} "
                f"detections on {len(data.scan_times)} scans, {0 if data.gps is None else len(data.gps)} GPS fixes",
                f"filter:        {self.caption(options)}; {result.seconds:.2f} s filter time, {seconds:.2f} s CPU",
                f"landmarks:     {len(result.landmarks)} in the map",
                *self._gps_lines(result, "GPS:")]

    def refinement_input(self, run: LandmarkSlamResult, motion_noise=None, measurement_noise=None,
                         command_period: Optional[float] = None) -> RefinementInput:
        """``refinement_input`` of the run (the sensors' noise: none other is taken)."""
        for name, value in (("motion_noise", motion_noise), ("measurement_noise", measurement_noise)):
            if value is not None:
                raise ValueError(f"{name}: the original Victoria Park run takes its sensors' noise")
        return refinement_input(run, self.data)

    def refine(self, result: LandmarkSlamResult, options) -> RefinedRun:
        """GraphSLAM's correspondence test over the run (``refine``, with the options' ``refinement``)
        and its error against the GPS."""
        cpu = time.process_time()
        refinement = self.refine_run(result, **refinement_keywords(options))
        r = refinement.result
        cpu = time.process_time() - cpu
        refined = refined_result(refinement, result)
        line = (f"refinement:    GraphSLAM correspondence test (ch. 11.6) on {len(r.poses)} scan poses: "
                f"{len(r.landmarks)} landmarks, {len(r.merges)} merges, {len(r.splits)} detections moved, "
                f"{int((r.labels < 0).sum())} unassigned, {r.iterations} rounds, {cpu:.2f} s CPU"
                f"{'' if r.converged else ' (stopped at the round limit)'}; the path and picture below are the refined "
                "ones")
        return RefinedRun(refined, r, [line, *self._gps_lines(refined, "GPS refined:")],
                          self.refinement_metrics(refinement, cpu))

    def score(self, result: LandmarkSlamResult, options) -> DatasetScore:
        """The error against the GPS (said in the summary and the refinement's lines), and that of
        the car's model alone (``run_ekf(dead_reckoning=True)``, the baseline) as ``metrics``."""
        error = self._gps_error(result)
        if error is None:
            return DatasetScore(values=dict(gps=None))
        dead = self._gps_error(self.run_filter("dead-reckoning", progress=False))
        return DatasetScore(values=dict(gps=error, dead_reckoning=dead),
                            metrics={"dead_reckoning_rmse_m": float(dead.rmse),
                                     "dead_reckoning_rmse_aligned_m": float(dead.rmse_aligned)})

    def draw(self, ax, result: LandmarkSlamResult, score: DatasetScore, refinement: Optional[RefinedRun] = None,
             filtered: Optional[LandmarkSlamResult] = None, options=None) -> str:
        """The path over the GPS fixes, with the map (and the filter's path beside a refined one)."""
        gps = self.data.gps
        if gps is not None:
            ax.plot(gps[:, 1], gps[:, 2], ".", ms=2, color="tab:blue", label="GPS")
        name = self.caption(options).split(",")[0]
        if refinement is not None:
            ax.plot(filtered.poses[:, 0], filtered.poses[:, 1], "-", lw=0.8, color="0.6", label=name)
            name = "GraphSLAM refinement"
        ax.plot(result.poses[:, 0], result.poses[:, 1], "-", lw=1.0, color="tab:orange", label=name)
        if result.landmarks:
            lm = np.array(list(result.landmarks.values()))
            ax.plot(lm[:, 0], lm[:, 1], "+", ms=4, color="k", label=f"{len(lm)} landmarks")
        ax.set_aspect("equal")
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")
        error = score.values.get("gps")
        return "" if error is None else f"; RMS vs GPS {error.rmse_aligned:.2f} m (aligned)"


__all__ = ["BEARING_SIGMA", "DETECTION_INFLATION", "DIAMETER_SIGMA", "FIELD_OF_VIEW", "INPUT_INFLATION", "MAX_RANGE",
           "VictoriaParkRun", "PROVISIONAL_MAX_AGE", "PROVISIONAL_SIGHTINGS", "RANGE_SIGMA", "SPEED_SIGMA", "STEERING_SIGMA", "Schedule",
           "control_noise", "first_seconds", "geometry", "measurement_noise", "provisional_list",
           "refined_result", "refinement_input", "run_ekf", "run_fastslam", "schedule"]
