"""GraphSLAM's refinement (docs/landmark_refine.md) of a run over the original Victoria Park run
(ACFR): the car's steps composed into one motion edge per scan against a step-by-step numpy
composition, the refinement of a prefix against the GPS, the CLI's --refine graphslam, and the
inputs it refuses. Skipped without ../shared/data."""

import dataclasses

import numpy as np
import pytest

import probslam as ps
from probslam import landmark_refine as lr
from probslam.datasets import (Associations, refine_run, run_landmark_slam, victoria_park_acfr,
                               victoria_park_acfr_run as vpr)
from test_victoria_park_acfr_slam import rms_aligned, run_data, write_prefix  # noqa: F401 (run_data: a fixture)

#: The composed edges and the step-by-step composition differ by rounding only (a few thousand
#: steps of double-precision sums; measured 1.4e-14 on the first 60 s).
COMPOSE_TOLERANCE = 1e-9
#: The prefix the refinement is tested on (s): the car's first loop, 937 scans.
PREFIX_SECONDS = 200.0
#: The prefix of the quick checks (s): 48 scans.
SHORT_SECONDS = 10.0


def step_by_step(deltas, covariances, nodes):
    """Node b in node a's frame composing one step at a time, the covariance propagated with the
    composition's Jacobians, P <- J1 P J1^T + J2 Q J2^T."""
    rel_out, cov_out = [], []
    for a, b in zip(nodes[:-1], nodes[1:]):
        rel, p = np.zeros(3), np.zeros((3, 3))
        for d, q in zip(deltas[a:b], covariances[a:b]):
            c, s = np.cos(rel[2]), np.sin(rel[2])
            j1 = np.array([[1.0, 0.0, -s * d[0] - c * d[1]], [0.0, 1.0, c * d[0] - s * d[1]], [0.0, 0.0, 1.0]])
            j2 = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            rel = np.array([rel[0] + c * d[0] - s * d[1], rel[1] + s * d[0] + c * d[1], rel[2] + d[2]])
            p = j1 @ p @ j1.T + j2 @ q @ j2.T
        rel[2] = np.arctan2(np.sin(rel[2]), np.cos(rel[2]))
        rel_out.append(rel)
        cov_out.append(p)
    return np.array(rel_out), np.array(cov_out)


def test_motion_edges_are_the_steps_composed(run_data):
    """One edge per scan: the Ackermann steps between two scans composed, their covariances
    propagated, as a numpy loop over the steps does it; the run's poses at the scans."""
    data = vpr.first_seconds(run_data, 60.0)
    run = run_landmark_slam(data, "ekf", progress=False)
    start = vpr.refinement_input(run, data)
    steps = vpr.schedule(data)
    nodes = np.unique(np.r_[0, steps.scan_after + 1])
    assert len(start.poses) == len(nodes) == len(np.unique(data.scan_times)) + (data.scan_times[0] > data.inputs[0, 0])
    rel, cov = step_by_step(steps.deltas, steps.covariances, nodes)
    np.testing.assert_allclose(start.odometry, rel, atol=COMPOSE_TOLERANCE)
    np.testing.assert_allclose(start.odometry_covariances, lr.floor_covariances(cov),
                               atol=COMPOSE_TOLERANCE * np.abs(cov).max())
    np.testing.assert_array_equal(start.poses, run.poses[nodes])
    np.testing.assert_array_equal(start.times, run.times[nodes])
    # Every detection on its scan's pose, with the run's landmark.
    np.testing.assert_array_equal(start.times[start.pose_index], run.times[steps.scan_after + 1][
        np.repeat(np.arange(len(data.scan_times)), np.diff(data.scan_starts))])
    np.testing.assert_array_equal(start.labels, np.where(run.associations.ids >= 0, run.associations.ids, -1))
    np.testing.assert_array_equal(start.measurements, data.measurements[:, 1:3])


def test_composition_of_an_empty_segment_is_no_motion():
    rng = np.random.default_rng(5)
    deltas = rng.normal(0.0, 0.2, (6, 3))
    a = rng.normal(size=(6, 3, 3)) * 0.1
    covariances = a @ a.transpose(0, 2, 1)
    nodes = np.array([0, 2, 2, 5, 6])
    rel, cov = lr.compose_increments(deltas, covariances, nodes)
    ref, ref_cov = step_by_step(deltas, covariances, nodes)
    np.testing.assert_allclose(rel, ref, atol=COMPOSE_TOLERANCE)
    np.testing.assert_allclose(cov, ref_cov, atol=COMPOSE_TOLERANCE)
    assert np.all(rel[1] == 0) and np.all(cov[1] == 0)


