"""The pipelines behind `probslam map`, `localize` and `eval`, from Python: each run gives what the
library's own functions give when called by hand (map_laser_log, localize, ate / relations_error),
its summary is what the command prints, and options are refused naming the field."""

import numpy as np
import pytest

import probslam as ps
from probslam import cli, data, io, mapping
from probslam import eval as ev
from probslam.localization import default_options, localize
from probslam.pipelines import (EvaluationOptions, LocalizationRun, MapOptions, MapRun, TrajectoryEvaluation,
                                evaluate_trajectory, localize_log, map_log, reference_kind, snapshot_times)


def _printed(capsys, argv):
    """What the command printed, its time line left out (it is measured, not computed)."""
    assert cli.main(argv) in (0, cli.EXIT_NOT_CONVERGED)
    return [line for line in capsys.readouterr().out.splitlines() if not line.startswith("time:")]


def _lines(text):
    return [line for line in text.splitlines() if not line.startswith("time:")]


# --- map -----------------------------------------------------------------------------------------

def test_map_log_is_map_laser_log_and_says_what_the_command_prints(tmp_path, capsys):
    path = data.path("intel_excerpt.log.gz")
    run = map_log(path, MapOptions(resolution=0.1, robot_radius=0.2), progress=False)
    by_hand = mapping.map_laser_log(io.read_carmen_log(path).scans, resolution=0.1, robot_radius=0.2,
                                    progress=False)
    np.testing.assert_array_equal(run.grid.log_odds, by_hand.grid.log_odds)
    assert (run.mapping.beams, run.mapping.cells_updated) == (by_hand.beams, by_hand.cells_updated)
    written = run.write(str(tmp_path / "m"))
    back = io.load_ros_map(written[0])
    assert (back.width, back.height, back.resolution) == (run.grid.width, run.grid.height, run.grid.resolution)
    printed = _printed(capsys, ["map", path, "--resolution", "0.1", "--robot-radius", "0.2", "--no-progress",
                                "--no-plot", "-o", str(tmp_path / "c")])
    assert _lines(run.summary(path, [f"{tmp_path}/c.yaml", f"{tmp_path}/c.pgm"])) == printed


@pytest.mark.parametrize("fields, exc, message", [
    (dict(resolution=0.0), ValueError, "^resolution must be finite and > 0"),
    (dict(max_range=float("inf")), ValueError, "^max_range must be finite and > 0"),
    (dict(robot_radius=-0.1), ValueError, "^robot_radius must be finite and >= 0"),
    (dict(skip_no_return=1), TypeError, "^skip_no_return: expected bool"),
    (dict(inverse_model="bundled", robot_radius=0.2), ValueError, "^robot_radius does not apply with inverse_model"),
    (dict(inverse_model="bundled", skip_no_return=False), ValueError, "^skip_no_return does not apply"),
])
def test_map_options_are_refused_by_field(fields, exc, message):
    with pytest.raises(exc, match=message):
        MapOptions().replace(**fields)


def test_map_run_refuses_what_is_not_its_options_or_a_model(tmp_path):
    with pytest.raises(TypeError, match="^options: expected MapOptions"):
        MapRun.prepare(data.path("intel_excerpt.log.gz"), {"resolution": 0.1})
    (tmp_path / "bad.npz").write_bytes(b"not a model")
    with pytest.raises(ValueError, match="^inverse_model: "):
        MapRun.prepare(data.path("intel_excerpt.log.gz"), MapOptions(inverse_model=str(tmp_path / "bad.npz")))


# --- localize --------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def loop():
    return io.read_carmen_log(data.path("intel_raw_loop.log.gz")), io.load_ros_map(data.path("intel_raw_loop_map.yaml"))


