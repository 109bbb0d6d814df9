"""Running EKF SLAM on the landmark datasets, and the metrics used to judge it."""

from __future__ import annotations

import collections
import dataclasses
import itertools
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from ._core import PoseGraph2D, velocity_motion
from ._core import chi_square_quantile
from .ekf import AssociationResult, EkfSlam, MapManagement, MultiHypothesisEkfSlam
from .io.landmark_datasets import Mrclam, VictoriaPark
from ._args import real_array, require_fields, require_instance

#: Outlier gate on the NIS of known-correspondence updates: the chi-square quantile at this
#: probability (2 dof). MRCLAM holds 0.5-3.6% gross outliers (wrong barcodes, reflections).
MRCLAM_OUTLIER_PROBABILITY = 0.999


@dataclass
class EkfRun:
    """An EKF SLAM run over a dataset: times (T,) s, filtered poses (T, 3), the final filter."""

    times: np.ndarray  # (T,) seconds
    poses: np.ndarray  # (T, 3) filtered poses
    ekf: EkfSlam
    landmarks: Dict[int, np.ndarray]  # id -> (2,) estimate
    rejected: int = 0  # measurements the outlier gate skipped
    associations: list = field(default_factory=list)  # per scan: (true ids, AssociationResult)
    #: known correspondences: (K, 4) rows ``(t, subject, NIS, used)`` per measurement (NIS NaN
    #: at a first sighting; used 0 where the outlier gate rejected it)
    innovations: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))


def align_rigid(estimate: np.ndarray, truth: np.ndarray):
    """Best-fit rotation R (2, 2) and translation t (2,) with R @ estimate + t ~ truth (Kabsch)."""
    estimate = real_array(estimate, "estimate", (None, 2))
    truth = real_array(truth, "truth", (len(estimate), 2))
    if len(estimate) == 0:
        raise ValueError("estimate: no points to align")
    mu_e, mu_t = estimate.mean(0), truth.mean(0)
    u, _, vt = np.linalg.svd((estimate - mu_e).T @ (truth - mu_t))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, d]) @ u.T
    return r, mu_t - r @ mu_e


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root mean square of the Euclidean distances between rows of a and b (N, 2 or 3)."""
    return float(np.sqrt(np.mean(np.sum((np.asarray(a) - np.asarray(b)) ** 2, axis=1))))


def truth_positions(groundtruth: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(T, 2) ground-truth positions at `times` (linear interpolation of (t, x, y, ...) rows, held
    at the ends; `probslam.eval.interpolate_poses` is the whole pose, within the span only)."""
    groundtruth = np.asarray(groundtruth)
    if groundtruth.ndim != 2 or groundtruth.shape[1] < 3 or len(groundtruth) == 0:
        raise ValueError(f"groundtruth: expected (T, 3 or more) rows (t, x, y, ...), got shape {groundtruth.shape}")
    times = real_array(times, "times", (None,))
    return np.column_stack([np.interp(times, groundtruth[:, 0], groundtruth[:, 1]),
                            np.interp(times, groundtruth[:, 0], groundtruth[:, 2])])


#: The share of a robot's sightings inside the perceptual field that negative information uses
#: with hidden correspondences (``mrclam_perceptual_field``). A landmark is penalised for not
#: being seen only where the camera nearly always sees one: 10% of the sightings lie beyond
#: this field's range or bearing limits, where detection is unreliable (MRCLAM's camera sees
#: landmarks up to 7-9 m, but half its sightings are within 3.3 m).
MRCLAM_PERCEPTUAL_FIELD_QUANTILE = 0.9


def mrclam_perceptual_field(data: Mrclam, quantile: float = MRCLAM_PERCEPTUAL_FIELD_QUANTILE) -> Tuple[float, float]:
    """(range m, full field-of-view angle rad) of the camera, from the robot's own sightings:
    the ``quantile`` of their ranges, and twice that of their absolute bearings."""
    require_instance(data, Mrclam, "data")
    if not (isinstance(quantile, (int, float)) and 0.0 < quantile <= 1.0):
        raise ValueError(f"quantile must be in (0, 1], got {quantile!r}")
    m = data.measurements
    if len(m) == 0:
        raise ValueError("data: the robot has no landmark measurements")
    return float(np.quantile(m[:, 2], quantile)), float(2.0 * np.quantile(np.abs(m[:, 3]), quantile))