@pytest.mark.slow  # EKF and FastSLAM 2.0 over 200 s and their refinements: ~20 s of CPU
def test_refinement_of_a_prefix_is_no_worse_against_gps(run_data):
    data = vpr.first_seconds(run_data, PREFIX_SECONDS)
    for run in (run_landmark_slam(data, "ekf", progress=False),
                run_landmark_slam(data, "fastslam", version=2, seed=0, progress=False)):
        refinement = refine_run(run, data)
        refined = vpr.refined_result(refinement, run)
        assert refinement.result.converged
        np.testing.assert_array_equal(refined.times, run.times)
        assert rms_aligned(data, refined) <= rms_aligned(data, run), run.method
        # The refined path passes through the refined scan poses.
        np.testing.assert_allclose(refined.poses[np.searchsorted(run.times, refinement.input.times)],
                                   refinement.result.poses, atol=1e-9)
        assert len(refined.landmarks) == len(refinement.result.landmarks) > 20


def test_refinement_refuses_what_it_cannot_take(run_data):
    data = vpr.first_seconds(run_data, SHORT_SECONDS)
    run = run_landmark_slam(data, "ekf", progress=False)
    with pytest.raises(TypeError, match="^run"):
        vpr.refinement_input(run.poses, data)
    with pytest.raises(TypeError, match="^data"):
        refine_run(run, "inputs.dat")
    with pytest.raises(ValueError, match="^run: holds"):
        refine_run(run, vpr.first_seconds(run_data, 2 * SHORT_SECONDS))
    with pytest.raises(ValueError, match="^run: a dead-reckoning run"):
        refine_run(run_landmark_slam(data, "dead-reckoning", progress=False), data)
    record = run.associations
    dropped = dataclasses.replace(run, associations=Associations(record.times[1:], record.truth[1:], record.ids[1:]))
    with pytest.raises(ValueError, match="^run: its associations"):
        refine_run(dropped, data)
    refinement = refine_run(run, data, max_iterations=0)
    with pytest.raises(ValueError, match="^refinement"):
        vpr.refined_result(refinement, run_landmark_slam(vpr.first_seconds(run_data, 2 * SHORT_SECONDS), "ekf",
                                                         progress=False))
    with pytest.raises(ValueError, match="^max_iterations"):
        refine_run(run, data, max_iterations=-1)


def test_cli_refines_the_run_and_prints_the_gps_error_before_and_after(run_data, tmp_path, capsys):
    """ekf-slam / fastslam DIR --refine graphslam on the run's first 60 s written as the
    dataset's files: both RMS against GPS printed, the refined trajectory written (the refined
    path, not the filter's) and drawn."""
    from probslam import cli

    folder = write_prefix(run_data, tmp_path / "vp", 60.0)
    data = victoria_park_acfr.load(folder)
    for command in (["ekf-slam"], ["fastslam", "--particles", "10", "--variant", "2"]):
        out = tmp_path / command[0]
        assert cli.main(command + [str(folder), "--refine", "graphslam", "-o", str(out), "--no-progress"]) == 0
        printed = capsys.readouterr().out
        before = [line for line in printed.splitlines() if line.startswith("GPS:")]
        after = [line for line in printed.splitlines() if line.startswith("GPS refined:")]
        assert len(before) == len(after) == 1 and "refinement:" in printed, printed
        rms_after = float(after[0].split("m after SE(2)")[0].split(",")[-1])
        assert rms_after <= float(before[0].split("m after SE(2)")[0].split(",")[-1])
        assert (tmp_path / f"{command[0]}.png").exists()
        written = ps.io.read_trajectory(str(tmp_path / f"{command[0]}_trajectory.tum"))
        estimate = ps.eval.position_error(written.timestamps, written.poses, data.gps[:, 0], data.gps[:, 1:])
        assert estimate.rmse_aligned == pytest.approx(rms_after, abs=0.01)
