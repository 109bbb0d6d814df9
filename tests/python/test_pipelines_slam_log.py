"""pipelines.slam_log (module pipelines.slam_run), the run of ``probslam slam``: from Python it runs run_slam with the options
given, writes what the command writes and says what it prints."""

import pytest

import probslam as ps
from probslam import cli
from probslam.pipelines import SlamLogRun, slam_log
from probslam.data import path as data_path


@pytest.mark.slow
def test_slam_log_is_run_slam_and_writes_and_says_what_the_command_does(tmp_path, capsys):
    log = data_path(cli.BUNDLED_SLAM_LOG)
    options = ps.slam.default_options(log).replace(closures={"enabled": False})
    run = slam_log(log, options, progress=False)
    assert isinstance(run, SlamLogRun) and run.path == log and run.result.options == options
    direct = ps.run_slam(log, options=options, progress=False)
    assert (run.result.poses == direct.poses).all()
    written = run.write(str(tmp_path / "py"))
    assert written == [str(tmp_path / f"py{s}") for s in (".yaml", ".pgm", "_trajectory.tum", ".g2o")]
    assert cli.main(["slam", log, "--no-loop-closures", "--no-plot", "--no-progress", "-o", str(tmp_path / "cli")]) == 0
    printed = capsys.readouterr().out
    assert (tmp_path / "py_trajectory.tum").read_bytes() == (tmp_path / "cli_trajectory.tum").read_bytes()
    ours = run.summary(log, written).splitlines()
    theirs = printed.splitlines()
    # The same lines but the wall time and the file names written.
    keep = [k for k, line in enumerate(ours) if not line.startswith(("time:", "wrote:", "log:"))]
    assert [ours[k] for k in keep] == [theirs[k] for k in keep]
    assert "closures:      0 accepted" in printed


def test_slam_log_refuses_what_is_not_a_log():
    with pytest.raises(TypeError, match="log"):
        slam_log(42)