#: The multiple-hypothesis EKF on MRCLAM (``run_ekf_mrclam(association="mht")``): a landmark in
#: the camera's perceptual field (``mrclam_perceptual_field``) is seen with this probability, so
#: a hypothesis pays -2 ln(1 - P_D) = 1.39 for each such landmark a scan misses; and a new
#: landmark costs this much (NIS units, below the library's 27.6). Chosen over all ten shipped
#: robots (benchmarks/bench_mrclam_association.py; docs/landmark_fastslam.md has the sweep).
MRCLAM_MHT_DETECTION_PROBABILITY = 0.5
MRCLAM_MHT_NEW_LANDMARK_COST = 21.0


def run_ekf_mrclam(data: Mrclam, motion_noise, measurement_noise, known: bool = True,
                   gate: Optional[float] = None, alpha: Optional[float] = None, alpha_new: Optional[float] = None,
                   initial_pose=None, map_management: Optional[MapManagement] = None,
                   gate_distance: float = 1.0, dead_reckoning: bool = False,
                   command_period: float = 0.01, association: str = "jcbb",
                   hypotheses: Optional[dict] = None, before_scan=None) -> EkfRun:
    """EKF SLAM over an MRCLAM robot: odometry (v, w) between stamps, the measurements of one
    time stamp as one scan. ``motion_noise`` (2, 2) is the control noise of one command
    period (MRCLAM's ~10 ms); the stamps are irregular (gaps up to 1 s), so it is applied as a
    white velocity noise, M * command_period / dt for a step of dt, whose pose variance grows
    linearly with time whatever the stamps. ``known``: the barcodes give the correspondences (gated by
    ``gate``, default the chi-square 0.999 quantile); else Table 10.2 (barcodes hidden) with
    ``association``: "jcbb" or "ml" (see ``EkfSlam.update_unknown``), or "mht", a beam of
    filters (``MultiHypothesisEkfSlam``, options from ``hypotheses``, by default with missed
    detections in the camera's perceptual field, MRCLAM_MHT_DETECTION_PROBABILITY, and
    MRCLAM_MHT_NEW_LANDMARK_COST) whose best one is returned, its assignments in
    ``associations`` (clutter as DISCARDED).
    ``dead_reckoning``: predictions only. The start pose defaults to the ground truth's.
    ``before_scan(filter, rows)``, if given, sees the filter (the EkfSlam, or the
    MultiHypothesisEkfSlam) and each scan's measurement rows (k, 4) just before it takes them."""
    require_instance(data, Mrclam, "data")
    odo, meas = data.odometry, data.measurements
    if len(odo) == 0:
        raise ValueError("data: the robot has no odometry")
    if initial_pose is None:
        if data.groundtruth is None:
            initial_pose = (0.0, 0.0, 0.0)
        else:
            g = data.groundtruth
            k = int(np.searchsorted(g[:, 0], odo[0, 0]))
            initial_pose = g[min(k, len(g) - 1), 1:4]
    gate = chi_square_quantile(MRCLAM_OUTLIER_PROBABILITY, 2) if gate is None else gate
    ekf = EkfSlam(motion_noise, measurement_noise, use_signatures=False, initial_pose=initial_pose,
                  map_management=map_management, gate_distance=gate_distance)
    mht = None
    if not known and association == "mht":
        options = dict(new_landmark_cost=MRCLAM_MHT_NEW_LANDMARK_COST,
                       detection_probability=MRCLAM_MHT_DETECTION_PROBABILITY)
        if len(meas):
            options["sensor_range"], options["sensor_fov"] = mrclam_perceptual_field(data)
        else:
            options["detection_probability"] = 0.0
        options.update(hypotheses or {})
        mht = MultiHypothesisEkfSlam(ekf, **options)
        ekf = mht  # predict() goes to every filter
    run = EkfRun(np.empty(0), np.empty((0, 3)), ekf, {})
    times, poses = np.empty(len(odo)), np.empty((len(odo), 3))
    m_rate = np.asarray(motion_noise, float) * command_period
    t_now, rejected, innovations = odo[0, 0], 0, []
    scan_rows = scans(meas)
    starts = np.array([r.start for r in scan_rows], dtype=np.int64)
    s = int(np.searchsorted(meas[starts, 0], odo[0, 0]))  # scans before the first control are skipped
    for k in range(len(odo)):
        v, w = odo[k, 1], odo[k, 2]
        t_next = odo[k + 1, 0] if k + 1 < len(odo) else odo[k, 0]
        while not dead_reckoning and s < len(starts) and meas[starts[s], 0] < t_next:
            rows = meas[scan_rows[s]]
            if rows[0, 0] > t_now:
                ekf.predict(v, w, rows[0, 0] - t_now, m_rate / (rows[0, 0] - t_now))
                t_now = rows[0, 0]
            if before_scan is not None:
                before_scan(ekf, rows)
            if known:
                report = ekf.update(rows[:, 2:4], rows[:, 1].astype(np.int64), gate)
                rejected += int(np.count_nonzero(~report.used))
                innovations.append(np.column_stack([rows[:, :2], report.nis, report.used]))
            elif mht is not None:
                mht.update(rows[:, 2:4])
                run.associations.append((rows[:, 1].astype(np.int64), None))
            else:
                result = ekf.update_unknown(rows[:, 2:4], alpha, alpha_new, association)
                run.associations.append((rows[:, 1].astype(np.int64), result))
            s += 1
        if t_next > t_now:
            ekf.predict(v, w, t_next - t_now, m_rate / (t_next - t_now))
            t_now = t_next
        times[k], poses[k] = t_now, ekf.pose
    if mht is not None:
        ekf = run.ekf = mht.best
        run.associations = _history_results(run.associations, mht.history())
    run.times, run.poses, run.rejected = times, poses, rejected
    if innovations:
        run.innovations = np.vstack(innovations)
    run.landmarks = {int(i): ekf.landmark(i)[:2] for i in ekf.landmarks().ids}
    return run


