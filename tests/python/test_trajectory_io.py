"""Trajectory files (probslam.io.trajectory): TUM, KITTI and 't x y theta' round trips, rows
that other tools write (non-planar, comments, bad rows), and evo reading what we write (issue 36:
evo refused 'timestamp x y theta' with "TUM trajectory files must have 8 entries per row")."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from probslam import io
from probslam.io import trajectory as tr

#: The writer prints nine decimals: a round trip is exact to half a unit of the ninth (5e-10),
#: and an angle read back from its quaternion or rotation matrix to a few of those.
ROUND_TRIP_TOLERANCE = 5e-9


def random_trajectory(n=60, seed=0):
    rng = np.random.default_rng(seed)
    times = 1.3e9 + np.cumsum(rng.uniform(0.01, 0.3, n))
    poses = np.column_stack([rng.normal(0, 30, (n, 2)), rng.uniform(-math.pi, math.pi, n)])
    poses[0, 2] = math.pi  # the end of (-pi, pi]: written as qw = 0, read back as pi
    return times, poses


def angle_difference(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


@pytest.mark.parametrize("fmt", tr.TRAJECTORY_FORMATS)
def test_round_trip(tmp_path, fmt):
    times, poses = random_trajectory()
    written = io.write_trajectory(times, poses, tmp_path / f"t.{fmt}", format=fmt)
    assert written[0] == str(tmp_path / f"t.{fmt}")
    assert written[1:] == ([io.kitti_times_path(tmp_path / "t.kitti")] if fmt == "kitti" else [])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read = io.read_trajectory(written[0])  # "auto": told apart by the field count
    assert read.format == fmt and len(read) == len(times)
    assert (read.skipped_rows, read.projected_rows, read.times_from_index) == (0, 0, False)
    np.testing.assert_allclose(read.timestamps, times, rtol=0, atol=ROUND_TRIP_TOLERANCE)
    np.testing.assert_allclose(read.poses[:, :2], poses[:, :2], rtol=0, atol=ROUND_TRIP_TOLERANCE)
    assert np.max(angle_difference(read.poses[:, 2], poses[:, 2])) < ROUND_TRIP_TOLERANCE
    assert np.all(read.poses[:, 2] > -math.pi) and np.all(read.poses[:, 2] <= math.pi)


def test_tum_rows_are_the_planar_pose_with_a_yaw_quaternion(tmp_path):
    io.write_trajectory([1.5, 2.0], [[1.0, 2.0, math.pi / 2], [0.0, -1.0, -math.pi / 3]], tmp_path / "t.tum")
    lines = (tmp_path / "t.tum").read_text().splitlines()
    assert lines[0] == "# timestamp x y z qx qy qz qw"
    row = np.array(lines[1].split(), float)
    np.testing.assert_allclose(row, [1.5, 1, 2, 0, 0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)], atol=1e-9)
    row = np.array(lines[2].split(), float)
    np.testing.assert_allclose(row[6:], [math.sin(-math.pi / 6), math.cos(math.pi / 6)], atol=1e-9)


def test_kitti_rows_are_the_rotation_about_z_and_the_times_beside(tmp_path):
    io.write_trajectory([0.25], [[3.0, 4.0, math.pi / 6]], tmp_path / "k.kitti", format="kitti")
    m = np.loadtxt(tmp_path / "k.kitti").reshape(3, 4)
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    np.testing.assert_allclose(m, [[c, -s, 0, 3], [s, c, 0, 4], [0, 0, 1, 0]], atol=1e-9)
    assert (tmp_path / "k_times.txt").read_text().split() == ["0.250000000"]


def test_kitti_without_times_takes_the_row_index_and_says_so(tmp_path):
    times, poses = random_trajectory(5)
    io.write_trajectory(times, poses, tmp_path / "k.kitti", format="kitti")
    (tmp_path / "k_times.txt").unlink()
    with pytest.warns(UserWarning, match="row index is taken as the time"):
        read = io.read_trajectory(tmp_path / "k.kitti")
    assert read.times_from_index and read.timestamps.tolist() == [0, 1, 2, 3, 4]
    # An explicit times file, and one of the wrong length.
    np.savetxt(tmp_path / "other.txt", times)
    np.testing.assert_allclose(io.read_trajectory(tmp_path / "k.kitti", times_path=tmp_path / "other.txt").timestamps,
                               times)
    np.savetxt(tmp_path / "short.txt", times[:3])
    with pytest.raises(ValueError, match="3 times for the 5 rows"):
        io.read_trajectory(tmp_path / "k.kitti", times_path=tmp_path / "short.txt")


def test_a_non_planar_tum_row_is_read_as_its_projection_and_counted(tmp_path):
    """A 3-D trajectory (a pitch of 0.2 rad, a height): x, y and the yaw, with a warning."""
    yaw, pitch = 0.7, 0.2
    # q = q_z(yaw) * q_y(pitch): the ZYX angles (yaw, pitch, 0).
    q = [-math.sin(yaw / 2) * math.sin(pitch / 2), math.cos(yaw / 2) * math.sin(pitch / 2),
         math.sin(yaw / 2) * math.cos(pitch / 2), math.cos(yaw / 2) * math.cos(pitch / 2)]
    text = ("# from a 3-D pipeline\n"
            f"1.0 1 2 0.5 {q[0]:.12f} {q[1]:.12f} {q[2]:.12f} {q[3]:.12f}\n"
            "2.0 3 4 0 0 0 0 1\n")
    (tmp_path / "3d.tum").write_text(text)
    with pytest.warns(UserWarning, match="1 of 2 rows are not planar"):
        read = io.read_trajectory(tmp_path / "3d.tum")
    assert read.projected_rows == 1
    np.testing.assert_allclose(read.poses, [[1, 2, yaw], [3, 4, 0]], atol=1e-12)


def test_bad_rows_are_skipped_and_counted(tmp_path):
    text = ("# t x y z qx qy qz qw\n"
            "\n"
            "1.0 0 0 0 0 0 0 1\n"
            "2.0 1 0 0 0 0 0\n"            # 7 fields
            "3.0 2 0 0 0 0 0 1   # a comment after a row\n"
            "4.0 nan 0 0 0 0 0 1\n"        # not finite
            "5.0 4 0 0 0 0 0.5 0.5\n"      # not a unit quaternion
            "6.0 five 0 0 0 0 0 1\n"       # a word
            "7.0 6 0 0 0 0 0 1\n")
    (tmp_path / "bad.tum").write_text(text)
    with pytest.warns(UserWarning, match=r"skipped 4 unreadable trajectory rows \(lines 4, 6, 7, 8; first: "
                                         r"expected 8 fields, got 7\)"):
        read = io.read_trajectory(tmp_path / "bad.tum")
    assert read.skipped_rows == 4 and read.skipped_lines == [4, 6, 7, 8]
    assert read.timestamps.tolist() == [1.0, 3.0, 7.0] and read.poses[:, 0].tolist() == [0.0, 2.0, 6.0]


def test_files_that_hold_no_trajectory_name_themselves(tmp_path):
    (tmp_path / "empty.tum").write_text("# nothing\n")
    with pytest.raises(ValueError, match=r"empty\.tum: no valid trajectory rows \(empty or only comments\)"):
        io.read_trajectory(tmp_path / "empty.tum")
    (tmp_path / "words.tum").write_text("hello world\n")
    with pytest.raises(ValueError, match=r"words\.tum: no valid trajectory rows \(first bad line 1"):
        io.read_trajectory(tmp_path / "words.tum")
    with pytest.raises(FileNotFoundError):
        io.read_trajectory(tmp_path / "missing.tum")
    with pytest.raises(ValueError, match="not a regular file"):
        io.read_trajectory(tmp_path)
    io.write_trajectory([0.0], [[0, 0, 0]], tmp_path / "x.tum")
    with pytest.raises(ValueError, match="format must be 'auto' or one of"):
        io.read_trajectory(tmp_path / "x.tum", format="csv")
    with pytest.raises(ValueError, match="no valid trajectory rows"):  # a TUM file read as KITTI
        io.read_trajectory(tmp_path / "x.tum", format="kitti")


def test_decreasing_times_are_kept_with_a_warning(tmp_path):
    io.write_trajectory([2.0, 1.0, 3.0], np.zeros((3, 3)), tmp_path / "jump.tum")
    with pytest.warns(UserWarning, match="timestamps decrease 1 times, first at line 3"):
        read = io.read_trajectory(tmp_path / "jump.tum")
    assert read.timestamps.tolist() == [2.0, 1.0, 3.0]


def test_writer_arguments_are_checked_by_name(tmp_path):
    with pytest.raises(ValueError, match="poses: expected shape"):
        io.write_trajectory(np.arange(3.0), np.zeros((2, 3)), tmp_path / "t.tum")
    with pytest.raises(ValueError, match="timestamps: contains NaN"):
        io.write_trajectory([np.nan], np.zeros((1, 3)), tmp_path / "t.tum")
    with pytest.raises(TypeError, match="path: expected a file path"):
        io.write_trajectory([0.0], np.zeros((1, 3)), 3)
    with pytest.raises(ValueError, match="format must be one of"):
        io.write_trajectory([0.0], np.zeros((1, 3)), tmp_path / "t.tum", format="g2o")
    assert not (tmp_path / "t.tum").exists()


# --- evo reads what we write ----------------------------------------------------------------------

def _evo_file_interface():
    pytest.importorskip("evo", reason="evo (a test-only dependency: pip install evo) is not installed")
    from evo.tools import file_interface

    return file_interface


def test_evo_reads_our_tum_and_kitti_files(tmp_path):
    file_interface = _evo_file_interface()
    times, poses = random_trajectory(40, seed=4)
    io.write_trajectory(times, poses, tmp_path / "t.tum")
    io.write_trajectory(times, poses, tmp_path / "t.kitti", format="kitti")
    for evo_traj in (file_interface.read_tum_trajectory_file(str(tmp_path / "t.tum")),
                     file_interface.read_kitti_poses_file(str(tmp_path / "t.kitti"))):
        assert evo_traj.num_poses == len(times)
        se3 = np.array(evo_traj.poses_se3)
        np.testing.assert_allclose(se3[:, :2, 3], poses[:, :2], rtol=0, atol=ROUND_TRIP_TOLERANCE)
        assert np.max(np.abs(se3[:, 2, 3])) == 0.0  # planar: z = 0
        yaw = np.arctan2(se3[:, 1, 0], se3[:, 0, 0])
        assert np.max(angle_difference(yaw, poses[:, 2])) < ROUND_TRIP_TOLERANCE
        np.testing.assert_allclose(se3[:, 2, 2], 1.0, atol=1e-12)  # no tilt
    evo_tum = file_interface.read_tum_trajectory_file(str(tmp_path / "t.tum"))
    np.testing.assert_allclose(evo_tum.timestamps, times, rtol=0, atol=ROUND_TRIP_TOLERANCE)


def test_we_read_what_evo_writes(tmp_path):
    """A TUM file written by evo (its own layout and precision) reads back as the same poses."""
    file_interface = _evo_file_interface()
    times, poses = random_trajectory(30, seed=5)
    io.write_trajectory(times, poses, tmp_path / "ours.tum")
    evo_traj = file_interface.read_tum_trajectory_file(str(tmp_path / "ours.tum"))
    file_interface.write_tum_trajectory_file(str(tmp_path / "evo.tum"), evo_traj)
    read = io.read_trajectory(tmp_path / "evo.tum")
    assert read.format == "tum" and read.projected_rows == 0 and read.skipped_rows == 0
    np.testing.assert_allclose(read.poses[:, :2], poses[:, :2], rtol=0, atol=ROUND_TRIP_TOLERANCE)
    assert np.max(angle_difference(read.poses[:, 2], poses[:, 2])) < ROUND_TRIP_TOLERANCE
