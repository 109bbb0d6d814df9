"""Issue 49: a CARMEN log's time is its logger stamp (each record's last field), the clock the
corrected Radish logs carry, so a `slam` run's trajectory and a corrected log pair; the ipc stamp
(the clock of the Freiburg relations files) is kept beside it, and eval moves relations onto the
logger time."""

import gzip
import re

import numpy as np
import pytest

import probslam as ps
from probslam import cli, io

#: ipc minus logger time of the raw Intel log (the same for all its records, to the last digit
#: written): what the scans' times were before issue 49.
INTEL_IPC_OFFSET = 976052857.337284
#: The ATE (RMSE, m, after the rigid alignment) a lap that pairs with GMapping's corrected poses
#: stays under: its scans are matched to a few centimetres; a pairing at the wrong scans or a
#: lost alignment gives metres.
PLAUSIBLE_ATE = 0.5
#: eval's default --max-time-difference (evo's): the pairs it may make.
MAX_TIME_DIFFERENCE = 0.01


def _log_text(ipc_offset):
    """Three FLASER and two ODOM records whose ipc stamps run ipc_offset s ahead of the logger's."""
    lines = []
    for k, t in enumerate((0.25, 0.5, 0.75)):
        lines.append(f"ODOM {0.1 * k} 0 0 0 0 0 {t - 0.01 + ipc_offset:.6f} host {t - 0.01:.6f}")
        lines.append(f"FLASER 3 1.0 2.0 3.0 {0.1 * k} 0 0 {0.1 * k} 0 0 {t + ipc_offset:.6f} host {t:.6f}")
    return "\n".join(lines) + "\n"


def test_a_log_is_timed_by_its_logger_stamps_and_keeps_the_ipc_ones(tmp_path):
    path = tmp_path / "clock.log.gz"
    with gzip.open(path, "wt") as f:
        f.write(_log_text(1000.0))
    log = io.read_carmen_log(path)
    np.testing.assert_array_equal(log.scans.timestamps, [0.25, 0.5, 0.75])
    np.testing.assert_array_equal(log.scans.ipc_timestamps, [1000.25, 1000.5, 1000.75])
    np.testing.assert_array_equal(log.odometry.timestamps, [0.24, 0.49, 0.74])
    np.testing.assert_array_equal(log.odometry.ipc_timestamps, [1000.24, 1000.49, 1000.74])
    # Sources without an ipc clock (a bag, a simulation) have NaN there; slicing keeps working.
    scans = io.LaserScans(log.scans.ranges, log.scans.laser_poses, log.scans.robot_poses, log.scans.start_angles,
                          log.scans.angular_resolutions, log.scans.max_ranges, log.scans.num_beams,
                          log.scans.timestamps)
    assert scans.ipc_timestamps.shape == (3,) and np.all(np.isnan(scans.ipc_timestamps))


def test_the_bundled_logs_load_on_the_logger_clock():
    """The raw excerpts start at logger time 0.000246 s (their ipc time was 976052857.337530);
    the corrected excerpt's two stamps are equal."""
    for name, first in (("intel_raw_lap.log.gz", 0.000246), ("intel_raw_loop.log.gz", 0.000246),
                        ("intel_excerpt.log.gz", 32.9068)):
        scans = io.read_carmen_log(ps.data.path(name)).scans
        assert scans.timestamps[0] == first, name
        offset = scans.ipc_timestamps - scans.timestamps
        expected = INTEL_IPC_OFFSET if name.startswith("intel_raw") else 0.0
        np.testing.assert_allclose(offset, expected, atol=1e-6, rtol=0, err_msg=name)


def _raw_logger_times(path):
    """The logger stamp (last field) of every FLASER line, from the text itself."""
    with gzip.open(path, "rt") as f:
        return np.array([float(line.split()[-1]) for line in f if line.startswith("FLASER ")])