def _history_results(associations, history):
    """(true ids, AssociationResult) per scan from a multiple-hypothesis filter's final history:
    a landmark's first measurement NEW_LANDMARK, later ones ASSOCIATED, clutter DISCARDED."""
    seen, out = set(), []
    for (truth, _), ids in zip(associations, history):
        outcome = np.full(len(ids), AssociationResult.DISCARDED, np.int8)
        for i, lid in enumerate(ids):
            if lid >= 0:
                outcome[i] = AssociationResult.ASSOCIATED if lid in seen else AssociationResult.NEW_LANDMARK
                seen.add(int(lid))
        out.append((truth, AssociationResult(ids, np.full(len(ids), np.nan), outcome, np.empty(0, np.int64))))
    return out


@dataclass
class MrclamScore:
    """Accuracy of an MRCLAM run against ground truth: path and landmark RMSE (m)."""

    path_rmse: float  # m, raw
    path_rmse_aligned: float  # m, after the best rigid alignment of the path to ground truth
    landmark_rmse: float  # m, against the surveyed positions (same frame as the path)
    landmark_rmse_aligned: float  # m, after the path's alignment


def score_mrclam(run: EkfRun, data: Mrclam, landmark_map: Optional[Dict[int, int]] = None) -> MrclamScore:
    """``run``: an EkfRun or FastSlamRun (times (T,), poses (T, 3), landmarks {id: (2,)});
    ``landmark_map``: filter id -> surveyed subject (identity when correspondences were known)."""
    require_fields(run, ("times", "poses", "landmarks"), "run", "a run (EkfRun or FastSlamRun)")
    require_instance(data, Mrclam, "data")
    truth = truth_positions(data.groundtruth, run.times)
    r, t = align_rigid(run.poses[:, :2], truth)
    aligned = run.poses[:, :2] @ r.T + t
    surveyed = data.landmark_positions
    pairs = [(xy, surveyed[(landmark_map or {}).get(i, i)]) for i, xy in run.landmarks.items()
             if (landmark_map or {}).get(i, i) in surveyed]
    est = np.array([p[0] for p in pairs]).reshape(-1, 2)
    sur = np.array([p[1] for p in pairs]).reshape(-1, 2)
    return MrclamScore(rmse(run.poses[:, :2], truth), rmse(aligned, truth),
                       rmse(est, sur) if len(est) else float("nan"),
                       rmse(est @ r.T + t, sur) if len(est) else float("nan"))


