"""probslam.eval: the relations metric of Kümmerle et al. 2009, checked against hand computations
written out with cos / sin, np.interp on unwrapped angles, and the ACES relations file."""

import bz2
import gzip
import math

import numpy as np
import pytest

import probslam as ps
from probslam import eval as ev

TWO_PI = 2.0 * math.pi


def rot(theta):
    """The 2-D rotation matrix, written out."""
    return np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])


# A small trajectory whose last step turns across +-pi (3.0 -> -2.9 is +0.383 rad the short way).
TS = np.array([0.0, 1.0, 2.0, 3.0])
POSES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, math.pi / 2], [1.0, 2.0, 3.0], [-1.0, 2.0, -2.9]])


def test_relations_error_equals_hand_computation():
    refs = np.array([[0.9, 0.1, 1.5], [2.1, 0.9, 1.6], [1.0, 2.0, -3.0], [0.0, 0.0, 0.0]])
    rel = ev.Relations(np.array([0.0, 1.0, 0.0, 2.5]), np.array([1.0, 2.5, 2.0, 3.5]), refs)
    err = ev.relations_error(TS, POSES, rel)
    # Relation 0 (0 -> 1 s): pose 0 is the origin, so d_est = pose 1.
    e0 = rot(1.5).T @ (np.array([1.0, 0.0]) - refs[0, :2])
    # Relation 1 (1 -> 2.5 s): the pose at 2.5 s is midway between poses 2 and 3; its heading is
    # 3.0 + (2 pi - 5.9) / 2, past pi, so one turn less.
    mid_xy, mid_theta = np.array([0.0, 2.0]), 3.0 + 0.5 * (TWO_PI - 5.9) - TWO_PI
    d1 = rot(math.pi / 2).T @ (mid_xy - POSES[1, :2])            # = (2, 1)
    d1_theta = mid_theta - math.pi / 2 + TWO_PI                   # = 1.6208 after wrapping
    e1 = rot(1.6).T @ (d1 - refs[1, :2])
    # Relation 2 (0 -> 2 s): d_est = (1, 2, 3.0) against a reference heading of -3.0: the
    # heading error 6.0 wraps to 6.0 - 2 pi.
    assert np.isclose(d1[0], 2.0) and np.isclose(d1[1], 1.0)
    np.testing.assert_allclose(err.translational, [np.linalg.norm(e0), np.linalg.norm(e1), 0.0], atol=1e-12)
    np.testing.assert_allclose(err.rotational, [math.pi / 2 - 1.5, abs(d1_theta - 1.6), TWO_PI - 6.0], atol=1e-12)
    np.testing.assert_array_equal(err.used, [0, 1, 2])
    assert err.skipped == 1  # relation 3 ends after the trajectory
    assert err.trans_mean == pytest.approx(np.mean(err.translational))
    assert err.trans_sq_mean == pytest.approx((np.linalg.norm(e0) ** 2 + np.linalg.norm(e1) ** 2) / 3)
    assert err.rot_sq_mean_deg2 == pytest.approx(np.mean(np.degrees(err.rotational) ** 2))
    assert err.rot_std_deg == pytest.approx(np.degrees(np.std(err.rotational)))
    assert str(err).startswith("relations 3 (skipped 1): translational ")


def _relations_from(ts, poses, pairs):
    """Exact relations between pose pairs, written out pose by pose."""
    delta = []
    for i, j in pairs:
        xy = rot(poses[i, 2]).T @ (poses[j, :2] - poses[i, :2])
        delta.append([xy[0], xy[1], float(ps.wrap_angle(poses[j, 2] - poses[i, 2]))])
    return ev.Relations(ts[pairs[:, 0]], ts[pairs[:, 1]], np.array(delta))


