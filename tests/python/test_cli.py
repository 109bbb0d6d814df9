"""The probslam command line, end to end."""

import contextlib
import os
import time

import numpy as np
import pytest

import probslam as ps
from probslam import cli, io
from probslam.pipelines.inputs import LANDMARK_DATASET
from probslam.data import path as data_path


def test_map_bundled_log(tmp_path, capsys):
    assert cli.main(["map", "-o", str(tmp_path / "m"), "--no-progress"]) == 0
    out = capsys.readouterr().out
    summary = ps.map_laser_log(io.read_carmen_log(data_path(cli.BUNDLED_LOG)).scans, progress=False)
    expected = summary.grid
    assert f"scans:         {summary.scans}" in out and f"beams:         {summary.beams}" in out
    assert f"cells updated: {summary.cells_updated}" in out
    saved = io.load_ros_map(tmp_path / "m.yaml")
    assert saved.same_geometry(expected)
    classes = lambda g: np.digitize(g.probability(), [0.196, 0.65])
    np.testing.assert_array_equal(classes(saved), classes(expected))
    assert 0 < np.count_nonzero(classes(saved) == 2) < np.count_nonzero(classes(saved) == 0)
    assert (tmp_path / "m.png").read_bytes()[:4] == b"\x89PNG"


def test_map_bad_log_reports_line(tmp_path, capsys):
    bad = tmp_path / "bad.log"
    bad.write_text("ODOM 0 0 0 0 0 0\nFLASER 3 1 2\n")
    assert cli.main(["map", str(bad), "-o", str(tmp_path / "m"), "--no-progress"]) == 2
    assert "bad.log:2:" in capsys.readouterr().err


def test_map_log_with_a_bad_line_reports_the_skip(tmp_path, capsys):
    log = tmp_path / "log.log"
    log.write_text("FLASER 3 1 2 1 0 0 0 0 0 0\nFLASER 3 1 2\nFLASER 3 1 2 1 0.1 0 0 0.1 0 0\n")
    with pytest.warns(UserWarning, match=r"log\.log: skipped 1 malformed line \(line 2: FLASER has 4 fields"):
        assert cli.main(["map", str(log), "-o", str(tmp_path / "m"), "--no-progress"]) == 0
    assert "scans:         2 (1 malformed log lines skipped)" in capsys.readouterr().out


def test_map_matches_direct_api(tmp_path):
    log = io.read_carmen_log(data_path(cli.BUNDLED_LOG))
    summary = ps.map_laser_log(log.scans, resolution=0.1, progress=False)
    grid = summary.grid
    direct = ps.OccupancyGrid2D(0.1, grid.width, grid.height, origin=grid.origin)
    scans = log.scans
    ranges = np.where(scans.ranges >= 81.83, np.nan, scans.ranges)  # the log's no-return value
    direct.insert_scans(scans.laser_poses, ranges, scans.beam_angles(), 30.0)
    np.testing.assert_array_equal(grid.log_odds, direct.log_odds)
    assert summary.scans == 180