def test_localize_log_is_localize_and_says_what_the_command_prints(loop, tmp_path, capsys):
    log, grid = loop
    options = default_options(log).replace(seed=7, max_particles=5000)
    run = localize_log(log, grid, options, progress=False)
    by_hand = localize(log, grid, options=options, snapshot_times=snapshot_times(log.scans), progress=False)
    np.testing.assert_array_equal(run.result.poses, by_hand.poses)
    np.testing.assert_array_equal(run.result.num_particles, by_hand.num_particles)
    assert run.initial_pose is None and run.converged == (by_hand.convergence_time is not None)
    args = ["localize", data.path("intel_raw_loop.log.gz"), "--map", data.path("intel_raw_loop_map.yaml"), "--global",
            "--seed", "7", "--max-particles", "5000", "--no-progress", "--no-plot", "-o", str(tmp_path / "l")]
    printed = _printed(capsys, args)
    written = run.write(str(tmp_path / "p"))
    assert open(written[0]).read() == open(f"{tmp_path}/l_trajectory.tum").read()
    summary = run.summary(data.path("intel_raw_loop.log.gz"), data.path("intel_raw_loop_map.yaml"),
                          [f"{tmp_path}/l_trajectory.tum"])
    assert _lines(summary) == printed


def test_localize_log_refuses_a_bad_start_map_or_options(loop):
    log, grid = loop
    with pytest.raises(ValueError, match="^initial_pose: contains NaN"):
        localize_log(log, grid, initial_pose=(0.0, float("nan"), 0.0))
    with pytest.raises(ValueError, match=r"^initial_pose: expected shape \(3\)"):
        localize_log(log, grid, initial_pose=(0.0, 0.0))
    tiny = ps.OccupancyGrid2D(1e-4, 10, 10)
    with pytest.raises(ValueError, match="^map: 0.001 x 0.001 m .* smaller than the log's median laser reading"):
        localize_log(log, tiny)
    with pytest.raises(TypeError, match="^options: expected a MonteCarloLocalizationOptions"):
        localize_log(log, grid, {"seed": 1})
    with pytest.raises(ValueError, match="^min_particles must lie in"):
        default_options(log).replace(min_particles=0)


# --- eval ------------------------------------------------------------------------------------------

def _pair(tmp_path, n=120, seed=1):
    rng = np.random.default_rng(seed)
    times = 10.0 + np.cumsum(rng.uniform(0.05, 0.2, n))
    theta = np.cumsum(rng.normal(0.0, 0.1, n))
    ref = np.column_stack([np.cumsum(0.3 * np.cos(theta)), np.cumsum(0.3 * np.sin(theta)), ps.wrap_angle(theta)])
    est = ref + rng.normal(0.0, [0.05, 0.05, 0.02], (n, 3))
    io.write_trajectory(times, ref, tmp_path / "ref.tum")
    io.write_trajectory(times, est, tmp_path / "est.tum")
    return str(tmp_path / "est.tum"), str(tmp_path / "ref.tum"), times, ref


def test_evaluate_trajectory_is_ate_and_rpe_and_says_what_the_command_prints(tmp_path, capsys):
    est, ref, _, _ = _pair(tmp_path)
    e, r = io.read_trajectory(est), io.read_trajectory(ref)
    run = evaluate_trajectory(est, ref)
    assert run.kind == "trajectory" and run.result.rmse == ev.ate(e.timestamps, e.poses, r.timestamps, r.poses).rmse
    text = "\n".join([run.estimate_summary(), run.reference_summary(), run.summary()])
    assert cli.main(["eval", est, ref]) == 0
    assert capsys.readouterr().out == text
    run = evaluate_trajectory(est, ref, EvaluationOptions(rpe=True, delta=2.0, delta_unit="m"))
    expected = ev.rpe(e.timestamps, e.poses, r.timestamps, r.poses, delta=2.0, delta_unit="m")
    np.testing.assert_array_equal(run.result.errors, expected.errors)
    assert run.align == "none" and "2 (m)" in run.summary()