def test_perfect_trajectory_scores_zero_and_a_moved_pose_its_offset():
    rng = np.random.default_rng(3)
    ts = np.cumsum(rng.uniform(0.1, 1.0, 30))
    poses = np.column_stack([rng.normal(0, 5, (30, 2)), rng.uniform(-np.pi, np.pi, 30)])
    pairs = np.array([(i, j) for i in range(30) for j in range(i + 1, min(i + 4, 30))])
    rel = _relations_from(ts, poses, pairs)
    err = ev.relations_error(ts, poses, rel)
    assert err.skipped == 0 and len(err.used) == len(rel) == len(pairs)
    np.testing.assert_allclose(err.translational, 0.0, atol=1e-12)
    np.testing.assert_allclose(err.rotational, 0.0, atol=1e-12)
    moved = poses.copy()
    moved[10, :2] += [0.3, -0.4]  # 0.5 m, whichever frame it is seen in
    err = ev.relations_error(ts, moved, rel)
    touches = (pairs[:, 0] == 10) | (pairs[:, 1] == 10)
    np.testing.assert_allclose(err.translational, np.where(touches, 0.5, 0.0), atol=1e-12)
    np.testing.assert_allclose(err.rotational, 0.0, atol=1e-12)


def _interp_reference(ts, poses, q):
    """np.interp per component; headings unwrapped first so each step is the shorter way round."""
    x, y = np.interp(q, ts, poses[:, 0]), np.interp(q, ts, poses[:, 1])
    theta = [ps.wrap_angle(t) for t in np.interp(q, ts, np.unwrap(poses[:, 2]))]
    return np.column_stack([x, y, theta])


def test_interpolate_poses_matches_np_interp():
    rng = np.random.default_rng(7)
    ts = np.cumsum(rng.uniform(0.05, 2.0, 50))
    poses = np.column_stack([rng.normal(0, 3, (50, 2)), rng.uniform(-np.pi, np.pi, 50)])
    q = np.concatenate([rng.uniform(ts[0], ts[-1], 200), ts[[0, 7, -1]]])
    got = ev.interpolate_poses(ts, poses, q)
    want = _interp_reference(ts, poses, q)
    np.testing.assert_allclose(got[:, :2], want[:, :2], atol=1e-12)
    np.testing.assert_allclose(np.asarray([ps.wrap_angle(a) for a in got[:, 2] - want[:, 2]]), 0.0, atol=1e-12)
    assert np.all((got[:, 2] > -np.pi) & (got[:, 2] <= np.pi))


def test_interpolate_poses_across_pi_and_repeated_timestamps():
    ts, poses = np.array([0.0, 1.0]), np.array([[0.0, 0.0, 3.0], [1.0, 0.0, -3.0]])
    got = ev.interpolate_poses(ts, poses, [0.25, 0.75])
    step = TWO_PI - 6.0  # the short way from 3.0 to -3.0, through pi
    np.testing.assert_allclose(got, [[0.25, 0.0, 3.0 + 0.25 * step], [0.75, 0.0, 3.0 + 0.75 * step - TWO_PI]])
    np.testing.assert_allclose(got[:, 2], _interp_reference(ts, poses, np.array([0.25, 0.75]))[:, 2])
    # A timestamp shared by two poses: the later pose is used, from and up to it.
    ts = np.array([0.0, 1.0, 1.0, 2.0])
    poses = np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0], [6.0, 0, 0]])
    np.testing.assert_allclose(ev.interpolate_poses(ts, poses, [0.5, 1.0, 1.5])[:, 0], [0.5, 5.0, 5.5])
    assert ev.interpolate_poses(ts[:1], poses[:1], [0.0]).tolist() == [[0.0, 0.0, 0.0]]
    assert ev.interpolate_poses(ts, poses, []).shape == (0, 3)


ACES_FIRST_ROW = [90.239599, 90.719599, 0.422330, -0.000750, 0.017260]


def _aces(shared_data):
    path = shared_data / "laser_2d/aces/aces.relations"
    if not path.is_file():
        pytest.skip(f"{path} not present")
    return path


def test_read_aces_relations(shared_data, tmp_path, recwarn):
    path = _aces(shared_data)
    text = path.read_text()
    rows = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    rel = ev.read_relations(path)
    assert len(rel) == len(rows) == 1279 and rel.skipped_rows == 0 and not recwarn.list
    np.testing.assert_array_equal([rel.t1[0], rel.t2[0], *rel.delta[0]], ACES_FIRST_ROW)
    assert np.all(rel.t2 >= rel.t1)
    for name, opener in (("a.relations.gz", gzip.open), ("a.relations.bz2", bz2.open)):
        with opener(tmp_path / name, "wt") as f:
            f.write(text)
        copy = ev.read_relations(tmp_path / name)
        for a, b in ((copy.t1, rel.t1), (copy.t2, rel.t2), (copy.delta, rel.delta)):
            np.testing.assert_array_equal(a, b)