def test_slam_on_the_raw_lap_pairs_with_the_corrected_intel_log(shared_data, tmp_path, capsys):
    corrected = shared_data / "laser_2d/intel/intel-corrected.log.gz"
    if not corrected.exists():
        pytest.skip("the corrected Intel log is not present")
    lap = ps.data.path("intel_raw_lap.log.gz")
    out = tmp_path / "lap"
    assert cli.main(["slam", "--no-progress", "--no-plot", "-o", str(out)]) == 0
    capsys.readouterr()
    with pytest.warns(UserWarning, match="timestamps decrease 26 times"):  # the raw log's own stamps go back
        assert cli.main(["eval", str(out) + "_trajectory.tum", str(corrected)]) == 0
    printed = capsys.readouterr().out
    # Independently: the corrected scans whose logger stamp is within 0.01 s of a lap scan's.
    lap_times, corrected_times = _raw_logger_times(lap), _raw_logger_times(corrected)
    expected = int(np.sum(np.min(np.abs(corrected_times[:, None] - lap_times[None, :]), axis=1)
                          <= MAX_TIME_DIFFERENCE))
    assert expected > 50  # the lap holds one in 12 of the corrected log's scans
    pairs = re.search(r"associated:\s+(\d+) of (\d+) possible pose pairs", printed)
    assert pairs and int(pairs.group(1)) == expected, printed
    rmse = float(re.search(r"rmse\s+(\S+)", printed).group(1))
    assert np.isfinite(rmse) and 0.0 < rmse < PLAUSIBLE_ATE, printed


@pytest.mark.slow
def test_slam_on_the_whole_raw_intel_log_pairs_every_corrected_scan(shared_data, tmp_path, capsys):
    raw = shared_data / "laser_2d/intel/intel.clf"
    corrected = shared_data / "laser_2d/intel/intel-corrected.log.gz"
    if not (raw.exists() and corrected.exists()):
        pytest.skip("the Intel logs are not present")
    out = tmp_path / "intel"
    assert cli.main(["slam", str(raw), "--no-progress", "--no-plot", "-o", str(out)]) == 0
    capsys.readouterr()
    assert cli.main(["eval", str(out) + "_trajectory.tum", str(corrected)]) == 0
    printed = capsys.readouterr().out
    assert "associated:    910 of 910 possible pose pairs" in printed, printed
    rmse = float(re.search(r"rmse\s+(\S+)", printed).group(1))
    assert 0.0 < rmse < PLAUSIBLE_ATE, printed


# --- relations: stamped with the ipc time ---------------------------------------------------

def _scans(logger, ipc):
    n = len(logger)
    return io.LaserScans(np.ones((n, 2)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n), np.full(n, 0.1),
                         np.full(n, np.nan), np.full(n, 2), np.asarray(logger, float), np.asarray(ipc, float))


def test_relations_move_to_the_logger_time_of_the_scan_they_name():
    logger = np.array([0.0, 0.2, 0.4, 0.35, 0.6])  # a stamp going back, as in the raw Intel log
    ipc = logger + np.array([70.1, 70.1, 70.2, 70.2, 70.3])  # an offset that even drifts
    rel = ps.eval.Relations(ipc[[0, 3]], ipc[[2, 4]], np.zeros((2, 3)), skipped_rows=1, skipped_lines=[7])
    moved = ps.eval.relations_on_logger_time(rel, _scans(logger, ipc))
    np.testing.assert_allclose(moved.t1, logger[[0, 3]], atol=1e-12)
    np.testing.assert_allclose(moved.t2, logger[[2, 4]], atol=1e-12)
    assert moved.skipped_rows == 1 and moved.skipped_lines == [7]
    np.testing.assert_array_equal(rel.t1, ipc[[0, 3]])  # the input is left as it was
    with pytest.raises(ValueError, match="^scans: no scan has both"):
        ps.eval.relations_on_logger_time(rel, _scans(logger, np.full(5, np.nan)))
    with pytest.raises(TypeError, match="^scans: expected LaserScans"):
        ps.eval.relations_on_logger_time(rel, logger)


def test_the_aces_relations_name_aces_scans_on_the_logger_time(shared_data):
    aces = shared_data / "laser_2d/aces"
    if not (aces / "aces.clf.bz2").exists():
        pytest.skip("ACES not present")
    scans = io.read_carmen_log(aces / "aces.clf.bz2").scans
    moved = ps.eval.relations_on_logger_time(aces / "aces.relations", scans)
    times = np.round(scans.timestamps, 6)
    assert np.isin(np.round(moved.t1, 6), times).all() and np.isin(np.round(moved.t2, 6), times).all()
    assert len(moved) == 1279