def _applied_sightings(run: EkfRun):
    """(true id, filter landmark id) of every sighting a hidden-correspondence run put in the map."""
    for truth, result in run.associations:
        for t, i, outcome in zip(truth, result.ids, result.outcome):
            if outcome in (AssociationResult.ASSOCIATED, AssociationResult.NEW_LANDMARK):
                yield int(t), int(i)


def majority_labels(run: EkfRun) -> Dict[int, int]:
    """For a run with hidden correspondences: each filter landmark's most frequent true id."""
    require_instance(run, EkfRun, "run")
    votes: Dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    for t, i in _applied_sightings(run):
        votes[i][t] += 1
    return {i: c.most_common(1)[0][0] for i, c in votes.items()}


def primary_landmarks(run: EkfRun) -> Dict[int, int]:
    """For a run with hidden correspondences: true id -> the filter landmark holding most of its
    sightings (duplicates left out), among the landmarks still in the map."""
    require_instance(run, EkfRun, "run")
    votes: Dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    for t, i in _applied_sightings(run):
        if i in run.landmarks:
            votes[t][i] += 1
    return {t: c.most_common(1)[0][0] for t, c in votes.items()}


def association_accuracy(run: EkfRun) -> float:
    """Fraction of the measurements applied to the map that went to their landmark's majority id."""
    require_instance(run, EkfRun, "run")
    label = majority_labels(run)
    pairs = list(_applied_sightings(run))
    return sum(label[i] == t for t, i in pairs) / len(pairs) if pairs else float("nan")


#: A surveyed landmark whose distances to the landmarks sighted in the same scans disagree with
#: the readings by more than this (median over its pairs) has a survey label that is not its
#: barcode's. Honest labels give medians of 0.01-0.17 m on Datasets 1 and 7 (camera noise over
#: two readings); a wrong label gives metres, the landmarks standing 1-10 m apart.
SURVEY_RESIDUAL_LIMIT = 0.5  # m


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


