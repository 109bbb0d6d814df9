"""probslam.eval.ate / rpe (issue 36): against evo (the tool SLAM is scored with; a test-only
dependency, these tests skip without it) on the same TUM files, written by our writer, and
against brute-force numpy computations that share no code with eval."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

import probslam as ps
from probslam import eval as ev
from probslam import io

#: evo and probslam compute the same numbers in a different order (evo in 3-D homogeneous
#: matrices, probslam in 2-D): the statistics agree to rounding, far below this.
EVO_TOLERANCE = 1e-9

#: The brute-force alignment searches rotations on a grid of 2 pi / 20000 rad and refines with
#: golden-section steps; the RMSE at the minimum is flat to second order, so 1e-9 m is met.
BRUTE_FORCE_TOLERANCE = 1e-9


def loop(n=400, seed=0, noise=(0.05, 0.05, 0.02)):
    """A reference path (times, poses) and a noisy estimate of it in another frame."""
    rng = np.random.default_rng(seed)
    times = 1000.0 + np.cumsum(rng.uniform(0.05, 0.2, n))
    theta = np.cumsum(rng.normal(0.0, 0.1, n))
    xy = np.cumsum(0.3 * np.column_stack([np.cos(theta), np.sin(theta)]), axis=0)
    ref = np.column_stack([xy, np.angle(np.exp(1j * theta))])
    est = ref + rng.normal(0.0, noise, (n, 3))
    est = moved(est, 0.7, (3.0, -2.0))
    return times, ref, est


def moved(poses, angle, shift):
    """Poses under the rigid motion (rotation by angle, then shift)."""
    c, s = math.cos(angle), math.sin(angle)
    out = np.array(poses, dtype=float)
    out[:, :2] = out[:, :2] @ np.array([[c, -s], [s, c]]).T + shift
    out[:, 2] = np.angle(np.exp(1j * (out[:, 2] + angle)))
    return out


# --- brute force -----------------------------------------------------------------------------

def brute_force_aligned_rmse(est_xy, ref_xy):
    """min over rotations R and translations t of the RMSE of R est + t - ref: for a fixed R the
    best t is the mean difference, so only the angle is searched (a grid, then golden sections)."""

    def rmse_at(angle):
        c, s = math.cos(angle), math.sin(angle)
        rotated = est_xy @ np.array([[c, -s], [s, c]]).T
        d = rotated - ref_xy
        d -= d.mean(axis=0)
        return math.sqrt(np.mean(np.sum(d * d, axis=1)))

    grid = np.linspace(-math.pi, math.pi, 20001)
    k = int(np.argmin([rmse_at(a) for a in grid]))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    ratio = (math.sqrt(5) - 1) / 2
    for _ in range(80):
        a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        if rmse_at(a) < rmse_at(b):
            hi = b
        else:
            lo = a
    return rmse_at(0.5 * (lo + hi))


def test_a_rotated_and_translated_copy_has_ate_zero():
    times, ref, _ = loop()
    copy_ = moved(ref, -2.1, (100.0, 40.0))
    result = ev.ate(times, copy_, times, ref)
    assert result.count == result.matched == len(times)
    assert result.rmse < 1e-12 and result.max < 1e-12
    # The alignment found is the inverse motion.
    assert math.atan2(result.rotation[1, 0], result.rotation[0, 0]) == pytest.approx(2.1, abs=1e-12)
    # Unaligned, each error is the distance the motion moved the point.
    unaligned = ev.ate(times, copy_, times, ref, align="none")
    np.testing.assert_allclose(unaligned.errors, np.hypot(*(copy_[:, :2] - ref[:, :2]).T), rtol=1e-12)


def test_a_known_perturbation_gives_its_rmse():
    """Offsets of a known length in directions that cancel (zero mean, no net rotation): the
    alignment cannot absorb them, so every error is their length."""
    times, ref, _ = loop(n=400)
    k = np.arange(len(times))
    offset = 0.25 * np.column_stack([(-1.0) ** k, np.zeros(len(k))])  # +-0.25 m in x, alternating
    offset[k % 4 >= 2] = offset[k % 4 >= 2][:, ::-1]  # and in y: no direction is favoured
    est = ref.copy()
    est[:, :2] += offset
    unaligned = ev.ate(times, est, times, ref, align="none")
    np.testing.assert_allclose(unaligned.errors, 0.25, rtol=1e-12)
    assert unaligned.rmse == pytest.approx(0.25, rel=1e-12) and unaligned.sse == pytest.approx(400 * 0.0625)
    aligned = ev.ate(times, est, times, ref)
    assert aligned.rmse == pytest.approx(brute_force_aligned_rmse(est[:, :2], ref[:, :2]), abs=BRUTE_FORCE_TOLERANCE)
    assert aligned.rmse <= unaligned.rmse + 1e-12


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_alignment_is_the_best_rigid_motion(seed):
    times, ref, est = loop(n=150, seed=seed, noise=(0.3, 0.2, 0.05))
    result = ev.ate(times, est, times, ref)
    assert result.rmse == pytest.approx(brute_force_aligned_rmse(est[:, :2], ref[:, :2]), abs=BRUTE_FORCE_TOLERANCE)


def test_statistics_are_the_errors_statistics():
    times, ref, est = loop(n=101, seed=7)
    r = ev.ate(times, est, times, ref)
    e = r.errors
    assert (r.count, r.min, r.max, r.median) == (101, e.min(), e.max(), np.sort(e)[50])
    assert r.mean == pytest.approx(e.sum() / 101, rel=1e-12)
    assert r.sse == pytest.approx(sum(x * x for x in e), rel=1e-12)
    assert r.rmse == pytest.approx(math.sqrt(r.sse / 101), rel=1e-12)
    assert r.std == pytest.approx(math.sqrt(sum((x - r.mean) ** 2 for x in e) / 101), rel=1e-12)


def test_rpe_against_a_direct_computation():
    """RPE over consecutive pairs delta frames apart: the translation of
    (ref_i^-1 ref_j)^-1 (est_i^-1 est_j), with homogeneous matrices."""
    times, ref, est = loop(n=60, seed=8)

    def matrix(p):
        c, s = math.cos(p[2]), math.sin(p[2])
        return np.array([[c, -s, p[0]], [s, c, p[1]], [0, 0, 1]])

    for delta in (1, 4):
        r = ev.rpe(times, est, times, ref, delta=delta)
        ids = list(range(0, 60, delta))
        expected = []
        for i, j in zip(ids, ids[1:]):
            q = np.linalg.inv(matrix(ref[i])) @ matrix(ref[j])
            p = np.linalg.inv(matrix(est[i])) @ matrix(est[j])
            expected.append(np.hypot(*(np.linalg.inv(q) @ p)[:2, 2]))
        np.testing.assert_allclose(r.errors, expected, rtol=1e-9, atol=1e-12)
        assert r.pairs.tolist() == [[i, j] for i, j in zip(ids, ids[1:])]
    # Seconds: the next pose once delta seconds have passed.
    r = ev.rpe(times, est, times, ref, delta=2.0, delta_unit="s")
    assert np.all(np.diff(times)[0] > 0) and np.all(times[r.pairs[:, 1]] - times[r.pairs[:, 0]] >= 2.0)
    assert np.all(times[r.pairs[:, 1] - 1] - times[r.pairs[:, 0]] < 2.0)


def test_association_is_by_nearest_time_within_the_limit():
    """As evo: each time of the shorter trajectory (here the reference) takes the nearest time
    of the other, if it is within the limit; a tie goes to the earlier."""
    t_ref = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    t_est = np.array([0.004, 1.02, 2.995, 3.005, 3.5, 10.0])  # 1.02: 20 ms away, beyond the default
    ie, ir = ev.associate(t_est, t_ref)
    assert ie.tolist() == [0, 2] and ir.tolist() == [0, 3]  # 3.0: 2.995 and 3.005 tie, the earlier
    ie, ir = ev.associate(t_est, t_ref, 0.05)
    assert ie.tolist() == [0, 1, 2] and ir.tolist() == [0, 1, 3]
    # Unsorted times (a clock jump) are searched in full, with the same answer.
    order = np.array([5, 2, 0, 4, 1, 3])
    ie2, ir2 = ev.associate(t_est[order], t_ref, 0.05)
    assert order[ie2].tolist() == [0, 1, 2] and ir2.tolist() == [0, 1, 3]
    # Equal lengths: the second trajectory's times are the ones matched, each once.
    ie, ir = ev.associate([0.0, 1.0], [0.001, 0.002])
    assert ie.tolist() == [0, 0] and ir.tolist() == [0, 1]


def _associate_by_brute_force(times_a, times_b, limit):
    """evo's association written plainly: every time of the shorter trajectory against every
    time of the other, the nearest (argmin: of equally near ones, the lowest index) kept when
    within the limit."""
    a, b = np.asarray(times_a, float), np.asarray(times_b, float)
    short, long = (a, b) if len(b) > len(a) else (b, a)
    pairs = [(i, int(np.argmin(np.abs(long - t)))) for i, t in enumerate(short)]
    pairs = [(i, j) for i, j in pairs if abs(long[j] - short[i]) <= limit]
    i_short = np.array([i for i, _ in pairs], np.int64)
    i_long = np.array([j for _, j in pairs], np.int64)
    return (i_short, i_long) if len(b) > len(a) else (i_long, i_short)


@pytest.mark.parametrize("seed", range(6))
def test_association_of_unsorted_times_equals_the_full_search(seed):
    # Issue 48: once one stamp went back, every time was compared with every other (10^6 poses:
    # ~20 min); the sorted search must give the full search's pairs exactly, repeated times and
    # ties (integer and half-integer stamps) included.
    rng = np.random.default_rng(seed)
    n, m = rng.integers(1, 300, 2)
    if seed % 2:
        t_a, t_b = rng.integers(0, 60, n) / 2.0, rng.integers(-4, 64, m) / 2.0
    else:
        t_a, t_b = np.sort(rng.uniform(0, 50, n)), rng.uniform(-1, 51, m)
        t_a[rng.integers(0, n)] -= 3.0  # one stamp goes back
    for limit in (0.01, 0.5, 100.0):
        got = ev.associate(t_a, t_b, limit)
        want = _associate_by_brute_force(t_a, t_b, limit)
        assert got[0].tolist() == want[0].tolist() and got[1].tolist() == want[1].tolist()


def test_bad_arguments_are_named():
    times, ref, est = loop(n=10)
    with pytest.raises(ValueError, match="times_est: no pose within max_time_difference"):
        ev.ate(times + 100.0, est, times, ref)
    with pytest.raises(ValueError, match="align must be one of"):
        ev.ate(times, est, times, ref, align="sim3")
    with pytest.raises(ValueError, match="max_time_difference must be finite and > 0"):
        ev.ate(times, est, times, ref, max_time_difference=0)
    with pytest.raises(ValueError, match="poses_est: expected shape"):
        ev.ate(times, est[:5], times, ref)
    with pytest.raises(ValueError, match="poses_ref: contains NaN"):
        ev.ate(times, est, times, np.full_like(ref, np.nan))
    with pytest.raises(ValueError, match="delta must be an integer number of frames"):
        ev.rpe(times, est, times, ref, delta=1.5)
    with pytest.raises(ValueError, match="delta_unit must be one of"):
        ev.rpe(times, est, times, ref, delta_unit="deg")
    with pytest.raises(ValueError, match="delta: 100 frames gives no pair"):
        ev.rpe(times, est, times, ref, delta=100)
    with pytest.raises(ValueError, match="times_est: empty trajectory"):
        ev.ate([], np.empty((0, 3)), times, ref)


# --- against evo, on files our writer wrote ----------------------------------------------------

def evo_modules():
    pytest.importorskip("evo", reason="evo (a test-only dependency: pip install evo) is not installed")
    from evo.core import metrics, sync
    from evo.tools import file_interface

    return metrics, sync, file_interface


def evo_statistics(ref_path, est_path, rpe=None, align=False):
    """evo's statistics of the files, as evo_ape / evo_rpe compute them (translation part)."""
    metrics, sync, file_interface = evo_modules()
    ref = file_interface.read_tum_trajectory_file(str(ref_path))
    est = file_interface.read_tum_trajectory_file(str(est_path))
    ref, est = sync.associate_trajectories(ref, est, max_diff=ev.MAX_TIME_DIFFERENCE)
    if align:
        est = copy.deepcopy(est)
        est.align(ref, correct_scale=False)
    if rpe is None:
        metric = metrics.APE(metrics.PoseRelation.translation_part)
    else:
        delta, unit = rpe
        metric = metrics.RPE(metrics.PoseRelation.translation_part, delta=delta,
                             delta_unit=metrics.Unit.frames if unit == "frames" else metrics.Unit.meters)
    metric.process_data((ref, est))
    return metric.get_all_statistics(), len(metric.error)