def test_relations_error_reads_a_path(tmp_path):
    path = tmp_path / "r.relations"
    path.write_text("# t1 t2 x y z roll pitch yaw\n0 1 1 0 0 0 0 1.5707963267948966\n\n2.5 9 0 0 0 0 0 0\n")
    err = ev.relations_error(TS, POSES, str(path))
    assert err.skipped == 1 and err.used.tolist() == [0]
    np.testing.assert_allclose([err.translational[0], err.rotational[0]], 0.0, atol=1e-12)
    assert str(err) == "relations 1 (skipped 1): translational 0.000 +- 0.000 m, rotational 0.00 +- 0.00 deg"


# ------------------------------------------------------------------------------------------
# Bad input


def test_read_relations_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.relations"):
        ev.read_relations(tmp_path / "missing.relations")
    with pytest.raises(ValueError, match="not a regular file"):
        ev.read_relations(tmp_path)
    (tmp_path / "empty.relations").write_text("# only a comment\n\n")
    with pytest.raises(ValueError, match=r"empty\.relations: no valid relation rows \(empty"):
        ev.read_relations(tmp_path / "empty.relations")
    (tmp_path / "garbage.relations").write_bytes(b"hello world\n\xff\xfe 1 2 3\n")
    with pytest.raises(ValueError, match=r"garbage\.relations: no valid relation rows \(first bad line 1:"):
        ev.read_relations(tmp_path / "garbage.relations")
    (tmp_path / "cut.relations.gz").write_bytes(gzip.compress(b"0 1 1 0 0 0 0 0\n" * 50)[:-10])
    with pytest.raises(ValueError, match=r"cut\.relations\.gz: corrupt"):
        ev.read_relations(tmp_path / "cut.relations.gz")


def test_read_relations_skips_and_counts_bad_rows(tmp_path):
    path = tmp_path / "some_bad.relations"
    path.write_text("0 1 1 0 0 0 0 0.1\n"
                    "1 2 1 0 0 0 0\n"           # line 2: 7 fields
                    "2 3 1 0 0 0 0 0.3\n"
                    "# a comment\n"
                    "3 4 x 0 0 0 0 0.4\n"       # line 5: not a number
                    "4 5 1 0 0 0 0 0.5  # trailing comment\n")
    with pytest.warns(UserWarning, match=r"some_bad\.relations: skipped 2 .*lines 2, 5"):
        rel = ev.read_relations(path)
    assert len(rel) == 3 and rel.skipped_rows == 2 and rel.skipped_lines == [2, 5]
    np.testing.assert_array_equal(rel.t1, [0, 2, 4])
    np.testing.assert_array_equal(rel.delta[:, 2], [0.1, 0.3, 0.5])


@pytest.mark.parametrize("row", ["0 1 nan 0 0 0 0 0", "0 1 1 0 0 0 0 inf", "2 1 1 0 0 0 0 0",
                                 "0 1 1_0 0 0 0 0 0", "0 1 1 0 0 0 0 0 9", "0,1,1,0,0,0,0,0"])
def test_read_relations_rejects_each_kind_of_bad_row(tmp_path, row):
    path = tmp_path / "r.relations"
    path.write_text(f"5 6 1 0 0 0 0 0\n{row}\n")
    with pytest.warns(UserWarning, match="skipped 1 .*lines 2"):
        rel = ev.read_relations(path)
    assert len(rel) == 1 and rel.skipped_lines == [2]


