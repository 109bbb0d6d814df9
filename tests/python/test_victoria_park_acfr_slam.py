"""Landmark SLAM on the original Victoria Park run (ACFR) against its GPS, as the SLAM lecture
measured FastSLAM ("100 particles, position error < 5 m RMS"): the drivers' time stepping, a
prefix and the whole run's EKF behind the slow marker (the ten seeds of both FastSLAM
variants are benchmarks/sweeps/victoria_park_acfr.toml's table: minutes of CPU, not a CI test).
Skipped without ../shared/data."""

import numpy as np
import pytest

import probslam as ps
from ekf_reference import DenseEkfSlam, full_state
from probslam.datasets import run_landmark_slam, victoria_park_acfr, victoria_park_acfr_run

#: The lecture's bound on the position error (RMS against GPS, m).
LECTURE_RMS = 5.0
#: The steps' relative poses composed and the model stepped at the inputs' times differ by
#: rounding only (62,000 steps).
COMPOSE_TOLERANCE = 1e-6
#: How far the cuts at the scans move the Euler path in PREFIX_SECONDS (m): 2 mm measured.
CUT_DISCRETISATION = 0.01
#: The prefix the default run drives (s): the car's first loop through the park.
PREFIX_SECONDS = 300.0
#: The prefix on which EkfSlam (signatures apart) is replayed by the full-state dense reference (s).
REPLAY_SECONDS = 20.0
#: Their states after it: the same filter rounded differently (every product in another order;
#: the reference inverts S where the filter solves by Cholesky) over ~900 steps and ~95 scans:
#: 5e-14 measured.
REPLAY_TOLERANCE = 1e-10


@pytest.fixture(scope="module")
def run_data():
    from conftest import SHARED_DATA
    folder = SHARED_DATA / "landmark_slam" / "victoria_park_acfr"
    if not folder.is_dir():
        pytest.skip(f"{folder} not present")
    return victoria_park_acfr.load(folder)


@pytest.mark.slow  # the dense reference's Python loop: 30-40 s on a loaded 2-core machine
def test_ekf_with_signatures_apart_equals_the_full_state(run_data):
    """EkfSlam keeps the trees' diameters out of its dense state; the dense numpy Table 10.1, with
    the diameter in the state, replayed with the same associations on the run's first seconds
    ends in the same state, and its diameters' cross covariances are zero throughout."""
    data = victoria_park_acfr_run.first_seconds(run_data, REPLAY_SECONDS)
    steps = victoria_park_acfr_run.schedule(data)
    z = np.ascontiguousarray(data.measurements[:, 1:4])
    scans = [z[a:b] for a, b in zip(data.scan_starts[:-1], data.scan_starts[1:])]
    q = victoria_park_acfr_run.measurement_noise(signatures=True)
    start = victoria_park_acfr.start_pose(data)
    ekf = ps.EkfSlam(victoria_park_acfr_run.control_noise(), q, use_signatures=True, initial_pose=start)
    ref = DenseEkfSlam(np.eye(3), q, True, pose=start)

    def scan(s):
        result = ekf.update_unknown(scans[s], association="jcbb")
        applied = result.outcome <= 1  # associated or a new landmark, in measurement order
        ref.update(scans[s][applied], result.ids[applied])

    for s in np.flatnonzero(steps.scan_after < 0):
        scan(s)
    for k in range(len(steps.deltas)):
        ekf.predict_odometry(steps.deltas[k], steps.covariances[k])
        ref.predict_odometry(steps.deltas[k], steps.covariances[k])
        for s in np.flatnonzero(steps.scan_after == k):
            scan(s)
    sig = np.zeros(len(ref.mu), bool)
    sig[5::3] = True
    assert ekf.num_landmarks >= 20 and not ref.sigma[np.ix_(sig, ~sig)].any()
    mean, cov = full_state(ekf)
    np.testing.assert_allclose(mean, ref.mu, atol=REPLAY_TOLERANCE, rtol=0)
    np.testing.assert_allclose(cov, ref.sigma, atol=REPLAY_TOLERANCE, rtol=0)


def rms_aligned(data, run):
    return ps.eval.position_error(run.times, run.poses, data.gps[:, 0], data.gps[:, 1:]).rmse_aligned