def ours(ref_path, est_path, rpe=None, align=True):
    est, ref = io.read_trajectory(est_path), io.read_trajectory(ref_path)
    if rpe is None:
        return ev.ate(est.timestamps, est.poses, ref.timestamps, ref.poses, align="se2" if align else "none")
    return ev.rpe(est.timestamps, est.poses, ref.timestamps, ref.poses, delta=rpe[0], delta_unit=rpe[1],
                  align="se2" if align else "none")


def assert_same_as_evo(ref_path, est_path):
    cases = [(None, True), (None, False), ((1, "frames"), False), ((10, "frames"), False), ((2.0, "m"), False),
             ((5, "frames"), True)]
    for rpe, align in cases:
        expected, count = evo_statistics(ref_path, est_path, rpe, align)
        result = ours(ref_path, est_path, rpe, align)
        assert result.count == count, (rpe, align)
        for name, value in expected.items():
            assert getattr(result, name) == pytest.approx(value, rel=0, abs=EVO_TOLERANCE), (rpe, align, name)


def test_same_statistics_as_evo_on_a_synthetic_trajectory(tmp_path):
    """A noisy estimate in another frame, sampled at every second reference time with a few ms
    of jitter (so the association is exercised)."""
    times, ref, est = loop(n=400, seed=11)
    rng = np.random.default_rng(12)
    est_times = times[::2] + rng.uniform(-0.008, 0.008, len(times[::2]))
    io.write_trajectory(times, ref, tmp_path / "ref.tum")
    io.write_trajectory(est_times, est[::2], tmp_path / "est.tum")
    assert_same_as_evo(tmp_path / "ref.tum", tmp_path / "est.tum")