def _relations_file(path, t1, t2, delta):
    rows = [f"{a:.6f} {b:.6f} {d[0]:.6f} {d[1]:.6f} 0 0 0 {d[2]:.6f}" for a, b, d in zip(t1, t2, delta)]
    path.write_text("\n".join(rows) + "\n")
    return str(path)


def test_eval_moves_relations_onto_the_estimates_clock(tmp_path, capsys):
    """Relations on the ipc clock, the estimate on the logger clock (as slam writes it): eval
    finds the one offset that puts every relation time on a pose's, says so, and scores as
    relations_error does on the logger time; with --log, through the log's own stamps."""
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.1, 0.3, 60)).round(6)
    poses = np.column_stack([np.cumsum(rng.normal(0.2, 0.05, 60)), rng.normal(0, 0.1, 60), rng.normal(0, 0.1, 60)])
    est = str(tmp_path / "est.tum")
    io.write_trajectory(t, poses, est, format="tum")
    i = rng.choice(59, 15, replace=False)
    delta = ps.eval.relative_poses(poses[i], poses[i + 1]) + rng.normal(0, 0.01, (15, 3))
    rel = _relations_file(tmp_path / "x.relations", t[i] + 70.1797, t[i + 1] + 70.1797, delta)
    assert cli.main(["eval", est, rel]) == 0
    printed = capsys.readouterr().out
    assert "times moved 70.179700 s earlier" in printed
    expected = ps.eval.relations_error(t, poses, ps.eval.Relations(t[i], t[i + 1], delta))
    assert re.search(rf"relations error w.r.t. translation part \(m\)\n\n.*\n\s+mean\s+{expected.trans_mean:.6f}",
                     printed), printed
    # The same through the log: a CARMEN file whose ipc stamps run 70.1797 s ahead.
    log = tmp_path / "run.log"
    log.write_text("".join(f"FLASER 2 1 1 0 0 0 0 0 0 {s + 70.1797:.6f} host {s:.6f}\n" for s in t))
    assert cli.main(["eval", est, rel, "--log", str(log)]) == 0
    printed = capsys.readouterr().out
    assert "ipc time to its logger time (70.179700 s earlier)" in printed
    assert re.search(rf"\s+mean\s+{expected.trans_mean:.6f}", printed), printed
    # Already on the estimate's clock: left alone, no message.
    same = _relations_file(tmp_path / "same.relations", t[i], t[i + 1], delta)
    assert cli.main(["eval", est, same]) == 0
    captured = capsys.readouterr()
    assert "times moved" not in captured.out and captured.err == ""
    # No offset puts them on the estimate's poses: a note.
    off = _relations_file(tmp_path / "off.relations", t[i] + 0.05123, t[i + 1] + 0.0731, delta)
    assert cli.main(["eval", est, off]) == 0
    assert "none of" in capsys.readouterr().err
    # --log applies to relations only.
    assert cli.main(["eval", est, est, "--log", str(log)]) == 2
    assert "--log " in (err := capsys.readouterr().err) and "applies to a relations file" in err


def test_a_run_saved_on_the_ipc_clock_is_refused_by_name(tmp_path):
    """A run file written before issue 49 holds the ipc times of its first and last scans: resuming
    it would mix the two clocks in one trajectory, so it is refused saying why."""
    import dataclasses

    from probslam.slam import load_run, run_slam, save_run

    scans = io.read_carmen_log(ps.data.path("intel_raw_lap.log.gz")).scans
    part = io.LaserScans(**{f.name: getattr(scans, f.name)[:40] for f in dataclasses.fields(scans)})
    run_slam(part, progress=False, save=tmp_path / "run.psl")
    run = load_run(tmp_path / "run.psl")
    assert (run.first_timestamp, run.last_timestamp) == (scans.timestamps[0], scans.timestamps[39])
    old = dataclasses.replace(run, first_timestamp=float(scans.ipc_timestamps[0]),
                              last_timestamp=float(scans.ipc_timestamps[39]))
    save_run(old, tmp_path / "old.psl")
    with pytest.raises(ValueError, match="timed by their ipc stamp.*run it again"):
        run_slam(scans, resume=tmp_path / "old.psl", progress=False)
    assert len(run_slam(scans, resume=tmp_path / "run.psl", progress=False).timestamps) == len(scans)
