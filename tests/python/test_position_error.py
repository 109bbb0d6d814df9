"""A path against reference positions with times, such as a GPS track (issue 50):
``probslam.eval.position_error`` against a hand computation and against ``ate`` where the two
coincide, its argument checks, and ``probslam eval EST gps.dat``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from probslam import cli
from probslam import eval as ev
from probslam import io


def straight_path():
    """x = t along the x axis, a pose every 2 s from 0 to 4 s (heading 0)."""
    t = np.array([0.0, 2.0, 4.0])
    return t, np.column_stack([t, np.zeros(3), np.zeros(3)])


def test_against_a_hand_computation():
    """Fixes at t = 1, 2, 3 (two between the poses, interpolated) at (1, 1), (2, -1), (3, 1);
    two more outside the span. By hand: the estimate is at (1, 0), (2, 0), (3, 0), each fix 1 m
    off: RMS 1. The best rigid fit keeps the rotation (the cross-covariance is diag(2, 0)) and
    moves the path by the centroids' difference (0, 1/3): errors 2/3, 4/3, 2/3 m, RMS
    sqrt((4 + 16 + 4) / 27) = sqrt(8/9)."""
    t, poses = straight_path()
    times_ref = np.array([-1.0, 1.0, 2.0, 3.0, 4.5])
    fixes = np.array([[9.0, 9.0], [1.0, 1.0], [2.0, -1.0], [3.0, 1.0], [9.0, 9.0]])
    r = ev.position_error(t, poses, times_ref, fixes)
    assert (r.count, r.outside) == (3, 2)
    np.testing.assert_array_equal(r.ref_indices, [1, 2, 3])
    np.testing.assert_allclose(r.errors, [1.0, 1.0, 1.0], rtol=0, atol=1e-15)
    assert r.rmse == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(r.rotation, np.eye(2), atol=1e-15)
    np.testing.assert_allclose(r.translation, [0.0, 1.0 / 3.0], atol=1e-15)
    np.testing.assert_allclose(r.errors_aligned, [2 / 3, 4 / 3, 2 / 3], atol=1e-15)
    assert r.rmse_aligned == pytest.approx(math.sqrt(8 / 9), abs=1e-15)
    # Positions alone (N, 2) are the same path.
    assert ev.position_error(t, poses[:, :2], times_ref, fixes).rmse_aligned == r.rmse_aligned


def test_a_path_in_another_frame_aligns_exactly():
    """The fixes are the path turned by 30 deg and moved: 0 after the alignment, which finds
    that turn, and the distances before it."""
    t = np.linspace(0.0, 10.0, 41)
    path = np.column_stack([t, np.sin(t), np.zeros_like(t)])
    turn = math.radians(30.0)
    rotation = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    times_ref = np.linspace(0.05, 9.95, 100)
    truth = np.column_stack([times_ref, np.interp(times_ref, t, path[:, 1])])  # on the path's chords
    fixes = truth @ rotation.T + [5.0, -2.0]
    r = ev.position_error(t, path, times_ref, fixes)
    assert r.count == 100 and r.outside == 0
    np.testing.assert_allclose(r.rotation, rotation, atol=1e-12)
    np.testing.assert_allclose(r.translation, [5.0, -2.0], atol=1e-12)
    assert r.rmse_aligned < 1e-12
    np.testing.assert_allclose(r.errors, np.hypot(*(fixes - truth).T), rtol=1e-12)


def test_coincides_with_ate_when_the_fixes_are_at_the_poses_times():
    rng = np.random.default_rng(4)
    n = 300
    t = np.cumsum(rng.uniform(0.1, 0.3, n))
    theta = np.cumsum(rng.normal(0.0, 0.1, n))
    ref = np.column_stack([np.cumsum(np.cos(theta)), np.cumsum(np.sin(theta)), np.angle(np.exp(1j * theta))])
    est = ref + rng.normal(0.0, [0.3, 0.3, 0.02], (n, 3))
    est[:, :2] = est[:, :2] @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + 7.0
    r = ev.position_error(t, est, t, ref[:, :2])
    aligned, plain = ev.ate(t, est, t, ref), ev.ate(t, est, t, ref, align="none")
    assert r.count == aligned.count == n
    assert r.rmse == pytest.approx(plain.rmse, rel=1e-12)
    assert r.rmse_aligned == pytest.approx(aligned.rmse, rel=1e-12)
    np.testing.assert_allclose(r.rotation, aligned.rotation, atol=1e-12)
    np.testing.assert_allclose(r.errors_aligned, aligned.errors, rtol=1e-9, atol=1e-12)


def test_the_str_is_evo_statistics_of_both():
    t, poses = straight_path()
    r = ev.position_error(t, poses, [1.0, 2.0, 3.0], [[1.0, 1.0], [2.0, -1.0], [3.0, 1.0]])
    text = str(r)
    assert "(not aligned)\n\n       max\t1.000000\n" in text
    assert f"      rmse\t{math.sqrt(8 / 9):.6f}\n" in text.split("(with SE(2) Umeyama alignment)")[1]


T3, P3 = straight_path()


@pytest.mark.parametrize("args, error, message", [
    (([], np.zeros((0, 3)), [1.0], [[0.0, 0.0]]), ValueError, "times_est: empty"),
    (([0.0, 2.0, 1.0], P3, [1.0], [[0.0, 0.0]]), ValueError, "times_est: decrease at index 2"),
    (([0.0, np.nan, 4.0], P3, [1.0], [[0.0, 0.0]]), ValueError, "times_est: contains NaN"),
    ((["a", "b", "c"], P3, [1.0], [[0.0, 0.0]]), TypeError, "times_est: expected real numbers"),
    ((T3, np.zeros((3, 4)), [1.0], [[0.0, 0.0]]), ValueError, "poses_est: expected shape"),
    ((T3, np.zeros((2, 3)), [1.0], [[0.0, 0.0]]), ValueError, "poses_est: expected shape"),
    ((T3, P3, [[1.0]], [[0.0, 0.0]]), ValueError, "times_ref: expected shape"),
    ((T3, P3, [1.0], [[0.0, 0.0, 0.0]]), ValueError, "positions_ref: expected shape"),
    ((T3, P3, [1.0], [[0.0, np.inf]]), ValueError, "positions_ref: contains NaN or inf"),
    ((T3, P3, [5.0, 6.0], [[0.0, 0.0], [1.0, 1.0]]), ValueError, r"times_ref: no fix within the estimate's time "
                                                                  r"span \[0, 4\] s \(reference \[5, 6\] s\)"),
    ((T3, P3, [], np.zeros((0, 2))), ValueError, r"times_ref: no fix .*\(reference empty\)"),
    ((T3, P3 * 1e300, [1.0, 2.0], [[-1e300, 0.0], [0.0, 0.0]]), ValueError, "poses_est and positions_ref: .* "
                                                                             "overflows a double"),
])
def test_every_input_is_checked_by_name(args, error, message):
    with pytest.raises(error, match=message):
        ev.position_error(*args)


def write_gps(path, times, xy, extra=""):
    with open(path, "w") as f:
        f.write(extra)
        for t, (x, y) in zip(times, xy):
            f.write(f"{t:10.3f} {x:12.4f} {y:12.4f}\n")


def test_cli_eval_against_a_gps_track(tmp_path, capsys):
    """``probslam eval EST gps.dat``: a 3-column t x y file is a position reference; the
    printed statistics are position_error's of the files as read."""
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 60.0, 0.025)
    theta = 0.3 * np.sin(0.1 * t)
    est = np.column_stack([np.cumsum(0.1 * np.cos(theta)), np.cumsum(0.1 * np.sin(theta)), theta])
    io.write_trajectory(t, est, tmp_path / "est.tum")
    times_ref = np.arange(-5.0, 70.0, 0.2)  # some fixes before and after the run
    fixes = np.column_stack([np.interp(times_ref, t, est[:, 0]), np.interp(times_ref, t, est[:, 1])])
    fixes += rng.normal(0.0, 0.5, fixes.shape) + [3.0, 1.0]
    write_gps(tmp_path / "gps.dat", times_ref, fixes, extra="# t x y\n1.0 2.0 nan\n")
    with pytest.warns(UserWarning, match="skipped 1 unreadable position rows"):
        assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "gps.dat")]) == 0
    out = capsys.readouterr().out
    with pytest.warns(UserWarning, match="lines 2; first: not finite numbers"):
        ref = io.read_positions(tmp_path / "gps.dat")
    read = io.read_trajectory(tmp_path / "est.tum")
    r = ev.position_error(read.timestamps, read.poses, ref.timestamps, ref.positions)
    assert f"gps.dat: {len(times_ref)} positions (t x y; 1 unreadable rows skipped)" in out
    assert f"fixes:         {r.count} used, {r.outside} outside the estimate's time span" in out
    assert r.outside == np.count_nonzero((times_ref < 0) | (times_ref > t[-1]))
    plain, aligned = out.split("(with SE(2) Umeyama alignment)")
    assert f"rmse\t{r.rmse:.6f}" in plain and f"rmse\t{r.rmse_aligned:.6f}" in aligned
    assert r.rmse > 3.0 and r.rmse_aligned < 0.8  # the offset of (3, 1) m taken out by the alignment
    assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "gps.dat"), "--rpe"]) == 2
    assert "--rpe applies to a reference trajectory, not to positions" in capsys.readouterr().err
    write_gps(tmp_path / "late.dat", times_ref + 1000.0, fixes)
    assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "late.dat")]) == 2
    err = capsys.readouterr().err
    assert "late.dat: no fix within the estimate's time span" in err and len(err.strip().splitlines()) == 1