@pytest.mark.slow
def test_same_statistics_as_evo_on_mrclam(tmp_path):
    """A real log: EKF SLAM on the bundled MRCLAM excerpt (`probslam ekf-slam`'s trajectory)
    against the robot's Vicon ground truth, both written as TUM (evo pairs each of the 8012 Vicon
    rows' nearest filter time: the association of a real, irregular clock)."""
    from probslam import cli

    evo_modules()
    assert cli.main(["ekf-slam", "--no-plot", "--no-progress", "-o", str(tmp_path / "e")]) == 0
    data = ps.datasets.load_landmark_dataset(ps.data.path("mrclam7_robot1_120s"))
    truth = data.groundtruth
    io.write_trajectory(truth[:, 0], truth[:, 1:4], tmp_path / "vicon.tum")
    assert_same_as_evo(tmp_path / "vicon.tum", tmp_path / "e_trajectory.tum")
    result = ours(tmp_path / "vicon.tum", tmp_path / "e_trajectory.tum")
    assert 100 < result.count and 0 < result.rmse < 1.0  # the filter's path is within a metre


@pytest.mark.slow
def test_same_statistics_as_evo_on_the_intel_raw_loop(tmp_path):
    """A real laser log: `probslam slam` on the bundled raw Intel loop against its odometry (the
    log has no ground truth; what is compared is the computation). The log's clock steps back
    34 times, so evo and we both search the unsorted times in full."""
    from probslam import cli

    evo_modules()
    assert cli.main(["slam", ps.data.path("intel_raw_loop.log.gz"), "--no-plot", "--no-progress",
                     "-o", str(tmp_path / "s")]) == 0
    scans = io.read_carmen_log(ps.data.path("intel_raw_loop.log.gz")).scans
    io.write_trajectory(scans.timestamps, scans.laser_poses, tmp_path / "odometry.tum")
    with pytest.warns(UserWarning, match="timestamps decrease"):
        assert_same_as_evo(tmp_path / "odometry.tum", tmp_path / "s_trajectory.tum")
