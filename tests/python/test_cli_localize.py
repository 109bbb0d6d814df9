"""probslam localize end to end: the bundled raw Intel excerpt mapped by probslam slam, then
localized in that map from its start (tracking) and from nowhere (global)."""

import numpy as np
import pytest

import probslam as ps
from probslam import cli, io


@pytest.fixture(scope="module")
def slam_map(tmp_path_factory):
    prefix = tmp_path_factory.mktemp("slam") / "s"
    assert cli.main(["slam", cli._bundled_log(cli.BUNDLED_RAW_LOG), "-o", str(prefix), "--no-progress", "--no-plot"]) == 0
    return prefix


def test_localize_tracks_the_slam_trajectory(slam_map, tmp_path, capsys):
    capsys.readouterr()
    ref = io.read_trajectory(f"{slam_map}_trajectory.tum")
    log = cli._bundled_log(cli.BUNDLED_RAW_LOG)
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
    log = cli._bundled_log(cli.BUNDLED_RAW_LOG)
    code = cli.main(["localize", log, "--map", f"{slam_map}.yaml", "--global", "-o", str(tmp_path / "g"),
                     "--no-progress", "--no-plot"])
    assert code == 0
    traj = io.read_trajectory(tmp_path / "g_trajectory.tum")
    err = np.hypot(*(traj.poses[-20:, :2] - ref.poses[-20:, :2]).T)
    assert np.max(err) < 0.3


def test_localize_options_are_checked(slam_map, tmp_path, capsys):
    log = cli._bundled_log(cli.BUNDLED_RAW_LOG)
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
    slam = ps.run_slam(data.path("intel_raw_loop.log.gz"), resolution=0.1, progress=False)
    late = ours.timestamps >= ours.timestamps[len(ours) // 2]  # well after convergence
    idx = np.searchsorted(slam.timestamps, ours.timestamps[late])
    err = np.hypot(*(ours.poses[late, :2] - slam.poses[idx, :2]).T)
    assert np.median(err) < 0.2, np.median(err)
    for args, message in ((["localize", data.path("intel_raw_loop.log.gz"), "--global"], "--map: give the map"),
                          (["localize", "--map", data.path("intel_raw_loop_map.yaml"), "--global"], "without a LOG")):
        assert cli.main(args + ["--no-progress", "--no-plot", "-o", str(tmp_path / "x")]) == 2
        assert message in capsys.readouterr().err
