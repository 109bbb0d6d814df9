"""probslam localize end to end: the bundled raw Intel excerpt mapped by probslam slam, then
localized in that map from its start (tracking) and from nowhere (global)."""

import numpy as np
import pytest

import probslam as ps
from probslam import cli, io
from probslam.data import path as data_path


@pytest.fixture(scope="module")
def slam_map(tmp_path_factory):
    prefix = tmp_path_factory.mktemp("slam") / "s"
    assert cli.main(["slam", data_path(cli.BUNDLED_RAW_LOG), "-o", str(prefix), "--no-progress", "--no-plot"]) == 0
    return prefix


def test_localize_tracks_the_slam_trajectory(slam_map, tmp_path, capsys):
    capsys.readouterr()
    ref = io.read_trajectory(f"{slam_map}_trajectory.tum")
    log = data_path(cli.BUNDLED_RAW_LOG)
    prefix = tmp_path / "loc"
    args = ["localize", log, "--map", f"{slam_map}.yaml", "--initial-pose", *map(str, ref.poses[0]), "-o",
            str(prefix), "--no-progress"]
    assert cli.main(args) == 0
    out = capsys.readouterr().out
    assert "converged:     after" in out and "real-time factor" in out and "particles:" in out
    traj = io.read_trajectory(tmp_path / "loc_trajectory.tum")
    assert traj.poses.shape == ref.poses.shape
    ate = ps.eval.ate(traj.timestamps, traj.poses, ref.timestamps, ref.poses, align="none")
    # The map has 0.05 m cells and the SLAM trajectory made it: the two agree within a few cells.
    assert ate.rmse < 0.15, ate.rmse
    assert (tmp_path / "loc.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_localize_global_on_the_bundled_log(slam_map, tmp_path, capsys):
    ref = io.read_trajectory(f"{slam_map}_trajectory.tum")
    log = data_path(cli.BUNDLED_RAW_LOG)
    code = cli.main(["localize", log, "--map", f"{slam_map}.yaml", "--global", "-o", str(tmp_path / "g"),
                     "--no-progress", "--no-plot"])
    assert code == 0
    traj = io.read_trajectory(tmp_path / "g_trajectory.tum")
    err = np.hypot(*(traj.poses[-20:, :2] - ref.poses[-20:, :2]).T)
    assert np.max(err) < 0.3


def test_localize_options_are_checked(slam_map, tmp_path, capsys):
    log = data_path(cli.BUNDLED_RAW_LOG)
    base = ["localize", log, "--map", f"{slam_map}.yaml", "-o", str(tmp_path / "x"), "--no-progress"]
    assert cli.main(base) == 2
    assert "--initial-pose" in capsys.readouterr().err
    assert cli.main(base + ["--global", "--initial-pose", "0", "0", "0"]) == 2
    assert "exclude" in capsys.readouterr().err
    assert cli.main(base + ["--global", "--max-particles", "10", "--min-particles", "20"]) == 2
    assert "--max-particles" in capsys.readouterr().err
    assert cli.main(["localize", log, "--map", str(tmp_path / "missing.yaml"), "--global"]) == 2
    assert "missing.yaml" in capsys.readouterr().err


def test_localize_without_arguments_uses_the_bundled_loop_and_map(tmp_path, capsys):
    """`probslam localize --global`: the bundled raw Intel loop in its bundled map (made by
    probslam slam from the same log); the global start converges, and the converged part of the
    path agrees with the SLAM trajectory the map came from."""
    from probslam import data, io

    assert cli.main(["localize", "--global", "--no-progress", "--no-plot", "-o", str(tmp_path / "g")]) == 0
    assert "converged:     after" in capsys.readouterr().out
    ours = io.read_trajectory(tmp_path / "g_trajectory.tum")
    log = data.path("intel_raw_loop.log.gz")
    slam = ps.run_slam(log, options=ps.slam.default_options(log).replace(frontend={"resolution": 0.1}), progress=False)
    late = ours.timestamps >= ours.timestamps[len(ours) // 2]  # well after convergence
    idx = np.searchsorted(slam.timestamps, ours.timestamps[late])
    err = np.hypot(*(ours.poses[late, :2] - slam.poses[idx, :2]).T)
    assert np.median(err) < 0.2, np.median(err)
    for args, message in ((["localize", data.path("intel_raw_loop.log.gz"), "--global"], "--map: give the map"),
                          (["localize", "--map", data.path("intel_raw_loop_map.yaml"), "--global"], "without a LOG")):
        assert cli.main(args + ["--no-progress", "--no-plot", "-o", str(tmp_path / "x")]) == 2
        assert message in capsys.readouterr().err


def test_localize_with_no_arguments_runs_global_localization_on_bundled_data(tmp_path, capsys, monkeypatch):
    """`probslam localize` alone (the README: every command runs on bundled data): the bundled raw
    Intel loop in its bundled map from a global start, said as it starts; it converges."""
    monkeypatch.chdir(tmp_path)
    assert cli.main(["localize", "--no-progress", "--no-plot"]) == 0
    out = capsys.readouterr().out
    assert "no LOG given: the bundled raw Intel loop" in out and "global start" in out
    assert "start:         global" in out and "converged:     after" in out
    assert (tmp_path / "localize_trajectory.tum").exists()


def _scan_only_log(tmp_path):
    """The bundled raw loop's first 60 scans with every pose set to 0: a log (or bag) of scans
    without odometry."""
    import gzip

    lines = []
    with gzip.open(data_path(cli.BUNDLED_RAW_LOG), "rt") as f:
        for line in f:
            if line.startswith("FLASER"):
                w = line.split()
                w[-9:-3] = ["0.0"] * 6
                lines.append(" ".join(w))
            if len(lines) == 60:
                break
    path = tmp_path / "scans_only.log"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_localize_says_when_nothing_moves_the_filter(tmp_path, capsys):
    from probslam import data

    log = _scan_only_log(tmp_path)
    code = cli.main(["localize", str(log), "--map", data.path("intel_raw_loop_map.yaml"), "--global",
                     "--max-particles", "2000", "--no-progress", "--no-plot", "-o", str(tmp_path / "s")])
    out = capsys.readouterr().out
    assert code == cli.EXIT_NOT_CONVERGED
    assert "scans:         60; 1 filter updates" in out
    assert "odometry:      none: the log's poses never move" in out and "nothing moved it" in out


def test_convergence_is_reported_from_its_first_time_with_the_spells_lost():
    """A run that converged early and lost the track for one moment late on: 'converged after'
    the first time (not after the late moment), the share of the time, and the spell."""
    from probslam.localization import LocalizationResult
    from probslam.pipelines import convergence_report

    t = np.arange(10, dtype=float) * 2.0 + 100.0
    converged = np.array([False, False, True, True, True, True, True, False, True, True])
    r = LocalizationResult(timestamps=t, poses=np.zeros((10, 3)), covariances=np.zeros((10, 3, 3)),
                           num_particles=np.full(10, 500), converged=converged, updated=np.ones(10, bool),
                           convergence_time=4.0, travel_to_converge=1.5, seconds=1.0, log_duration=18.0)
    assert r.converged_fraction == pytest.approx(7 / 8)
    assert r.lost == [(14.0, 16.0)]
    text = convergence_report(r)
    assert text.startswith("after 4.0 s of log, 1.5 m of travel; then converged 87.5% of the time")
    assert "lost at 14.0 s, regained at 16.0 s" in text
    r.converged[8:] = False
    assert r.lost == [(14.0, None)] and "not regained" in convergence_report(r)



def test_a_map_at_micrometre_cells_is_a_user_error(tmp_path, capsys):
    """A map YAML at resolution 1e-6 asked the likelihood field for terabytes (exit 1, 'a bug');
    the field is now bounded by the map, and the command says the map cannot hold a scan."""
    import shutil

    from probslam import data

    shutil.copy(data.path("intel_raw_loop_map.pgm"), tmp_path / "intel_raw_loop_map.pgm")
    text = open(data.path("intel_raw_loop_map.yaml")).read().splitlines()
    text = ["resolution: 0.000001" if line.startswith("resolution:") else line for line in text]
    (tmp_path / "tiny.yaml").write_text("\n".join(text) + "\n")
    log = data_path(cli.BUNDLED_RAW_LOG)
    code = cli.main(["localize", log, "--map", str(tmp_path / "tiny.yaml"), "--global", "--no-progress", "--no-plot",
                     "-o", str(tmp_path / "t")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "--map " in err and "tiny.yaml: 0.000296 x 0.000286 m" in err
    assert "check its resolution" in err


def test_threads_that_cannot_start_are_a_user_error(tmp_path, capsys):
    """`localize --threads N` when the system refuses the threads: one line naming --threads,
    exit 2 (was RuntimeError, exit 1 'a bug')."""
    from probslam import _core

    _core._fail_worker_thread_start_after(0)
    try:
        code = cli.main(["localize", "--threads", "4", "--no-progress", "--no-plot", "-o", str(tmp_path / "x")])
    finally:
        _core._fail_worker_thread_start_after(-1)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("probslam: error: --threads 4: the system refused to start 4 worker threads")
    assert err.count("\n") == 1