@pytest.mark.slow
def test_optimize_writes_the_optimised_graph(tmp_path, capsys):
    g = ps.PoseGraph2D()
    truth = np.array([[0, 0, 0], [1, 0, np.pi / 2], [1, 1, np.pi], [0, 1, -np.pi / 2]])
    for i, p in enumerate(truth):
        g.add_pose(i, p + np.array([0.2, -0.1, 0.1]) * (i > 0))
    for i in range(4):
        a, b = truth[i], truth[(i + 1) % 4]
        c, s = np.cos(a[2]), np.sin(a[2])
        z = np.r_[np.array([[c, s], [-s, c]]) @ (b[:2] - a[:2]), ps.wrap_angle(b[2] - a[2])]
        g.add_pose_edge(i, (i + 1) % 4, z, np.eye(3))
    ps.write_g2o(g, str(tmp_path / "square.g2o"))
    assert cli.main(["optimize", str(tmp_path / "square.g2o"), "-o", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "4 poses" in out and "iteration   1" in out and "chi2 0.000000 after" in out
    result = ps.read_pose_graph(str(tmp_path / "out.g2o"))
    np.testing.assert_allclose(result.poses, truth, atol=1e-9)
    assert (tmp_path / "out.png").read_bytes()[:4] == b"\x89PNG"


def test_optimize_with_an_initialisation(tmp_path, capsys):
    g = ps.PoseGraph2D()
    for i in range(3):
        g.add_pose(i, [0.0, 0.0, 0.0])
        if i:
            g.add_pose_edge(i - 1, i, [1.0, 0.0, 0.5], np.eye(3))
    ps.write_g2o(g, str(tmp_path / "chain.g2o"))
    args = ["optimize", str(tmp_path / "chain.g2o"), "--no-plot", "-o", str(tmp_path / "o")]
    assert cli.main(args + ["--init", "odometry"]) == 0
    out = capsys.readouterr().out
    assert "init:       odometry" in out and "chi2 0.000000 after" in out
    assert cli.main(args + ["--init", "incremental", "--poses-per-step", "0"]) == 2
    assert "--poses-per-step 0: must lie in [1, 2^31)" in capsys.readouterr().err
    for option, value in (("--max-iterations", 2 ** 64), ("--max-iterations", -1), ("--poses-per-step", 2 ** 40)):
        init = ["--init", "incremental"] if option == "--poses-per-step" else []
        assert cli.main(args + init + [option, str(value)]) == 2
        assert f"probslam: error: {option} {value}: must lie in [" in capsys.readouterr().err


def test_optimize_says_what_toro_equivalences_merged(tmp_path, capsys):
    loop = tmp_path / "loop.graph"  # 4 poses round a unit square, the fifth the first again
    loop.write_text("".join(f"VERTEX2 {i} 0 0 0\n" for i in range(5))
                    + "".join(f"EDGE2 {i} {i + 1} 1 0 1.5707963267948966 1 0 1 1 0 0\n" for i in range(4))
                    + "EQUIV 4 0\n")
    assert cli.main(["optimize", str(loop), "--no-plot", "-o", str(tmp_path / "o"), "--init", "odometry"]) == 0
    out = capsys.readouterr().out
    assert "4 poses" in out and "1 TORO EQUIV records: 1 vertices merged into others, 0 edges" in out
    assert "chi2 0.000000 after" in out


def test_optimize_bad_file_reports_line(tmp_path, capsys):
    bad = tmp_path / "bad.g2o"
    bad.write_text("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0\n")
    assert cli.main(["optimize", str(bad), "--no-plot", "-o", str(tmp_path / "o")]) == 2
    assert "bad.g2o:2:" in capsys.readouterr().err


@pytest.mark.slow
def test_ekf_slam_unknown_correspondences(tmp_path, capsys, shared_data):
    import pytest

    pytest.importorskip("matplotlib")
    folder = shared_data / "landmark_slam/mrclam_dataset7"
    assert cli.main(["ekf-slam", str(folder), "--unknown", "-o", str(tmp_path / "e")]) == 0
    out = capsys.readouterr().out
    assert "unknown (mht) correspondences" in out and "% correct" in out
    assert (tmp_path / "e.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_slam_bundled_raw_log(tmp_path, capsys):
    prefix = tmp_path / "s"
    assert cli.main(["slam", "-o", str(prefix), "--no-progress"]) == 0
    out = capsys.readouterr().out
    log = io.read_carmen_log(data_path(cli.BUNDLED_SLAM_LOG))
    assert f"scans:         {len(log.scans)} (" in out and "closures:" in out and "real-time factor" in out
    traj = io.read_trajectory(tmp_path / "s_trajectory.tum")
    assert traj.format == "tum" and traj.poses.shape == (len(log.scans), 3)
    np.testing.assert_allclose(traj.timestamps, log.scans.timestamps, atol=1e-6)
    # The first scan is the map frame's origin: its raw odometry pose.
    np.testing.assert_allclose(traj.poses[0], log.scans.laser_poses[0], atol=1e-6)
    graph = ps.read_pose_graph(str(tmp_path / "s.g2o"))
    submaps = int(out.split("submaps:")[1].split()[0])
    assert graph.num_vertices == submaps >= 2
    grid = io.load_ros_map(tmp_path / "s.yaml")
    assert grid.resolution == pytest.approx(0.05)
    assert (tmp_path / "s.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_slam_rbpf_on_the_bundled_raw_log(tmp_path, capsys):
    prefix = tmp_path / "r"
    assert cli.main(["slam", data_path(cli.BUNDLED_RAW_LOG), "--method", "rbpf", "--particles", "4", "-o",
                     str(prefix), "--no-progress"]) == 0
    out = capsys.readouterr().out
    log = io.read_carmen_log(data_path(cli.BUNDLED_RAW_LOG))
    assert "grid-based FastSLAM, 4 particles, scan-matching proposal" in out and "distinct tiles" in out
    traj = io.read_trajectory(tmp_path / "r_trajectory.tum")
    assert traj.poses.shape == (len(log.scans), 3)
    np.testing.assert_allclose(traj.poses[0], log.scans.laser_poses[0], atol=1e-6)
    assert not (tmp_path / "r.g2o").exists()  # no graph: a particle filter
    assert io.load_ros_map(tmp_path / "r.yaml").resolution == pytest.approx(0.05)
    # The GraphSLAM trajectory of the same log: the filter's best path stays within a few cm of it
    # over this excerpt (no loop closes in it).
    graph = ps.run_slam(log, progress=False)
    err = np.linalg.norm(traj.poses[:, :2] - graph.poses[:, :2], axis=1)
    assert np.median(err) < 0.1, np.median(err)


def test_slam_rbpf_needs_odometry(tmp_path, capsys):
    log = io.read_carmen_log(data_path(cli.BUNDLED_RAW_LOG))
    scans = log.scans
    lines = [f"FLASER {scans.ranges.shape[1]} " + " ".join(f"{r:.3f}" for r in scans.ranges[k]) + " 0 0 0 0 0 0 "
             f"{scans.timestamps[k]:.6f} host {scans.timestamps[k]:.6f}" for k in range(30)]
    still = tmp_path / "still.log"
    still.write_text("\n".join(lines) + "\n")
    assert cli.main(["slam", str(still), "--method", "rbpf", "-o", str(tmp_path / "s"), "--no-progress"]) == 2
    assert "no odometry" in capsys.readouterr().err


def test_slam_bad_log_is_an_error_not_a_traceback(tmp_path, capsys):
    bad = tmp_path / "bad.log"
    bad.write_text("ODOM 0 0 0 0 0 0\n")
    assert cli.main(["slam", str(bad), "-o", str(tmp_path / "s"), "--no-progress"]) == 2
    assert "bad.log" in capsys.readouterr().err
    assert cli.main(["slam", str(tmp_path / "missing.log"), "--no-progress"]) == 2


@pytest.mark.slow
def test_fastslam_mrclam_prints_what_the_driver_computes(tmp_path, capsys, shared_data):
    pytest.importorskip("matplotlib")
    from probslam.datasets import mrclam

    folder = shared_data / "landmark_slam/mrclam_dataset7"
    args = ["fastslam", str(folder), "--unknown", "--seconds", "60", "--particles", "20", "--seed", "3"]
    assert cli.main(args + ["-o", str(tmp_path / "f")]) == 0
    out = capsys.readouterr().out
    # The same run through the driver: the summary's figures are its figures.
    data = io.read_mrclam(folder, robot=1)
    data = mrclam.first_seconds(data, 60.0).with_euclidean_ranges()
    run = mrclam.run_fastslam(data, np.diag([0.15 ** 2, 0.6 ** 2]), np.diag([0.15 ** 2, 0.04 ** 2]), known=False,
                                 num_particles=20, seed=3)
    assert f"landmarks:     {len(run.landmarks)} in the best particle's map" in out
    assert f"associations:  {ps.eval.association_accuracy(run):.1%} correct" in out
    assert "path RMSE:" in out and "unknown correspondences" in out
    trajectory = io.read_trajectory(tmp_path / "f_trajectory.tum")  # TUM with times, as every command
    np.testing.assert_allclose(trajectory.poses, run.poses, atol=1e-6)
    np.testing.assert_allclose(trajectory.timestamps, run.times, atol=1e-6)
    assert (tmp_path / "f.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("extra, name", [(["--particles", "0"], "--particles"), (["--seed", "-1"], "seed"),
                                         (["--threads", "0"], "--threads"), (["--particles", str(2 ** 64)], "--particles"),
                                         (["--threads", str(2 ** 40)], "--threads")])
def test_fastslam_bad_options_are_errors_naming_them(tmp_path, capsys, shared_data, extra, name):
    vp = shared_data / "landmark_slam/victoria_park/victoriaPark.txt"
    assert cli.main(["fastslam", str(vp), "-o", str(tmp_path / "x")] + extra) == 2
    assert name in capsys.readouterr().err
    assert cli.main(["fastslam", str(tmp_path / "missing.txt"), "-o", str(tmp_path / "x")]) == 2


# ------------------------------------------------------------------ bundled data, errors, no matplotlib

import gzip
import os
import subprocess
import sys

from probslam import data


def test_every_bundled_file_is_there():
    for name in data.FILES:
        assert os.path.exists(data.path(name)), name
    with pytest.raises(ValueError, match="no bundled data called 'nope'.*intel_400.g2o"):
        data.path("nope")


def test_optimize_bundled_graph(tmp_path, capsys):
    assert cli.main(["optimize", "--no-plot", "-o", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "intel_400.g2o (bundled" in out and "400 poses, 0 points, 513 pose edges" in out
    result = ps.read_pose_graph(str(tmp_path / "o.g2o"))
    direct = ps.read_pose_graph(data.path("intel_400.g2o"))
    report = ps.optimize(direct)
    np.testing.assert_allclose(result.poses, direct.poses, atol=1e-6)
    assert f"chi2 {report.chi2:.6f} after {report.iterations} iterations" in out
    assert report.chi2 < report.initial_chi2


def test_optimize_bundled_3d_graph(tmp_path, capsys):
    """A 3-D file is told by its records: read into a PoseGraph3D, chordal initialisation by
    default, the same optimiser, a g2o SE3 file and a TUM trajectory written."""
    path = data.path("parking_garage_400.g2o")
    assert cli.main(["optimize", path, "--no-plot", "--no-progress", "-o", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "3-D, 400 poses, 500 edges, 0 priors" in out and "init:       chordal" in out
    direct = ps.graph.read_pose_graph_3d(path)
    ps.initialize_chordal(direct)
    report = ps.optimize(direct)
    assert f"chi2 {report.chi2:.6f} after {report.iterations} iterations" in out
    result = ps.graph.read_pose_graph_3d(tmp_path / "o.g2o")
    np.testing.assert_allclose(result.poses, direct.poses, atol=1e-9)
    rows = np.loadtxt(tmp_path / "o_trajectory.tum")
    np.testing.assert_allclose(rows[:, 0], direct.pose_ids)
    np.testing.assert_allclose(rows[:, 1:], direct.poses, atol=1e-8)


def test_optimize_3d_options(tmp_path, capsys):
    path = data.path("parking_garage_400.g2o")
    base = ["optimize", path, "--no-plot", "--no-progress", "-o", str(tmp_path / "o")]
    assert cli.main(base + ["--init", "file", "--algorithm", "levenberg-marquardt", "--kernel", "huber",
                            "--trajectory-format", "kitti"]) == 0
    out = capsys.readouterr().out
    assert "init:" not in out and "result:     chi2" in out
    assert (tmp_path / "o_trajectory.kitti").is_file() and (tmp_path / "o_trajectory_times.txt").is_file()
    assert cli.main(base + ["--init", "odometry", "--max-iterations", "2"]) in (0, 3)
    assert "init:       odometry" in capsys.readouterr().out
    assert cli.main(base + ["--init", "ekf"]) == 2
    assert "--init ekf applies to 2-D graphs" in capsys.readouterr().err
    assert cli.main(base + ["--trajectory-format", "xyt"]) == 2
    assert "--trajectory-format xyt" in capsys.readouterr().err
    assert cli.main(["optimize", data.path("intel_400.g2o"), "--init", "chordal", "--no-plot", "-o",
                     str(tmp_path / "o")]) == 2
    assert "--init chordal applies to 3-D graphs" in capsys.readouterr().err
    bad = tmp_path / "bad.g2o"
    bad.write_text("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0 2\n")
    assert cli.main(["optimize", str(bad), "--no-plot", "-o", str(tmp_path / "o")]) == 2
    assert "bad.g2o:2: quaternion" in capsys.readouterr().err


def test_ekf_slam_bundled_mrclam(tmp_path, capsys):
    assert cli.main(["ekf-slam", "-o", str(tmp_path / "e")]) == 0
    out = capsys.readouterr().out
    folder = data.path("mrclam7_robot1_120s")
    assert f"UTIAS MRCLAM {folder} robot 1" in out and "path RMSE:" in out
    mr = io.read_mrclam(folder)
    assert mr.groundtruth is not None and 115 < mr.odometry[-1, 0] - mr.odometry[0, 0] <= 120
    assert f"odometry:      {len(mr.odometry)} controls" in out
    path = io.read_trajectory(tmp_path / "e_trajectory.tum")
    assert path.format == "tum" and len(path) > 100


def test_ekf_slam_bundled_victoria_park(tmp_path, capsys):
    assert cli.main(["ekf-slam", data.path("victoria_park_1000.txt"), "-o", str(tmp_path / "v")]) == 0
    out = capsys.readouterr().out
    assert "1000 poses, 613 observations" in out
    path = io.read_trajectory(tmp_path / "v_trajectory.tum")
    assert path.poses.shape == (1000, 3)
    np.testing.assert_array_equal(path.timestamps, np.arange(1000.0))  # Victoria Park: the pose index


def test_fastslam_bundled_mrclam(tmp_path, capsys):
    assert cli.main(["fastslam", "--particles", "20", "-o", str(tmp_path / "f")]) == 0
    out = capsys.readouterr().out
    assert "FastSLAM 1.0, 20 particles" in out and "path RMSE:" in out
    assert len(io.read_trajectory(tmp_path / "f_trajectory.tum")) > 100


@pytest.mark.parametrize("command", ["ekf-slam", "fastslam"])
@pytest.mark.parametrize("option, value", [("--sigma-v", "-0.15"), ("--sigma-w", "0"), ("--sigma-r", "nan"),
                                           ("--sigma-phi", "inf")])
def test_mrclam_noise_options_must_be_positive_sigmas(tmp_path, capsys, command, option, value):
    """A negative sigma squared would pass as a positive one: each is refused by name, before the
    data is read, and nothing is written."""
    assert cli.main([command, option, value, "-o", str(tmp_path / "x")]) == 2
    captured = capsys.readouterr()
    assert captured.err.startswith(f"probslam: error: {option} "), captured.err
    assert "must be a finite standard deviation > 0" in captured.err
    assert "dataset:" not in captured.out and "skipped" not in captured.out
    assert not list(tmp_path.iterdir())


def _bad_inputs(tmp_path):
    """(name, path) of the inputs no command can read."""
    (tmp_path / "empty.txt").write_bytes(b"")
    (tmp_path / "garbage.txt").write_bytes(bytes(range(256)) * 8)
    (tmp_path / "corrupt.log.gz").write_bytes(gzip.compress(b"FLASER 3 1 2 3 0 0 0 0 0 0\n" * 50)[:40])
    (tmp_path / "folder").mkdir()
    return [("missing", tmp_path / "missing.txt"), ("directory", tmp_path / "folder"),
            ("empty", tmp_path / "empty.txt"), ("garbage", tmp_path / "garbage.txt"),
            ("corrupt .gz", tmp_path / "corrupt.log.gz")]


@pytest.mark.parametrize("command", ["map", "slam", "ekf-slam", "fastslam", "optimize"])
def test_bad_inputs_give_one_line_naming_the_file(tmp_path, capsys, command):
    for kind, path in _bad_inputs(tmp_path):
        status = cli.main([command, str(path), "-o", str(tmp_path / "out")]
                          + (["--no-progress"] if command in ("map", "slam") else []))
        err = capsys.readouterr().err
        assert status == 2, (kind, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and str(path) in lines[0] and "expected" in lines[0], (kind, err)
        assert "Traceback" not in err


def _run(args, tmp_path, env_extra=None):
    env = dict(os.environ, MPLBACKEND="Agg", **(env_extra or {}))
    return subprocess.run([sys.executable] + args, cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.slow
def test_subprocess_bad_file_has_no_traceback(tmp_path):
    run = _run(["-m", "probslam", "ekf-slam", str(tmp_path / "missing")], tmp_path)
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert run.stderr.strip() == f"probslam: error: {tmp_path / 'missing'}: no such file; expected " \
                                 f"{LANDMARK_DATASET}"


@pytest.mark.slow
def test_version_and_python_m(tmp_path):
    run = _run(["-m", "probslam", "--version"], tmp_path)
    assert run.returncode == 0 and run.stdout.strip() == f"probslam {ps.__version__}"
    run = _run(["-m", "probslam", "--help"], tmp_path)
    assert run.returncode == 0 and "exit status:" in run.stdout and "2  a user or input error" in run.stdout


@pytest.mark.slow
def test_without_matplotlib_plots_are_skipped(tmp_path):
    shim = tmp_path / "shim"
    (shim / "matplotlib").mkdir(parents=True)
    (shim / "matplotlib" / "__init__.py").write_text("raise ImportError('matplotlib hidden by the test')\n")
    env = {"PYTHONPATH": str(shim) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    run = _run(["-m", "probslam", "optimize", "-o", "g"], tmp_path, env)
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr
    assert run.stderr.strip() == "probslam: plot skipped: matplotlib is not installed (pip install 'probslam[plot]')"
    assert (tmp_path / "g.g2o").exists() and not (tmp_path / "g.png").exists()
    run = _run(["-m", "probslam", "ekf-slam", "-o", "e"], tmp_path, env)
    assert run.returncode == 0 and "plot skipped" in run.stderr and "Traceback" not in run.stderr
    assert (tmp_path / "e_trajectory.tum").exists() and not (tmp_path / "e.png").exists()


def test_an_unexpected_error_is_one_line_and_exit_1(monkeypatch, capsys):
    def broken(args):
        raise RuntimeError("something the code did not expect")

    monkeypatch.setitem(cli.COMMANDS, "map", broken)
    monkeypatch.delenv("PROBSLAM_DEBUG", raising=False)
    assert cli.main(["map"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unexpected error: RuntimeError: something the code did not expect" in err
    monkeypatch.setenv("PROBSLAM_DEBUG", "1")
    with pytest.raises(RuntimeError):
        cli.main(["map"])


def test_a_mrclam_folder_missing_a_robot_file_is_named(tmp_path, capsys):
    import shutil

    folder = tmp_path / "mrclam"
    shutil.copytree(data.path("mrclam7_robot1_120s"), folder)
    (folder / "Robot1_Odometry.dat.gz").unlink()
    assert cli.main(["ekf-slam", str(folder), "-o", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Robot1_Odometry.dat" in err and "expected a UTIAS MRCLAM folder" in err


@pytest.mark.slow
def test_a_skipped_line_is_a_one_line_warning(tmp_path):
    log = tmp_path / "log.log"
    log.write_text("FLASER 3 1 2 1 0 0 0 0 0 0\nFLASER 3 1 2\nFLASER 3 1 2 1 0.1 0 0 0.1 0 0\n")
    run = _run(["-m", "probslam", "map", str(log), "--no-progress", "-o", "m"], tmp_path)
    assert run.returncode == 0, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"probslam: warning: {log}: skipped 1 malformed line (line 2: ")


@pytest.mark.slow
def test_ekf_slam_bearing_offset_on_the_bundled_mrclam(tmp_path, capsys):
    """--bearing-offset runs the multiple hypotheses with the scan's offset: the printed share of
    correct sightings is the library's for the same run; misuse is a one-line error."""
    from probslam.datasets import mrclam

    args = ["ekf-slam", "--unknown", "--association", "mht", "--sigma-phi", "0.02", "--bearing-offset", "0.03"]
    assert cli.main(args + ["-o", str(tmp_path / "e")]) == 0
    out = capsys.readouterr().out
    assert "unknown (mht) correspondences, bearing offset 0.03 rad per scan" in out
    robot = io.read_mrclam(data.path("mrclam7_robot1_120s")).with_euclidean_ranges()
    run = mrclam.run_ekf(robot, np.diag([0.15 ** 2, 0.6 ** 2]), np.diag([0.15 ** 2, 0.02 ** 2]), known=False,
                            association="mht", hypotheses=ps.MultiHypothesisOptions(bearing_offset_sigma=0.03))
    assert f"associations:  {ps.eval.association_accuracy(run):.1%} correct" in out
    for bad, message in [(["ekf-slam", "--unknown", "--association", "jcbb", "--bearing-offset", "0.03"],
                          "needs unknown correspondences and association mht"),
                         (["ekf-slam", "--bearing-offset", "0.03"], "needs unknown correspondences and association mht"),
                         (["ekf-slam", "--unknown", "--association", "mht", "--bearing-offset", "-0.1"], "--bearing-offset"),
                         (["ekf-slam", "--unknown", "--association", "mht", "--bearing-offset", "nan"], "--bearing-offset"),
                         (["ekf-slam", data.path("victoria_park_1000.txt"), "--bearing-offset", "0.03"], "MRCLAM")]:
        assert cli.main(bad + ["-o", str(tmp_path / "x")]) == 2
        assert message in capsys.readouterr().err


def test_slam_flags_set_their_option_paths(tmp_path, capsys, monkeypatch):
    # Each flag replaces one field of default_options(log) (SLAM_FLAGS); the rest is the log's.
    seen = []

    def spy(log, **kw):
        seen.append(kw["options"])
        raise KeyboardInterrupt  # the options are what is tested, not the run
    monkeypatch.setattr(ps.pipelines.slam_run, "run_slam", spy)
    log = data_path(cli.BUNDLED_RAW_LOG)
    out = ["-o", str(tmp_path / "s"), "--no-progress"]
    assert cli.main(["slam", log, "--resolution", "0.1", "--submap-distance", "5", "--no-loop-closures"] + out) \
        == cli.EXIT_INTERRUPTED
    assert cli.main(["slam", log, "--method", "rbpf", "--particles", "7", "--proposal", "motion", "--seed", "9",
                     "--threads", "2", "--max-range", "40"] + out) == cli.EXIT_INTERRUPTED
    graph, rbpf = seen
    assert graph == ps.slam.default_options(log).replace(frontend={"resolution": 0.1, "submap_distance": 5.0},
                                                         closures={"enabled": False})
    assert rbpf == ps.slam.default_options(log, "rbpf").replace(num_particles=7, proposal="motion", seed=9, threads=2,
                                                                 filter={"max_range": 40.0})


def test_slam_particle_count_is_checked_by_name_before_reading(tmp_path, capsys):
    # The library checks num_particles; the CLI tells its message as the flag.
    for value, message in (("0", "must lie in [1, 100000]"), (str(2 ** 64), "is out of range")):
        assert cli.main(["slam", "--method", "rbpf", "--particles", value, "-o", str(tmp_path / "s"), "--no-progress"]) == 2
        err = capsys.readouterr()
        assert f"probslam: error: --particles {value}: {message}" in err.err and "scans" not in err.out
    assert not list(tmp_path.iterdir())


# --- issue 33: every user error one line and exit 2, options checked before the data ---------

def _mrclam_folder(folder, odometry=True, measurements=True, survey=True, groundtruth=None):
    """A copy of the bundled MRCLAM excerpt, uncompressed, with some files emptied or replaced."""
    import gzip
    import shutil

    shutil.copytree(ps.data.path(cli.BUNDLED_LANDMARKS), folder)
    for packed in list(folder.glob("*.gz")):
        packed.with_suffix("").write_bytes(gzip.decompress(packed.read_bytes()))
        packed.unlink()
    for keep, name in ((odometry, "Robot1_Odometry.dat"), (measurements, "Robot1_Measurement.dat"),
                       (survey, "Landmark_Groundtruth.dat")):
        if not keep:
            (folder / name).write_text("# nothing\n")
    if groundtruth is not None:
        (folder / "Robot1_Groundtruth.dat").write_text(groundtruth)
    return folder


def _one_line_error(capsys, *needles):
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("probslam"), captured.err
    for needle in needles:
        assert needle in lines[0], lines[0]
    return captured


@pytest.mark.parametrize("command", ["ekf-slam", "fastslam"])
@pytest.mark.parametrize("value", ["1e300", "1e-200"])
def test_a_sigma_whose_square_is_not_a_finite_variance_is_refused_by_flag(tmp_path, capsys, command, value):
    """--sigma-v 1e300 ended in an OverflowError (exit 1, "a bug"); 1e-200 squared is 0."""
    assert cli.main([command, "--sigma-v", value, "-o", str(tmp_path / "x")]) == 2
    captured = _one_line_error(capsys, "--sigma-v", "finite variance")
    assert "dataset:" not in captured.out and not list(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["ekf-slam", "fastslam"])
def test_mrclam_ground_truth_with_no_row_inside_seconds_is_one_line(tmp_path, capsys, command):
    """It was an IndexError (exit 1) from the driver."""
    folder = _mrclam_folder(tmp_path / "d", groundtruth="# Time x y theta\n2e9 0 0 0\n")
    assert cli.main([command, str(folder), "--seconds", "5", "--particles", "5", "-o", str(tmp_path / "x")]
                    if command == "fastslam" else [command, str(folder), "--seconds", "5", "-o", str(tmp_path / "x")]) == 2
    _one_line_error(capsys, "Groundtruth has no row within the first 5 s")


@pytest.mark.parametrize("command", ["ekf-slam", "fastslam"])
def test_an_empty_mrclam_measurement_file_is_one_line_not_a_nan_rmse(tmp_path, capsys, command):
    folder = _mrclam_folder(tmp_path / "d", measurements=False)
    assert cli.main([command, str(folder), "-o", str(tmp_path / "x")]) == 2
    captured = _one_line_error(capsys, str(folder), "no landmark measurements for robot 1")
    assert "RMSE" not in captured.out and "filter" not in captured.out


def test_an_empty_mrclam_survey_is_one_line_not_a_nan_rmse(tmp_path, capsys):
    folder = _mrclam_folder(tmp_path / "d", survey=False)
    assert cli.main(["ekf-slam", str(folder), "-o", str(tmp_path / "x")]) == 2
    assert "nan" not in _one_line_error(capsys, "Landmark_Groundtruth.dat lists no landmark").out


def test_a_survey_too_large_to_score_is_one_line_without_warnings(tmp_path, capsys):
    folder = _mrclam_folder(tmp_path / "d")
    survey = folder / "Landmark_Groundtruth.dat"
    survey.write_text("".join(line if line.startswith("#") else " ".join([line.split()[0]] + ["1e300"] * 4) + "\n"
                              for line in survey.read_text().splitlines(keepends=True) if line.strip()))
    assert cli.main(["ekf-slam", str(folder), "-o", str(tmp_path / "x")]) == 2
    assert "inf" not in _one_line_error(capsys, "scores are not finite").out


@pytest.mark.parametrize("command", ["ekf-slam", "fastslam"])
def test_a_victoria_park_file_without_landmark_lines_is_one_line(tmp_path, capsys, command):
    """It ended in three lines (two numpy warnings and "measurement_noise must contain only
    finite values")."""
    path = tmp_path / "vp.txt"
    path.write_text("".join(line for line in open(ps.data.path("victoria_park_1000.txt"))
                            if not line.startswith("LANDMARK")))
    assert cli.main([command, str(path), "-o", str(tmp_path / "x")]) == 2
    _one_line_error(capsys, str(path), "no LANDMARK records")


@pytest.mark.parametrize("argv, flag", [
    (["map", "--resolution", "0"], "--resolution"),
    (["map", "--max-range", "inf"], "--max-range"),
    (["map", "--robot-radius", "nan"], "--robot-radius"),
    (["slam", "--resolution", "nan"], "--resolution"),
    (["slam", "--max-range", "-1"], "--max-range"),
    (["slam", "--submap-distance", "inf"], "--submap-distance"),
    (["ekf-slam", "--seconds", "nan"], "--seconds"),
    (["ekf-slam", "--robot", "7"], "--robot"),
    (["ekf-slam", "--bearing-offset", "inf"], "--bearing-offset"),
    (["fastslam", "--seed", "-1"], "--seed"),
    (["fastslam", "--seed", str(2 ** 64)], "--seed"),
    (["fastslam", "--robot", "0"], "--robot"),
    (["optimize", "--kernel-width", "nan"], "--kernel-width"),
    (["map", "--resolution", "abc"], "--resolution"),  # argparse's own errors are one line too
    (["ekf-slam", "--seconds", "-inf"], "--seconds"),
    (["fastslam", "--variant", "3"], "--variant"),
])
def test_bad_option_values_are_one_line_naming_the_flag_before_reading(tmp_path, capsys, argv, flag):
    missing = str(tmp_path / "missing")  # checked before the data: the missing file is never named
    with pytest.raises(SystemExit) if argv[-1] in ("abc", "-inf", "3") else contextlib.nullcontext() as exit_info:
        status = cli.main(argv[:1] + [missing] + argv[1:] + ["-o", str(tmp_path / "x")])
    status = exit_info.value.code if exit_info else status
    assert status == 2
    captured = _one_line_error(capsys, flag)
    assert missing not in captured.err and not list(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["ekf-slam", "fastslam"])
def test_victoria_park_distances_beyond_max_coordinate_are_one_line(tmp_path, capsys, command):
    """1e300 in a LANDMARK record ended in a numpy overflow warning and "measurement_noise must be
    positive definite" (an internal name)."""
    path = tmp_path / "vp.txt"
    path.write_text("ODOMETRY 0 1 1 0 0 10 0 0 10 0 31.6\nLANDMARK 1 7 1e300 1 1.6 0 1.6\n")
    assert cli.main([command, str(path), "-o", str(tmp_path / "x")]) == 2
    _one_line_error(capsys, str(path), "LANDMARK records with distances beyond 1e+09 m (MAX_COORDINATE)")


def test_every_command_checks_its_output_folder_before_the_run(tmp_path, capsys):
    """`probslam slam -o /missing/dir/x` ran the whole log, then failed writing."""
    missing = str(tmp_path / "missing" / "x")
    for command in (["map"], ["slam"], ["ekf-slam"], ["fastslam"], ["optimize"]):
        start = time.perf_counter()
        assert cli.main(command + ["-o", missing]) == 2
        err = capsys.readouterr().err
        assert err == f"probslam: error: -o {missing}: folder {os.path.dirname(missing)} does not exist\n", err
        assert time.perf_counter() - start < 5.0  # refused before any data is read


@pytest.mark.parametrize("command", [["map"], ["slam"], ["ekf-slam"], ["fastslam", "--particles", "5"],
                                     ["optimize"]])
def test_no_plot_everywhere_a_picture_is_written(tmp_path, command, capsys):
    prefix = str(tmp_path / "o")
    assert cli.main(command + ["--no-plot", "-o", prefix]) == 0
    assert not (tmp_path / "o.png").exists()
    assert ".png" not in capsys.readouterr().out


@pytest.mark.parametrize("fmt", ["tum", "kitti", "xyt"])
def test_every_trajectory_is_one_format_with_timestamps(tmp_path, fmt):
    """slam wrote 'timestamp x y theta' rows evo refuses, ekf-slam / fastslam wrote no times
    (issue 36); optimize wrote no path. Now one writer and --trajectory-format: the times are the
    run's (scan times, MRCLAM seconds; a graph's vertex ids)."""
    runs = {"slam": ["slam", "--no-progress"], "ekf-slam": ["ekf-slam", "--no-progress"],
            "fastslam": ["fastslam", "--particles", "5", "--no-progress"],
            "optimize": ["optimize", "--max-iterations", "3"]}
    for name, command in runs.items():
        prefix = str(tmp_path / name)
        assert cli.main(command + ["--no-plot",
                                   "--trajectory-format", fmt, "-o", prefix]) in (0, cli.EXIT_NOT_CONVERGED)
        path = prefix + "_trajectory" + io.trajectory.EXTENSIONS[fmt]
        trajectory = io.read_trajectory(path)
        assert trajectory.format == fmt and not trajectory.times_from_index and len(trajectory) > 10
        assert np.all(np.isfinite(trajectory.poses))
        if name == "slam":  # the scans' times (the Intel log's clock steps back once: kept as logged)
            log = io.read_carmen_log(data_path(cli.BUNDLED_SLAM_LOG))
            np.testing.assert_allclose(trajectory.timestamps, log.scans.timestamps, rtol=0, atol=1e-9)
        else:
            assert np.all(np.diff(trajectory.timestamps) >= 0)
        if name == "ekf-slam":  # MRCLAM seconds: Unix time of 2009
            assert trajectory.timestamps[0] > 1.2e9
        if name == "optimize":
            graph = ps.read_pose_graph(prefix + ".g2o")
            np.testing.assert_array_equal(trajectory.timestamps, np.sort(graph.pose_ids).astype(float))
        if fmt == "kitti":
            assert os.path.exists(prefix + "_trajectory_times.txt")


def test_a_run_that_does_not_converge_exits_3_not_1(tmp_path, capsys):
    """Exit 1 meant both "a bug" and "optimize did not converge"."""
    assert cli.main(["optimize", "--max-iterations", "1", "--no-plot", "-o", str(tmp_path / "o")]) == 3
    assert (tmp_path / "o.g2o").exists()  # the result is written all the same
    assert "exit status" in cli.build_parser().format_help() and "3  optimize did not converge" in cli.EPILOG


@pytest.mark.parametrize("command", ["ekf-slam", "fastslam"])
def test_refine_graphslam_prints_and_writes_what_the_library_computes(tmp_path, capsys, command):
    """--unknown --refine graphslam on the bundled MRCLAM excerpt: the refinement line and the
    trajectory file are refine_run's on the same run."""
    assert cli.main([command, "--unknown", "--refine", "graphslam", "--no-plot", "-o", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    data = ps.datasets.load_landmark_dataset(ps.data.path("mrclam7_robot1_120s"))
    run = ps.run_landmark_slam(data, "mht" if command == "ekf-slam" else "fastslam", known=False)  # the defaults
    refined = ps.refine_run(run, data, ps.datasets.mrclam.MOTION_NOISE, ps.datasets.mrclam.MEASUREMENT_NOISE)
    result = refined.as_landmark_slam_result(run)
    accuracy = ps.eval.association_accuracy(result)
    assert f"GraphSLAM correspondence test (ch. 11.6): {accuracy:.1%} correct, {len(result.landmarks)} landmarks" in out
    assert accuracy >= ps.eval.association_accuracy(run)
    written = io.read_trajectory(tmp_path / "r_trajectory.tum")
    np.testing.assert_allclose(written.poses, refined.result.poses, atol=1e-6)


@pytest.mark.parametrize("argv, message", [
    (["ekf-slam", "--refine", "graphslam"], "--refine graphslam needs unknown correspondences"),
    (["fastslam", "--refine", "graphslam"], "--refine graphslam needs unknown correspondences"),
    (["ekf-slam", "VICTORIA", "--unknown", "--refine", "graphslam"], "--refine graphslam applies to MRCLAM folders"),
])
def test_refine_graphslam_refuses_what_it_cannot_refine(tmp_path, capsys, argv, message):
    argv = [a if a != "VICTORIA" else ps.data.path("victoria_park_1000.txt") for a in argv]
    assert cli.main(argv + ["--no-plot", "-o", str(tmp_path / "x")]) == 2
    assert message in capsys.readouterr().err


def test_slam_rbpf_takes_seed_and_threads(tmp_path, capsys):
    """slam --method rbpf had no --seed and no --threads (issue 52); the library checks them and
    its message names the flag."""
    base = ["slam", "--method", "rbpf", "--particles", "2", "--no-plot", "--no-progress", "-o", str(tmp_path / "s")]
    assert cli.main(base + ["--seed", "-1"]) == 2
    assert capsys.readouterr().err.startswith("probslam: error: --seed -1: must be in [0, 2^64)")
    assert cli.main(base + ["--threads", "0"]) == 2
    assert capsys.readouterr().err.startswith("probslam: error: --threads 0: must lie in [1, 1024]")
    assert cli.main(["slam", "--seed", "3", "--no-plot", "-o", str(tmp_path / "g")]) == 2
    assert "--seed does not apply to --method graph" in capsys.readouterr().err