GOOD = (TS, POSES, [0.5])
BAD_ARRAYS = [
    ((TS, POSES[:, :2], [0.5]), ValueError, r"poses: expected shape \(N, 3\)"),
    ((TS[:, None], POSES, [0.5]), ValueError, r"timestamps: expected shape"),
    ((TS[:3], POSES, [0.5]), ValueError, r"poses: 4 poses for 3 timestamps"),
    ((TS, POSES, [[0.5]]), ValueError, r"query_times: expected shape"),
    (([], np.zeros((0, 3)), [0.5]), ValueError, r"timestamps: empty"),
    ((np.where(TS == 2.0, np.nan, TS), POSES, [0.5]), ValueError, r"timestamps: contains NaN"),
    ((TS, np.where(POSES == 3.0, np.inf, POSES), [0.5]), ValueError, r"poses: contains NaN or inf"),
    ((TS, POSES, [np.nan]), ValueError, r"query_times: contains NaN"),
    ((TS[::-1], POSES, [0.5]), ValueError, r"timestamps: decrease at index 1"),
    ((TS.astype(str), POSES, [0.5]), TypeError, r"timestamps: expected real numbers"),
    ((TS, [[0, 0, "a"]] * 4, [0.5]), TypeError, r"poses: expected real numbers"),
    ((TS, POSES, [0.5, None]), TypeError, r"query_times: expected real numbers"),
    ((TS, [[0, 0, 0], [1, 1]], [0.5]), ValueError, r"poses: not an array of numbers"),
    ((TS, POSES, [-0.1, 1.0]), ValueError, r"query_times: 1 outside the trajectory span \[0, 3\]"),
]


@pytest.mark.parametrize("args, exc, message", BAD_ARRAYS)
def test_interpolate_poses_bad_arrays(args, exc, message):
    ev.interpolate_poses(*GOOD)  # the good call works
    with pytest.raises(exc, match=message):
        ev.interpolate_poses(*args)


@pytest.mark.parametrize("args, exc, message", [b for b in BAD_ARRAYS if "query_times" not in b[2]])
def test_relations_error_bad_arrays(args, exc, message):
    rel = ev.Relations(np.array([0.0]), np.array([1.0]), np.array([[1.0, 0.0, 1.5]]))
    with pytest.raises(exc, match=message):
        ev.relations_error(args[0], args[1], rel)


def test_relations_error_bad_relations():
    with pytest.raises(ValueError, match=r"none of the 2 relations lies within the trajectory span"):
        ev.relations_error(TS, POSES, ev.Relations(np.array([-2.0, 3.5]), np.array([-1.0, 4.0]), np.zeros((2, 3))))
    with pytest.raises(ValueError, match=r"relations\.delta: expected shape \(1, 3\)"):
        ev.relations_error(TS, POSES, ev.Relations(np.array([0.0]), np.array([1.0]), np.zeros((2, 3))))
    with pytest.raises(ValueError, match=r"relations\.t2: contains NaN"):
        ev.relations_error(TS, POSES, ev.Relations(np.array([0.0]), np.array([np.nan]), np.zeros((1, 3))))
    with pytest.raises(FileNotFoundError):
        ev.relations_error(TS, POSES, "/nonexistent/x.relations")


def test_relative_poses_equal_pose2_between_and_compose_back():
    rng = np.random.default_rng(11)
    a = np.column_stack([rng.normal(0, 5, (40, 2)), rng.uniform(-np.pi, np.pi, 40)])
    b = np.column_stack([rng.normal(0, 5, (40, 2)), rng.uniform(-np.pi, np.pi, 40)])
    got = ev.relative_poses(a, b)
    want = np.array([ps.Pose2.from_array(p).between(ps.Pose2.from_array(q)).as_array() for p, q in zip(a, b)])
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert np.all((got[:, 2] > -np.pi) & (got[:, 2] <= np.pi))
    back = np.array([ps.Pose2.from_array(p).compose(ps.Pose2.from_array(d)).as_array() for p, d in zip(a, got)])
    np.testing.assert_allclose(back[:, :2], b[:, :2], atol=1e-12)
    np.testing.assert_allclose(ps.wrap_angle(back[:, 2] - b[:, 2]), 0.0, atol=1e-12)
    # one pair in, one pose out; a robot at (1, 1) facing +y sees (1, 3) 2 m straight ahead
    np.testing.assert_allclose(ev.relative_poses([1.0, 1.0, np.pi / 2], [1.0, 3.0, np.pi]), [2.0, 0.0, np.pi / 2],
                               atol=1e-12)
    assert ev.relative_poses(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0, 3)