def test_schedule_steps_at_the_inputs_and_cuts_at_the_scans(run_data):
    data = victoria_park_acfr_run.first_seconds(run_data, PREFIX_SECONDS)
    steps = victoria_park_acfr_run.schedule(data)
    t_in = data.inputs[:, 0]
    # Every input time and every scan stamp inside the inputs' span ends a step.
    inside = data.scan_times[(data.scan_times > t_in[0]) & (data.scan_times < t_in[-1])]
    assert set(np.round(t_in[1:], 6)) <= set(np.round(steps.ends, 6))
    assert set(np.round(inside, 6)) <= set(np.round(steps.ends, 6))
    # A scan is applied right after the step ending at its stamp (before any step if earlier).
    applied = steps.scan_after >= 0
    np.testing.assert_allclose(steps.ends[steps.scan_after[applied]][data.scan_times[applied] > t_in[0]],
                               data.scan_times[applied][data.scan_times[applied] > t_in[0]])
    assert np.all(data.scan_times[~applied] <= t_in[0])
    # The steps composed are the model stepped from cut to cut with the input that holds there
    # (Euler steps: a cut at a scan moves the path by millimetres against uncut steps, no more).
    pose = victoria_park_acfr.start_pose(data)
    for d in steps.deltas:
        pose = ps.Pose2.from_array(pose).compose(ps.Pose2.from_array(d)).as_array()
    reference = uncut = victoria_park_acfr.start_pose(data)
    cuts = np.r_[t_in[0], steps.ends]
    for a, b in zip(cuts[:-1], cuts[1:]):
        k = np.searchsorted(t_in, a, side="right") - 1
        reference = ps.ackermann_motion(reference, data.inputs[k, 1], data.inputs[k, 2], b - a)
    for k in range(len(t_in) - 1):
        uncut = ps.ackermann_motion(uncut, data.inputs[k, 1], data.inputs[k, 2], t_in[k + 1] - t_in[k])
    assert np.max(np.abs(pose[:2] - reference[:2])) < COMPOSE_TOLERANCE
    assert np.max(np.abs(pose[:2] - uncut[:2])) < CUT_DISCRETISATION


@pytest.mark.slow  # EKF and FastSLAM over 300 s of the run: 80 s under the sanitizers
def test_prefix_beats_dead_reckoning_within_the_lecture_bound(run_data):
    data = victoria_park_acfr_run.first_seconds(run_data, PREFIX_SECONDS)
    dead = rms_aligned(data, run_landmark_slam(data, "dead-reckoning", progress=False))
    ekf = run_landmark_slam(data, "ekf", progress=False)
    fast = run_landmark_slam(data, "fastslam", seed=0, progress=False)
    assert rms_aligned(data, ekf) < min(LECTURE_RMS, dead)
    assert rms_aligned(data, fast) < min(LECTURE_RMS, dead)
    assert len(fast.landmarks) > 20 and len(ekf.landmarks) > 20


def test_run_landmark_slam_refuses_what_the_run_cannot_take(run_data):
    data = victoria_park_acfr_run.first_seconds(run_data, 5.0)
    with pytest.raises(ValueError, match="^known"):
        run_landmark_slam(data, "ekf", known=True)
    with pytest.raises(ValueError, match="^motion_noise"):
        run_landmark_slam(data, "fastslam", motion_noise=np.eye(2))
    with pytest.raises(ValueError, match="mht"):
        run_landmark_slam(data, "mht", known=False)
    with pytest.raises(ValueError, match="^seconds"):
        victoria_park_acfr_run.first_seconds(data, -1.0)
    with pytest.raises(TypeError, match="^data"):
        victoria_park_acfr_run.schedule("inputs.dat")


@pytest.mark.slow
def test_ekf_within_the_lecture_bound(run_data):
    assert rms_aligned(run_data, run_landmark_slam(run_data, "ekf", progress=False)) < LECTURE_RMS


def write_prefix(data, folder, seconds: float):
    """The run's first ``seconds`` written as the dataset's files in ``folder`` (made); returns it."""
    end = data.inputs[0, 0] + seconds
    folder.mkdir()
    np.savetxt(folder / "inputs.dat", data.inputs[data.inputs[:, 0] < end])
    m = data.measurements[data.measurements[:, 0] < end].copy()
    m[:, 2] += np.pi / 2  # the file's detector angle
    np.savetxt(folder / "measurements.dat", m)
    np.savetxt(folder / "gps.dat", data.gps[data.gps[:, 0] < end])
    return folder


def test_cli_runs_the_folder_and_scores_it_against_gps(run_data, tmp_path, capsys):
    """ekf-slam / fastslam DIR on the run's first 60 s written as the dataset's files: the RMS
    against GPS printed, the trajectory written (--refine graphslam: test_victoria_park_acfr_refine.py)."""
    from probslam import cli

    folder = write_prefix(run_data, tmp_path / "vp", 60.0)
    with open(folder / "inputs.dat", "a") as f:
        f.write("1.0 not-a-speed 0.0\n")  # one unreadable row: skipped and counted, by file
    for command in (["ekf-slam"], ["fastslam", "--particles", "10", "--variant", "2"]):
        out = tmp_path / command[0]
        assert cli.main(command + [str(folder), "-o", str(out), "--no-plot", "--no-progress"]) == 0
        printed = capsys.readouterr().out
        assert "GPS:" in printed and "after SE(2) alignment" in printed, printed
        assert "skipped rows:  1 (inputs.dat" in printed, printed
        assert (tmp_path / f"{command[0]}_trajectory.tum").exists()