def test_relations_are_moved_onto_the_estimates_clock(tmp_path):
    est, _, times, ref = _pair(tmp_path)
    pairs = [(i, i + 4) for i in range(0, 100, 5)]
    delta = ev.relative_poses(ref[[i for i, _ in pairs]], ref[[j for _, j in pairs]])
    rows = [f"{times[i] + 70.1797:.6f} {times[j] + 70.1797:.6f} {d[0]:.9f} {d[1]:.9f} 0 0 0 {d[2]:.9f}"
            for (i, j), d in zip(pairs, delta)]
    (tmp_path / "x.relations").write_text("\n".join(rows) + "\n")
    run = evaluate_trajectory(est, tmp_path / "x.relations")
    e, read = io.read_trajectory(est), ev.read_relations(tmp_path / "x.relations")
    # Each relation names two of the estimate's scans: scored at exactly their times.
    first, second = [i for i, _ in pairs], [j for _, j in pairs]
    expected = ev.relations_error(e.timestamps, e.poses, ev.Relations(e.timestamps[first], e.timestamps[second],
                                                                      read.delta))
    assert run.kind == "relations" and "times moved 70.179700 s earlier" in run.reference_summary()
    # The file writes times to the microsecond: the moved times lie up to 5e-7 s off the scans', and
    # the estimate is interpolated there (a 0.3 m step in ~0.1 s moves ~2e-6 m).
    assert run.result.trans_mean == pytest.approx(expected.trans_mean, abs=1e-5)
    assert len(run.result.used) == len(pairs) and run.notes == []


def test_the_reference_kind_is_told_by_name_format_and_rows(tmp_path):
    _, ref, times, poses = _pair(tmp_path)
    (tmp_path / "gps.dat").write_text("".join(f"{t:.3f} {x:.3f} {y:.3f}\n" for t, (x, y) in zip(times, poses[:, :2])))
    assert reference_kind(ref) == "trajectory" and reference_kind(tmp_path / "gps.dat") == "positions"
    assert reference_kind("a.relations") == "relations" and reference_kind("intel.clf.bz2") == "carmen"
    assert reference_kind("x.txt", "relations") == "relations" and reference_kind("x.relations", "tum") == "trajectory"


@pytest.mark.parametrize("fields, exc, message", [
    (dict(delta=0.0, rpe=True), ValueError, "^delta must be finite and > 0"),
    (dict(delta=2.0), ValueError, "^delta applies with rpe only"),
    (dict(delta_unit="m"), ValueError, "^delta_unit applies with rpe only"),
    (dict(rpe=True, delta=1.5), ValueError, "^delta must be a whole number of frames"),
    (dict(rpe=True, delta_unit="parsec"), ValueError, "^delta_unit must be one of frames, m, s"),
    (dict(reference_format="csv"), ValueError, "^reference_format must be one of auto, tum"),
    (dict(max_time_difference=float("nan")), ValueError, "^max_time_difference must be finite and > 0"),
    (dict(rpe="yes"), TypeError, "^rpe: expected bool"),
])
def test_evaluation_options_are_refused_by_field(fields, exc, message):
    with pytest.raises(exc, match=message):
        EvaluationOptions().replace(**fields)


def test_options_that_do_not_apply_to_the_reference_are_refused_by_field(tmp_path):
    est, ref, _, _ = _pair(tmp_path)
    (tmp_path / "x.relations").write_text("10.5 10.9 0 0 0 0 0 0\n")
    for options, reference, message in ((EvaluationOptions(rpe=True), "x.relations", "^rpe applies to a reference "
                                         "trajectory, not to relations"),
                                        (EvaluationOptions(max_time_difference=0.1), "x.relations",
                                         "^max_time_difference applies to a reference trajectory"),
                                        (EvaluationOptions(raw_log="a.clf"), "ref.tum", "^raw_log applies to a "
                                         "relations file")):
        run = TrajectoryEvaluation.read_estimate(est, options)
        with pytest.raises(ValueError, match=message):
            run.read_reference(tmp_path / reference)


def test_the_evaluation_draws_the_aligned_estimate_on_the_reference(tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot", reason="the picture needs matplotlib")
    est, ref, _, _ = _pair(tmp_path)
    run = evaluate_trajectory(est, ref)
    poses = io.read_trajectory(ref).poses
    fig = run.draw(plt)
    (reference, estimate), errors = fig.axes[0].get_lines(), fig.axes[1].get_lines()[0]
    np.testing.assert_allclose(np.column_stack(reference.get_data()), poses[:, :2])
    moved = run.estimate.poses[:, :2] @ run.result.rotation.T + run.result.translation
    np.testing.assert_allclose(np.column_stack(estimate.get_data()), moved)
    np.testing.assert_array_equal(errors.get_ydata(), run.result.errors)
    plt.close(fig)