def first_seconds(data: Mrclam, seconds: float) -> Mrclam:
    """A copy holding the odometry, measurements and ground truth of the first ``seconds`` of
    the run (from the first odometry stamp): a short run of a long dataset."""
    seconds = float(seconds)
    if not (np.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds: must be finite and > 0, got {seconds}")
    if len(data.odometry) == 0:
        raise ValueError("data: no odometry")
    end = data.odometry[0, 0] + seconds
    keep = lambda rows: rows if rows is None else rows[rows[:, 0] <= end]
    return dataclasses.replace(data, odometry=keep(data.odometry), measurements=keep(data.measurements),
                               groundtruth=keep(data.groundtruth))


def scans(measurements: np.ndarray):
    """Row slices of the measurements sharing one time stamp (rows sorted by time)."""
    if len(measurements) == 0:
        return []
    starts = np.flatnonzero(np.r_[True, np.diff(measurements[:, 0]) != 0])
    return [slice(a, b) for a, b in zip(starts, np.r_[starts[1:], len(measurements)])]


def same_scan_residuals(data: Mrclam) -> Dict[int, np.ndarray]:
    """A check of the survey against the barcodes that needs no robot pose: for two landmarks
    sighted in one scan, their distance computed from the two range-bearing readings minus their
    surveyed distance. Returns subject -> residuals (m) of the pairs it is part of."""
    require_instance(data, Mrclam, "data")
    surveyed = data.landmark_positions
    out: Dict[int, list] = {s: [] for s in surveyed}
    for rows in scans(data.measurements):
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


@dataclass
class LandmarkScore:
    """A landmark map against the survey: RMSE (m) as estimated and after rigid alignment."""

    rmse: float  # m, map against the survey as estimated (frames may differ)
    rmse_aligned: float  # m, after the best rigid alignment of the map onto the survey
    errors: Dict[int, float]  # surveyed subject -> aligned error, m
    rotation: np.ndarray = field(default_factory=lambda: np.eye(2))  # (2, 2) R of R m + t ~ survey
    translation: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (2,) t, m

    def survey_in_map_frame(self, data: Mrclam) -> Dict[int, np.ndarray]:
        """Every surveyed landmark of ``data`` brought into the map's frame by the inverse of the
        alignment (subject -> (2,) m), to draw the survey over the map it was compared with."""
        require_instance(data, Mrclam, "data")
        return {s: (np.asarray(p) - self.translation) @ self.rotation for s, p in data.landmark_positions.items()}


def score_landmarks(landmarks: Dict[int, np.ndarray], data: Mrclam,
                    landmark_map: Optional[Dict[int, int]] = None) -> LandmarkScore:
    """The map alone against the survey, for data without robot ground truth (MRCLAM Dataset 1):
    the filter starts at (0, 0, 0), so its frame is the start pose's, and the map is rigidly
    aligned onto the surveyed landmarks. ``landmark_map``: filter id -> subject (identity by
    default). Needs at least two landmarks."""
    require_instance(landmarks, dict, "landmarks")
    require_instance(data, Mrclam, "data")
    surveyed = data.landmark_positions
    pairs = [(i, (landmark_map or {}).get(i, i)) for i in landmarks]
    pairs = [(i, s) for i, s in pairs if s in surveyed]
    if len(pairs) < 2:
        raise ValueError(f"landmarks: need at least two surveyed landmarks to align, got {len(pairs)}")
    est = np.array([landmarks[i] for i, _ in pairs])
    sur = np.array([surveyed[s] for _, s in pairs])
    r, t = align_rigid(est, sur)
    errors = np.hypot(*(est @ r.T + t - sur).T)
    return LandmarkScore(rmse(est, sur), float(np.sqrt(np.mean(errors ** 2))),
                         {s: float(e) for (_, s), e in zip(pairs, errors)}, r, t)


def dead_reckoning_map(data: Mrclam, initial_pose=(0.0, 0.0, 0.0)) -> Dict[int, np.ndarray]:
    """Subject -> mean of the points where its sightings land from the dead-reckoned pose: the map
    odometry alone would draw, the baseline for EKF SLAM's map when there is no robot ground truth."""
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


def polar_measurements(xy: np.ndarray, xy_cov: np.ndarray):
    """Robot-frame points (L, 2) with covariances (L, 2, 2) as range-bearing (L, 2) with
    covariances (L, 2, 2), through the Jacobian of (r, phi) = (|p|, atan2(p_y, p_x))."""
    xy = real_array(xy, "xy", (None, 2))
    xy_cov = real_array(xy_cov, "xy_cov", (len(xy), 2, 2))
    r = np.hypot(xy[:, 0], xy[:, 1])
    if np.any(r == 0.0):
        raise ValueError("xy: a point at the origin has no bearing")
    z = np.column_stack([r, np.arctan2(xy[:, 1], xy[:, 0])])
    j = np.stack([np.column_stack([xy[:, 0] / r, xy[:, 1] / r]),
                  np.column_stack([-xy[:, 1] / r ** 2, xy[:, 0] / r ** 2])], axis=1)
    return z, j @ xy_cov @ j.transpose(0, 2, 1)


def _ekf_along_chain(delta: np.ndarray, delta_cov: np.ndarray, observed_from: np.ndarray, z: np.ndarray,
                     z_cov: np.ndarray, landmark: np.ndarray, measurement_noise=None,
                     initial_pose=(0.0, 0.0, 0.0)) -> EkfRun:
    """EKF SLAM with known correspondences along a chain of P poses: ``delta`` (P-1, 3) relative
    poses with covariances (P-1, 3, 3); observation k (robot-frame range-bearing ``z[k]``, polar
    covariance ``z_cov[k]``) of landmark ``landmark[k]`` is made from chain pose
    ``observed_from[k]``. The filter takes one Q_t: the median of ``z_cov`` unless given; the
    chain starts at ``initial_pose``, known exactly."""
    q = np.median(z_cov, axis=0) if measurement_noise is None else np.asarray(measurement_noise, float)
    ekf = EkfSlam(np.eye(3) * 1e-6, 0.5 * (q + q.T), use_signatures=False, initial_pose=initial_pose)
    order = np.argsort(observed_from, kind="stable")
    bounds = np.searchsorted(observed_from[order], np.arange(len(delta) + 2))
    poses = np.empty((len(delta) + 1, 3))
    for k in range(len(delta) + 1):
        if k > 0:
            ekf.predict_odometry(delta[k - 1], delta_cov[k - 1])
        rows = order[bounds[k]:bounds[k + 1]]
        if len(rows):
            ekf.update(z[rows], landmark[rows])
        poses[k] = ekf.pose
    run = EkfRun(np.arange(len(poses), dtype=float), poses, ekf, {})
    run.landmarks = {int(i): ekf.landmark(i)[:2] for i in ekf.landmarks().ids}
    return run


def run_ekf_victoria_park(data: VictoriaPark, measurement_noise=None) -> EkfRun:
    """EKF SLAM with known correspondences over Victoria Park: odometry as relative poses,
    landmark points converted to range-bearing. The file's per-observation covariances are
    constant (0.4 m^2 per axis); their polar form at each range would change Q_t per
    measurement, so Q_t is the polar covariance at the median range unless given."""
    require_instance(data, VictoriaPark, "data")
    chain = np.r_[data.pose_from[0], data.pose_to]
    if np.any(data.pose_from[1:] != data.pose_to[:-1]):
        raise ValueError("data: the odometry edges do not form one chain")
    z, z_cov = polar_measurements(data.xy, data.xy_cov)
    position = {int(p): k for k, p in enumerate(chain)}
    observed_from = np.array([position[int(p)] for p in data.pose], dtype=np.int64)
    return _ekf_along_chain(data.delta, data.delta_cov, observed_from, z, z_cov, data.landmark, measurement_noise)


def run_ekf_on_graph(graph, measurement_noise=None) -> EkfRun:
    """EKF SLAM over a pose/landmark graph (``probslam.graph.PoseGraph2D``): the poses in the
    order they were added form the chain, each consecutive pair linked by a pose edge (the
    odometry, its covariance the inverse information); the point edges are the landmark
    observations, converted to range-bearing. Other pose edges (loop closures) are ignored.
    The filter starts, certain, at the first pose's current value.
    ``EkfRun.poses`` follows ``graph.pose_ids``; ``landmarks`` maps point ids to positions."""
    require_instance(graph, PoseGraph2D, "graph")
    chain = np.asarray(graph.pose_ids)
    if len(chain) < 2 or graph.num_point_edges == 0:
        raise ValueError("graph: the EKF needs at least two poses and one point edge")
    ends, delta, info = graph.pose_edges()
    edge_of = {(int(a), int(b)): k for k, (a, b) in enumerate(ends)}
    links = [edge_of.get((int(a), int(b)), -1) for a, b in zip(chain[:-1], chain[1:])]
    if min(links) < 0:
        k = links.index(-1)
        raise ValueError(f"graph: no pose edge from pose {chain[k]} to the next pose {chain[k + 1]}; "
                         "the EKF follows a chain of odometry edges in the order the poses were added")
    point_ends, xy, xy_info = graph.point_edges()
    by_id = np.argsort(chain)
    observed_from = by_id[np.searchsorted(chain[by_id], point_ends[:, 0])]
    z, z_cov = polar_measurements(xy, np.linalg.inv(xy_info))
    return _ekf_along_chain(delta[links], np.linalg.inv(info[links]), observed_from, z, z_cov,
                            point_ends[:, 1].astype(np.int64), measurement_noise, graph.poses[0])


def dead_reckoning(odometry: np.ndarray, initial_pose) -> np.ndarray:
    """(M, 3) poses integrating (t, v, w) rows with the velocity motion model."""
    poses = np.empty((len(odometry), 3))
    x = np.asarray(initial_pose, float)
    for k in range(len(odometry)):
        poses[k] = x
        if k + 1 < len(odometry) and odometry[k + 1, 0] > odometry[k, 0]:
            x = velocity_motion(x, odometry[k, 1], odometry[k, 2], odometry[k + 1, 0] - odometry[k, 0])
    return poses