@pytest.mark.parametrize("a, b, exc, message", [
    (np.zeros((4, 2)), np.zeros((4, 3)), ValueError, r"a: expected shape \(N, 3\)"),
    (np.zeros((4, 3)), np.zeros((3, 3)), ValueError, r"b: expected the shape of a"),
    (np.zeros(3), np.zeros((1, 3)), ValueError, r"b: expected the shape of a"),
    (np.zeros(4), np.zeros(4), ValueError, r"a: expected shape \(3\), got \(4,\)"),
    ([0.0, np.nan, 0.0], [0.0, 0.0, 0.0], ValueError, r"a: contains NaN or inf"),
    (np.zeros((2, 3)), np.full((2, 3), np.inf), ValueError, r"b: contains NaN or inf"),
    (["x", "y", "z"], [0.0, 0.0, 0.0], TypeError, r"a: expected real numbers"),
    ([[0, 0, 0], [1, 1]], np.zeros((2, 3)), ValueError, r"a: not an array of numbers"),
])
def test_relative_poses_bad_input(a, b, exc, message):
    with pytest.raises(exc, match=message):
        ev.relative_poses(a, b)


# --- issue 33: hand-built relations checked as the reader checks rows; empty and huge input ---

def test_relations_error_refuses_a_hand_built_relation_with_t2_before_t1():
    """read_relations skips such rows, but a hand-built Relations with one was scored."""
    rel = ev.Relations(np.array([0.5, 2.0, 1.5]), np.array([1.0, 1.0, 1.0]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"relations: 2 rows with t2 < t1 .*first row 1 \(t1 2, t2 1\)"):
        ev.relations_error(TS, POSES, rel)
    np.testing.assert_array_equal(rel.t2, [1.0, 1.0, 1.0])  # the argument is left as it was


def test_relations_error_refuses_empty_relations_by_name():
    with pytest.raises(ValueError, match="relations: empty"):
        ev.relations_error(TS, POSES, ev.Relations(np.zeros(0), np.zeros(0), np.zeros((0, 3))))


@pytest.mark.parametrize("error, covariance, exc, message", [
    (np.zeros(0), np.zeros((0, 0)), ValueError, r"error: expected shape \(\.\.\., n\) with n >= 1"),
    (np.zeros((4, 0)), np.zeros((4, 0, 0)), ValueError, r"error: expected shape \(\.\.\., n\) with n >= 1"),
    (np.float64(1.0), np.ones((1, 1)), ValueError, r"error: expected shape \(\.\.\., n\)"),
    ([[0.1, 0.1], [0.2]], np.eye(2), ValueError, "error: not an array of numbers"),
    (["a", "b"], np.eye(2), TypeError, "error: expected real numbers"),
    (np.zeros(2), [[1, 0], [0, "x"]], TypeError, "covariance: expected real numbers"),
    (np.zeros(2) + 1j, np.eye(2), TypeError, "error: expected real numbers"),
    (np.zeros(2), np.diag([np.nan, 1.0]), ValueError, "covariance: contains NaN or inf"),
    ([1e200, 0.0], np.eye(2), ValueError, "error and covariance: the NEES overflows"),
])
def test_nees_bad_input_names_the_argument(error, covariance, exc, message):
    """nees([], ...) raised numpy's "zero-size array to reduction operation maximum"."""
    with pytest.raises(exc, match=message):
        ev.nees(error, covariance)


def test_nees_of_no_estimates_is_empty():
    assert ev.nees(np.zeros((0, 3)), np.zeros((0, 3, 3))).shape == (0,)


@pytest.mark.parametrize("call, message", [
    (lambda: ev.relative_poses([-1e308, 0, 0], [1e308, 0, 0]), "a and b: the relative poses overflow"),
    (lambda: ev.interpolate_poses([0.0, 1.0], [[-1e308, 0, 0], [1e308, 0, 0]], [0.5]),
     "timestamps and poses: the interpolation overflows"),
    (lambda: ev.relations_error([0.0, 1.0], [[-1e308, 0, 0], [1e308, 0, 0]],
                                ev.Relations(np.array([0.0]), np.array([1.0]), np.zeros((1, 3)))),
     "the relations error overflows"),
    (lambda: ev.relative_poses([0, 0, -1e308], [0, 0, 1e308]), "a and b: the relative poses overflow"),
    (lambda: ev.interpolate_poses([0.0, 1.0], [[0, 0, -1e308], [0, 0, 1e308]], [0.5]),
     "timestamps and poses: the interpolation overflows"),
])
def test_eval_results_are_finite_or_refused(call, message):
    """Coordinates near the largest double gave inf or NaN results."""
    with pytest.raises((ValueError, TypeError), match=message):
        call()
