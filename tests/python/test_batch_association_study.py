"""The batch smoother and re-placement of studies/mrclam_association_ceiling.py --smoothed
(issue 14's study of what smoothing a whole MRCLAM run can associate), on simulated runs."""

import importlib.util
import pathlib
import sys
import types

import numpy as np
import pytest

import probslam as ps

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def study():
    saved = list(sys.path)  # the study puts benchmarks/ on the path to import a bench module
    try:
        spec = importlib.util.spec_from_file_location("association_ceiling", ROOT / "studies" / "mrclam_association_ceiling.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path[:] = saved
    return module


#: The sightings' noise the smoother is told (m, rad) and its offset prior (rad).
SENSOR_SD, OFFSET_SD = (0.03, 0.005), 0.03


def _simulated_run(rng, steps=60, offsets=None, landmarks=None, noise=(0.0, 0.0)):
    """A robot driving an arc past landmarks (default 4), a scan every 0.3 s seeing them all, each
    scan's bearings turned by its offset (default none), range and bearing noise sd `noise`:
    (data, times, scan_of, true poses, landmarks)."""
    t = np.arange(steps + 1) * 0.1
    odometry = np.column_stack([t, np.full(steps + 1, 0.5), np.full(steps + 1, 0.2)])
    poses = ps.landmark_slam.dead_reckoning(odometry, (0.0, 0.0, 0.0))
    if landmarks is None:
        landmarks = np.array([[1.0, 1.5], [2.0, 2.5], [0.5, 2.5], [3.0, 1.0]])
    rows = []
    for n, k in enumerate(range(0, steps, 3)):  # a scan every 0.3 s, at the odometry stamps
        off = 0.0 if offsets is None else offsets[n]
        for j, lm in enumerate(landmarks):
            d = lm - poses[k, :2]
            rows.append([t[k], j, np.hypot(*d) + rng.normal(0, noise[0]),
                         ps.wrap_angle(np.arctan2(d[1], d[0]) - poses[k, 2] - off + rng.normal(0, noise[1]))])
    m = np.array(rows)
    times = np.unique(m[:, 0])
    scan_of = np.searchsorted(times, m[:, 0])
    return types.SimpleNamespace(odometry=odometry, measurements=m), times, scan_of, poses, landmarks


def test_smoother_jacobian_matches_finite_differences(study):
    rng = np.random.default_rng(0)
    data, times, scan_of, poses, landmarks = _simulated_run(rng)
    smoother = study.Smoother(data, times, scan_of, poses[0], SENSOR_SD, OFFSET_SD)
    at = np.column_stack([ps.eval.interpolate_poses(data.odometry[:, 0], poses, times), np.zeros(len(times))])
    # At the noise-free solution every residual is zero, so the Cauchy weight, held fixed in the
    # analytic Jacobian (iteratively reweighted least squares), adds nothing to the derivative.
    lm = landmarks.copy()
    labels = data.measurements[:, 1].astype(np.int64)
    labelled = np.arange(len(labels))
    r, j = smoother._system(at, lm, labelled, labels)
    x = np.concatenate([at.ravel(), lm.ravel()])
    numeric = np.zeros((len(r), len(x)))
    h = 1e-6
    for k in range(len(x)):
        for sign in (1, -1):
            y = x.copy()
            y[k] += sign * h
            rk, _ = smoother._system(y[:4 * len(at)].reshape(-1, 4), y[4 * len(at):].reshape(-1, 2), labelled, labels)
            numeric[:, k] += sign * rk / (2 * h)
    assert np.abs(r).max() < 1e-9
    assert np.abs(j.toarray() - numeric).max() < 1e-6 * np.abs(numeric).max()


def test_smoother_recovers_path_map_and_offsets_from_noisy_odometry(study):
    rng = np.random.default_rng(1)
    offsets = rng.normal(0, 0.02, 20)  # each scan's common bearing error
    data, times, scan_of, poses, landmarks = _simulated_run(rng, offsets=offsets)
    truth = ps.eval.interpolate_poses(data.odometry[:, 0], poses, times)
    noisy = data.odometry.copy()
    noisy[:, 1:] += rng.normal(0, [0.05, 0.05], (len(noisy), 2))  # odometry off by a drift
    data.odometry = noisy
    smoother = study.Smoother(data, times, scan_of, poses[0], SENSOR_SD, OFFSET_SD)
    start = ps.eval.interpolate_poses(noisy[:, 0], ps.landmark_slam.dead_reckoning(noisy, poses[0]), times)
    labels = data.measurements[:, 1].astype(np.int64)
    states, out_lm = smoother.solve(np.column_stack([start, np.zeros(len(start))]), landmarks + 0.3, labels)
    before = np.abs(start[:, :2] - truth[:, :2]).max()
    # The offsets' mean turns the map about the anchored first pose: 0.02 / sqrt(20) rad.
    assert np.abs(out_lm - landmarks).max() < 0.04 < before
    assert np.abs(states[:, :2] - truth[:, :2]).max() < 0.04
    spacing = lambda p: np.linalg.norm(p[:, None] - p[None], axis=2)  # noqa: E731
    assert np.abs(spacing(out_lm) - spacing(landmarks)).max() < 0.01
    # A scan's bearings turn with heading + offset: that sum is found up to the map's common
    # turn (above) and what the positions' errors (< 0.01 m at 1-3 m) turn a bearing, each alone
    # within the offset prior's reach.
    turn = ps.wrap_angle(states[:, 2] + states[:, 3] - truth[:, 2] - offsets)
    assert np.abs(turn - turn.mean()).max() < 5e-3 and abs(turn.mean()) < 0.02
    assert np.abs(states[:, 3] - offsets).max() < 0.03


@pytest.mark.slow
def test_alternation_recovers_cluster_labels(study):
    """Two pairs of landmarks 0.18 m apart (MRCLAM's clusters); a fifth of the sightings start on
    their pair's other member and the poses from drifted odometry: smoothing and re-placing
    settles on the true labels."""
    rng = np.random.default_rng(4)
    landmarks = np.array([[1.0, 1.5], [1.18, 1.5], [2.0, 2.5], [2.0, 2.68]])
    data, times, scan_of, poses, _ = _simulated_run(rng, offsets=rng.normal(0, 0.02, 20), landmarks=landmarks,
                                                    noise=(0.01, 0.003))
    truth = data.measurements[:, 1].astype(np.int64)
    noisy = data.odometry.copy()
    noisy[:, 1:] += rng.normal(0, [0.05, 0.05], (len(noisy), 2))
    data.odometry = noisy
    start = ps.eval.interpolate_poses(noisy[:, 0], ps.landmark_slam.dead_reckoning(noisy, poses[0]), times)
    labels = truth.copy()
    flip = rng.random(len(labels)) < 0.2
    labels[flip] ^= 1  # 0 <-> 1, 2 <-> 3
    smoother = study.Smoother(data, times, scan_of, poses[0], SENSOR_SD, OFFSET_SD)
    scan_rows = ps.landmark_slam.scans(data.measurements)
    out, rounds = study.alternate(smoother, data.measurements, scan_rows, scan_of, start, labels)
    assert study.majority_correct(labels, truth) < 0.85
    assert (out == truth).all() and rounds < study.ROUNDS


def test_majority_correct_by_hand(study):
    truth = np.array([0, 0, 1, 1, 1, 2])
    labels = np.array([5, 5, 5, 7, 7, 7])  # label 5: two of 0, one of 1; label 7: two of 1, one of 2
    assert study.majority_correct(labels, truth) == pytest.approx(4 / 6)



def test_withheld_sightings_are_placed_but_not_smoothed(study):
    """A landmark seen only by withheld sightings gets no place in the smoothed map, so they
    are placed on the others; withheld sightings whose landmark the rest also see keep it."""
    rng = np.random.default_rng(5)
    data, times, scan_of, poses, landmarks = _simulated_run(rng, noise=(0.005, 0.002))
    truth = data.measurements[:, 1].astype(np.int64)
    start = ps.eval.interpolate_poses(data.odometry[:, 0], poses, times)
    smoother = study.Smoother(data, times, scan_of, poses[0], SENSOR_SD, OFFSET_SD)
    scan_rows = ps.landmark_slam.scans(data.measurements)
    alone = truth == 3  # every sighting of landmark 3
    out, _ = study.alternate(smoother, data.measurements, scan_rows, scan_of, start, truth, withheld=alone)
    assert len(np.unique(out)) == 3 and (out[~alone] == truth[~alone]).all()
    some = (truth == 2) & (scan_of % 2 == 0)  # landmark 2's sightings in every other scan
    out, _ = study.alternate(smoother, data.measurements, scan_rows, scan_of, start, truth, withheld=some)
    assert len(np.unique(out)) == 4 and study.majority_right(out, truth).all()


def test_majority_right_marks_each_sighting(study):
    truth = np.array([0, 0, 1, 1, 1, 2])
    labels = np.array([5, 5, 5, 7, 7, 7])
    assert study.majority_right(labels, truth).tolist() == [True, True, False, True, True, False]
