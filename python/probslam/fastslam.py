"""Running landmark FastSLAM (C++ ``FastSlam``) on the landmark datasets: UTIAS MRCLAM and Victoria
Park, with known or hidden correspondences. Units: metres, radians, seconds.

The best particle's history of data associations is carried along the resamplings (each
particle's list follows its ancestor's), so that a run with hidden correspondences can be scored
measurement by measurement against the dataset's own labels.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from ._args import require_instance
from ._core import FastSlam, velocity_motion, velocity_motion_control_jacobian
from .io.landmark_datasets import Mrclam, VictoriaPark
from .landmark_slam import (MRCLAM_OUTLIER_PROBABILITY, MRCLAM_PERCEPTUAL_FIELD_QUANTILE,  # noqa: F401 (re-used names)
                            mrclam_perceptual_field, polar_measurements, scans)

#: p_new of the hidden-correspondence runs: the density (1 / (m rad)) a measurement of a new
#: landmark is given; a known landmark must explain the measurement better than this.
DEFAULT_P_NEW = 1e-3

#: Victoria Park: the standard deviations of the file's odometry noise are multiplied by this.
#: The file gives every step the same noise (0.01 m, 0.002 m, 0.002 rad), but the odometry's
#: heading error is not white: at the GraphSLAM optimum (chi2 6184.12) the per-step heading
#: residuals have mean +0.54 sigma (7.5 rad accumulated over the run, more than a full turn), so
#: the error over n steps grows like n, not sqrt(n): its RMS is 0.79, 2.5, 4.3 and 7.2 times
#: sigma sqrt(n) for n = 1, 10, 30, 100. An EKF corrects such a drift through its pose-landmark
#: correlations; a particle filter can only select among the poses it sampled, so with the
#: file's noise the particles cannot follow it (one noise-free particle equals dead reckoning,
#: 156 m RMS from the optimum; the best of 100 particles ends 157 m from it). 7 is that ratio at
#: 100 steps: the particles then cover the heading error accumulated between loop closures,
#: which is what hidden associations need (a particle that drifted beyond the association gate
#: starts a duplicate instead of closing the loop). Measured on this file only, the one it is
#: for (studies/fastslam_victoria_park_study.py, 100 particles, seeds 0-3, hidden
#: associations, median path RMSE from the optimum): scale 3: 180 m (version 1) / 181 m
#: (version 2); 5: 45 / 13 m; 7: 10 / 8.8 m; 10: 24 / 24 m. Known associations: 3: 4.8-21 m;
#: 7: 8-14 m.
VICTORIA_PARK_ODOMETRY_NOISE_SCALE = 7.0


@dataclass
class FastSlamRun:
    """times (T,) s and poses (T, 3): the best particle's path at each step; filter the FastSlam;
    landmarks: the best particle's map, id -> (2,) position; associations: per scan, (true ids
    (k,), the best particle's landmark ids (k,)) (hidden correspondences only); seconds: filter time."""

    times: np.ndarray
    poses: np.ndarray
    filter: FastSlam
    landmarks: Dict[int, np.ndarray]
    associations: List[Tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    seconds: float = 0.0


class _Histories:
    """Per-particle association histories, carried along resamplings: each scan's (ancestors,
    ids (M, k), true ids) are kept, and one particle's lineage is traced back at the end, so
    the run pays O(1) Python work per scan, not O(M)."""

    def __init__(self) -> None:
        self.scans: List[Tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def add(self, f: FastSlam, rows: np.ndarray, truth: np.ndarray) -> None:
        # Row j of this scan's ids belongs to particle j after the scan's resampling, whose
        # history before it is that of particle ancestors[j].
        self.scans.append((f.ancestors, rows, truth))

    def of(self, k: int) -> List[Tuple[np.ndarray, np.ndarray]]:
        out = []
        for ancestors, rows, truth in reversed(self.scans):
            out.append((truth, rows[k]))
            if len(ancestors):
                k = int(ancestors[k])
        return out[::-1]


def _landmarks(f: FastSlam) -> Dict[int, np.ndarray]:
    landmarks = f.landmarks()
    return {int(i): m for i, m in zip(landmarks.ids, landmarks.means)}


def _sightings(run: FastSlamRun) -> List[Tuple[int, int]]:
    """(true id, best particle's landmark id) of every sighting it associated (id >= 0)."""
    return [(int(t), int(i)) for truth, ids in run.associations for t, i in zip(truth, ids) if i >= 0]


def majority_labels(run: FastSlamRun) -> Dict[int, int]:
    """For a run with hidden correspondences: each of the best particle's landmarks -> the true id
    most of its sightings carry."""
    require_instance(run, FastSlamRun, "run")
    votes: Dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    for t, i in _sightings(run):
        votes[i][t] += 1
    return {i: c.most_common(1)[0][0] for i, c in votes.items()}


def association_accuracy(run: FastSlamRun) -> float:
    """Fraction of the best particle's measurements that went to their landmark's majority true id."""
    require_instance(run, FastSlamRun, "run")
    label = majority_labels(run)
    pairs = _sightings(run)
    return sum(label[i] == t for t, i in pairs) / len(pairs) if pairs else float("nan")


def run_fastslam_mrclam(data: Mrclam, motion_noise, measurement_noise, *, known: bool = True,
                        num_particles: int = 100, version: int = 1, seed: int = 0, threads: int = 1,
                        p_new: float = DEFAULT_P_NEW, initial_pose=None, command_period: float = 0.01,
                        negative_information: bool = True, **options) -> FastSlamRun:
    """FastSLAM over an MRCLAM robot, as ``landmark_slam.run_ekf_mrclam`` runs the EKF: odometry
    (v, w) between stamps; the control noise ``motion_noise`` (2, 2) is that of one command
    period, applied as white velocity noise (pose noise V (M period / dt) V^T for a step of dt);
    the measurements of one stamp form one scan. ``known``: the barcodes are the correspondences;
    else each particle associates by maximum likelihood (``FastSlam.update_unknown``), with
    ``negative_information`` in the camera's field (``mrclam_perceptual_field``, unless
    ``sensor_range`` / ``sensor_fov`` are given): a landmark there that a scan does not see loses
    existence, and a particle's duplicates, never seen again, are removed.
    ``options`` go to ``FastSlam``. The start pose defaults to the ground truth's."""
    require_instance(data, Mrclam, "data")
    import time

    if not known and negative_information and len(data.measurements):
        field_range, field_fov = mrclam_perceptual_field(data)
        options = {"negative_information": True, "sensor_range": field_range, "sensor_fov": field_fov, **options}

    odo, meas = data.odometry, data.measurements
    if len(odo) == 0:
        raise ValueError("data: the robot has no odometry")
    if initial_pose is None:
        initial_pose = (0.0, 0.0, 0.0)
        if data.groundtruth is not None:
            g = data.groundtruth
            k = int(np.searchsorted(g[:, 0], odo[0, 0]))
            initial_pose = g[min(k, len(g) - 1), 1:4]
    m_rate = np.asarray(motion_noise, float) * command_period
    f = FastSlam(num_particles, np.eye(3) * 0.0, measurement_noise, version=version, seed=seed, threads=threads,
                 initial_pose=initial_pose, p_new=p_new, **options)
    hist = _Histories()
    run = FastSlamRun(np.empty(0), np.empty((0, 3)), f, {})
    times = [odo[0, 0]]  # of the path's poses: the start, then one per prediction
    scan_rows = scans(meas)
    starts = np.array([r.start for r in scan_rows], dtype=np.int64)
    s = int(np.searchsorted(meas[starts, 0], odo[0, 0]))
    zero = np.zeros(3)
    t_now = odo[0, 0]
    t0 = time.perf_counter()

    def move(v: float, w: float, dt: float) -> None:
        # Robot-frame motion and its covariance: V (M period / dt) V^T at the origin.
        delta = velocity_motion(zero, v, w, dt)
        jac = velocity_motion_control_jacobian(zero, v, w, dt)
        f.predict_odometry(delta, jac @ (m_rate / dt) @ jac.T)
        times.append(t_now + dt)

    for k in range(len(odo)):
        v, w = odo[k, 1], odo[k, 2]
        t_next = odo[k + 1, 0] if k + 1 < len(odo) else odo[k, 0]
        while s < len(starts) and meas[starts[s], 0] < t_next:
            rows = meas[scan_rows[s]]
            if rows[0, 0] > t_now:
                move(v, w, rows[0, 0] - t_now)
                t_now = rows[0, 0]
            truth = rows[:, 1].astype(np.int64)
            if known:
                f.update(rows[:, 2:4], truth)
            else:
                ids = f.update_unknown(rows[:, 2:4]).ids
                hist.add(f, ids, truth)
            s += 1
        if t_next > t_now:
            move(v, w, t_next - t_now)
            t_now = t_next
    run.seconds = time.perf_counter() - t0
    run.times, run.poses = np.array(times), f.path()
    run.landmarks = _landmarks(f)
    if not known:
        run.associations = hist.of(f.best_index)
    return run


def run_fastslam_victoria_park(data: VictoriaPark, *, known: bool = False, num_particles: int = 100,
                               version: int = 1, seed: int = 0, threads: int = 1, p_new: float = DEFAULT_P_NEW,
                               measurement_noise=None,
                               odometry_noise_scale: float = VICTORIA_PARK_ODOMETRY_NOISE_SCALE,
                               **options) -> FastSlamRun:
    """FastSLAM over Victoria Park: odometry edges as relative poses with their covariances times
    ``odometry_noise_scale`` ** 2 (see VICTORIA_PARK_ODOMETRY_NOISE_SCALE), landmark points as
    range-bearing (Q_t: their polar covariance at the median range unless given, as
    ``run_ekf_victoria_park``). ``known=False`` hides the associations."""
    require_instance(data, VictoriaPark, "data")
    import time

    if isinstance(odometry_noise_scale, bool) or not isinstance(odometry_noise_scale, (int, float, np.floating)):
        raise TypeError("odometry_noise_scale must be a number")
    if not (np.isfinite(odometry_noise_scale) and odometry_noise_scale > 0):
        raise ValueError("odometry_noise_scale must be finite and > 0")

    if np.any(data.pose_from[1:] != data.pose_to[:-1]):
        raise ValueError("data: the odometry edges do not form one chain")
    chain = np.r_[data.pose_from[0], data.pose_to]
    z, z_cov = polar_measurements(data.xy, data.xy_cov)
    q = np.median(z_cov, axis=0) if measurement_noise is None else np.asarray(measurement_noise, float)
    position = {int(p): k for k, p in enumerate(chain)}
    observed_from = np.array([position[int(p)] for p in data.pose], dtype=np.int64)
    order = np.argsort(observed_from, kind="stable")
    bounds = np.searchsorted(observed_from[order], np.arange(len(chain) + 1))
    f = FastSlam(num_particles, np.eye(3) * 0.0, 0.5 * (q + q.T), version=version, seed=seed, threads=threads,
                 p_new=p_new, **options)
    hist = _Histories()
    t0 = time.perf_counter()
    for k in range(len(chain)):
        if k > 0:
            f.predict_odometry(data.delta[k - 1], odometry_noise_scale ** 2 * data.delta_cov[k - 1])
        rows = order[bounds[k]:bounds[k + 1]]
        if len(rows):
            truth = data.landmark[rows].astype(np.int64)
            if known:
                f.update(z[rows], truth)
            else:
                ids = f.update_unknown(z[rows]).ids
                hist.add(f, ids, truth)
    run = FastSlamRun(np.arange(len(chain), dtype=float), f.path(), f, _landmarks(f),
                      seconds=time.perf_counter() - t0)
    if not known:
        run.associations = hist.of(f.best_index)
    return run


__all__ = ["DEFAULT_P_NEW", "MRCLAM_PERCEPTUAL_FIELD_QUANTILE", "mrclam_perceptual_field", "VICTORIA_PARK_ODOMETRY_NOISE_SCALE", "FastSlamRun", "association_accuracy",
           "majority_labels", "run_fastslam_mrclam", "run_fastslam_victoria_park"]
