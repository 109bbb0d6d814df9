"""ROS bags in (``io.read_rosbag``) and out (``io.write_rosbag``): each reader path against poses
and offsets composed independently with ``probslam.Pose2``, the writers' round trip in the three
formats, SLAM on a bag against SLAM on the log it came from, the real bags, and the CLI."""

import dataclasses
import importlib.util
import math
import os
import shutil
import sys

import numpy as np
import pytest

import probslam as ps
from probslam import cli, io
from probslam.io import rosbag_writer

needs_rosbags = pytest.mark.skipif(importlib.util.find_spec("rosbags") is None,
                                   reason="rosbags is not installed (pip install rosbags)")

#: LaserScan angles are float32: what a bag holds of a log's start angle and step.
F32 = lambda a: np.asarray(a, dtype=np.float32).astype(float)  # noqa: E731
#: A heading written as a quaternion (sin / cos of the half angle) and read back with atan2 comes
#: back within an ulp or two of pi (4.4e-16); x, y and timestamps come back exactly.
HEADING_ROUND_TRIP_TOL = 1e-15
#: SLAM on a bag against SLAM on its log (angles as float32, as the bag holds them): the only
#: difference in the input is the heading's last bit, which the matcher and the optimiser carried
#: to 1e-14 m here; 1e-9 leaves a wide margin and would still catch any real difference.
SLAM_MATCH_TOL = 1e-9

INTEL_RAW = "intel_raw_loop.log.gz"
DEMO_BAG = "rosbags/ccny_laser_scan_matcher_demo/demo.bag"
STATIONARY_BAG = "rosbags/leg_tracker_stationary/demo_stationary_simple_environment.bag"


def _suffix(fmt):
    return ".bag" if fmt == "rosbag1" else ""


@pytest.fixture(scope="module")
def raw_log():
    return io.read_carmen_log(ps.data.path(INTEL_RAW))


def _compose_all(poses, offset):
    """pose (+) offset row by row with the bindings' Pose2 (independent of the reader's numpy)."""
    off = ps.Pose2(*offset)
    return np.array([list(_pose_tuple(ps.Pose2(*p).compose(off))) for p in poses])


def _pose_tuple(p):
    return (p.x, p.y, p.theta)


def _headings_close(a, b, tol):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))).max() <= tol


# --- hand-built bags -------------------------------------------------------------------------------

class _Bag:
    """A ROS 1 bag written message by message with rosbags' writer, for the reader's corner cases."""

    def __init__(self, path):
        from rosbags.rosbag1 import Writer
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        self.store = get_typestore(Stores.ROS1_NOETIC)
        self.store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
        self.build = rosbag_writer._Messages(self.store)
        self.writer = Writer(path)
        self.writer.open()
        self.connections = {}

    def write(self, topic, msgtype, t, msg=None, raw=None):
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=self.store)
        data = raw if raw is not None else self.store.serialize_ros1(msg, msgtype)
        self.writer.write(self.connections[topic], int(t * 1e9), data)

    def scan(self, topic, t, ranges, frame="laser", start=-1.5, step=0.01, range_max=10.0, range_min=0.1):
        msg = self.build.scan(self.build.header(int(t * 1e9), frame), np.asarray(ranges, float), start, step, range_max)
        msg = dataclasses.replace(msg, range_min=range_min)
        self.write(topic, "sensor_msgs/msg/LaserScan", t, msg)

    def tf(self, t, parent, child, pose, static=False):
        msg = self.build.tf([self.build.transform(self.build.header(int(t * 1e9), parent), child, pose)])
        self.write("/tf_static" if static else "/tf", "tf2_msgs/msg/TFMessage", t, msg)

    def odometry(self, topic, t, pose, frame="odom", child="base_link"):
        msg = self.build.odometry(self.build.header(int(t * 1e9), frame), child, pose)
        self.write(topic, "nav_msgs/msg/Odometry", t, msg)

    def close(self):
        self.writer.close()


def _moving(t):
    """A smooth planar path: the robot pose at time t (s)."""
    return np.array([0.5 * t, 0.2 * math.sin(t), 0.3 * t - 0.1])


def _scan_with_tf(path, slash, fixed_on_tf=False):
    """Scans at 1..5 s; odom -> base_footprint moving (tf at 0.5 s steps), base_footprint ->
    base_link and base_link -> laser fixed (in tf_static, or repeated on /tf as ROS 1 bags from
    before tf_static have them); frame ids with or without a leading slash."""
    s = "/" if slash else ""
    bag = _Bag(path)
    for k in range(13):
        t = 0.5 * k
        if k == 0 or fixed_on_tf:
            bag.tf(t, s + "base_footprint", s + "base_link", (0.1, 0.0, 0.0), static=not fixed_on_tf)
            bag.tf(t, s + "base_link", s + "laser", (0.2, -0.05, 0.3), static=not fixed_on_tf)
        bag.tf(t, s + "odom", s + "base_footprint", _moving(t))
        if 1 <= t <= 5 and t == int(t):
            bag.scan("/scan", t + 1e-3, [1.0, 2.0, 3.0], frame=s + "laser")
    bag.close()


# --- reader paths ----------------------------------------------------------------------------------

@needs_rosbags
@pytest.mark.parametrize("slash,fixed_on_tf", [(False, False), (True, False), (True, True)],
                         ids=["tf2 frames", "leading slashes", "fixed transforms on /tf"])
def test_tf_chain_through_an_intermediate_frame(tmp_path, slash, fixed_on_tf):
    path = tmp_path / "tf.bag"
    _scan_with_tf(path, slash, fixed_on_tf)
    log = io.read_rosbag(path)
    t = log.scans.timestamps
    np.testing.assert_allclose(t, [1.001, 2.001, 3.001, 4.001, 5.001], atol=1e-9)
    # Reference: the tf messages interpolated linearly between their 0.5 s neighbours (the
    # reader's interpolation), composed with Pose2 along odom -> base_footprint -> base_link -> laser.
    lo = np.floor(t / 0.5) * 0.5
    frac = (t - lo) / 0.5
    robot = np.array([_moving(a) + f * (_moving(a + 0.5) - _moving(a)) for a, f in zip(lo, frac)])
    np.testing.assert_allclose(log.scans.robot_poses, robot, atol=1e-12)
    base_to_laser = _pose_tuple(ps.Pose2(0.1, 0, 0).compose(ps.Pose2(0.2, -0.05, 0.3)))
    np.testing.assert_allclose(log.scans.laser_poses, _compose_all(robot, base_to_laser), atol=1e-12)
    assert log.pose_source == "tf odom->base_footprint"
    assert log.laser_offset_source == "tf_static"
    np.testing.assert_allclose(log.laser_offset, base_to_laser, atol=1e-15)
    assert len(log.odometry.timestamps) == 13
    np.testing.assert_allclose(log.odometry.poses, [_moving(0.5 * k) for k in range(13)], atol=1e-15)


@needs_rosbags
def test_tf_frames_named(tmp_path):
    path = tmp_path / "tf.bag"
    _scan_with_tf(path, slash=True)
    # base_link as the robot's frame: the pose then includes the static footprint -> base_link.
    log = io.read_rosbag(path, odom_frame="/odom", base_frame="base_link")
    auto = io.read_rosbag(path)
    np.testing.assert_allclose(log.scans.robot_poses, _compose_all(auto.scans.robot_poses, (0.1, 0, 0)), atol=1e-12)
    np.testing.assert_allclose(log.scans.laser_poses, auto.scans.laser_poses, atol=1e-12)
    np.testing.assert_allclose(log.laser_offset, (0.2, -0.05, 0.3), atol=1e-15)
    with pytest.raises(ValueError, match="base_frame: no tf chain from odom to nowhere"):
        io.read_rosbag(path, base_frame="nowhere")


@needs_rosbags
def test_topics_found_and_named(tmp_path, raw_log):
    path = tmp_path / "a.bag"
    io.write_rosbag(raw_log, path)
    found = io.read_rosbag(path)
    named = io.read_rosbag(path, scan_topic="/scan", odom_topic="/odom")
    assert found.scan_topic == named.scan_topic == "/scan"
    assert found.pose_source == named.pose_source == "odometry /odom"
    np.testing.assert_array_equal(found.scans.laser_poses, named.scans.laser_poses)
    assert found.topics == {"/scan": "sensor_msgs/msg/LaserScan", "/odom": "nav_msgs/msg/Odometry",
                            "/tf_static": "tf2_msgs/msg/TFMessage"}


@needs_rosbags
def test_topic_errors(tmp_path, raw_log):
    path = tmp_path / "two.bag"
    bag = _Bag(path)
    for t in (1.0, 2.0):
        bag.scan("/front", t, [1.0, 2.0])
        bag.scan("/rear", t, [1.0, 2.0])
        bag.odometry("/odom", t, (t, 0, 0))
    bag.close()
    with pytest.raises(ValueError, match=r"several sensor_msgs/LaserScan topics: /front, /rear; name one with scan_topic"):
        io.read_rosbag(path)
    assert len(io.read_rosbag(path, scan_topic="/rear").scans) == 2
    with pytest.raises(ValueError, match=r"scan_topic: no topic '/scan' in the bag \(topics: /front \[sensor_msgs"):
        io.read_rosbag(path, scan_topic="/scan")
    with pytest.raises(ValueError, match=r"scan_topic: topic '/odom' has message type nav_msgs/msg/Odometry, "
                                         r"expected sensor_msgs/msg/LaserScan"):
        io.read_rosbag(path, scan_topic="/odom")
    with pytest.raises(ValueError, match=r"odom_topic: topic '/front' has message type sensor_msgs/msg/LaserScan"):
        io.read_rosbag(path, scan_topic="/front", odom_topic="/front")
    with pytest.raises(ValueError, match=r"pose_topic: no topic '/pose'"):
        io.read_rosbag(path, scan_topic="/front", pose_topic="/pose")
    with pytest.raises(TypeError, match="scan_topic: expected a topic name"):
        io.read_rosbag(path, scan_topic=3)
    with pytest.raises(ValueError, match=r"laser_offset: expected \(x, y, theta\)"):
        io.read_rosbag(path, laser_offset=(1, 2))


@needs_rosbags
def test_empty_and_scanless_bags(tmp_path):
    empty = tmp_path / "empty.bag"
    bag = _Bag(empty)
    bag.connections["/scan"] = bag.writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=bag.store)
    bag.odometry("/odom", 1.0, (0, 0, 0))
    bag.close()
    with pytest.raises(ValueError, match=r"empty\.bag: topic /scan holds no readable LaserScan"):
        io.read_rosbag(empty)
    none = tmp_path / "none.bag"
    bag = _Bag(none)
    bag.odometry("/odom", 1.0, (0, 0, 0))
    bag.close()
    with pytest.raises(ValueError, match=r"no sensor_msgs/LaserScan topic .* \(topics: /odom \[nav_msgs/msg/Odometry\]\)"):
        io.read_rosbag(none)


@needs_rosbags
def test_laser_offset_from_tf_static_or_given(tmp_path, raw_log):
    offset = (0.12, -0.03, 0.05)
    scans = dataclasses.replace(raw_log.scans, laser_poses=_compose_all(raw_log.scans.robot_poses, offset))
    with_static, without = tmp_path / "static.bag", tmp_path / "plain.bag"
    io.write_rosbag(scans, with_static)
    io.write_rosbag(scans, without, laser_offset_in_tf_static=False)
    a = io.read_rosbag(with_static)
    b = io.read_rosbag(without, laser_offset=offset)
    c = io.read_rosbag(without)
    assert (a.laser_offset_source, b.laser_offset_source, c.laser_offset_source) == ("tf_static", "given", "none")
    np.testing.assert_allclose(a.laser_offset, offset, atol=1e-12)
    for log in (a, b):
        np.testing.assert_allclose(log.scans.laser_poses[:, :2], scans.laser_poses[:, :2], atol=1e-12)
        assert _headings_close(log.scans.laser_poses[:, 2], scans.laser_poses[:, 2], 1e-12)
    np.testing.assert_array_equal(c.scans.laser_poses, c.scans.robot_poses)
    # The given offset wins over tf_static.
    d = io.read_rosbag(with_static, laser_offset=(0, 0, 0))
    np.testing.assert_array_equal(d.scans.laser_poses, d.scans.robot_poses)


@needs_rosbags
def test_odometry_and_tf_give_the_same_poses(tmp_path, raw_log):
    odo, tf = tmp_path / "odo.bag", tmp_path / "tf.bag"
    io.write_rosbag(raw_log, odo, odometry="odometry")
    io.write_rosbag(raw_log, tf, odometry="tf")
    a, b = io.read_rosbag(odo), io.read_rosbag(tf)
    assert b.pose_source == "tf odom->base_link"
    for name in ("ranges", "laser_poses", "robot_poses", "timestamps", "start_angles", "max_ranges"):
        np.testing.assert_array_equal(getattr(a.scans, name), getattr(b.scans, name))
    np.testing.assert_array_equal(a.odometry.poses, b.odometry.poses)


@needs_rosbags
def test_out_of_order_stamps(tmp_path, raw_log):
    """The Intel excerpt's stamps go back 34 times while its path runs smoothly in file order: the
    scans keep their recording order (as rosbag play delivers them), counted; or sorted on request."""
    path = tmp_path / "a.bag"
    io.write_rosbag(raw_log, path)
    t = raw_log.scans.timestamps
    log = io.read_rosbag(path)
    assert log.backward_stamps == np.count_nonzero(np.diff(t) < 0) == 34
    np.testing.assert_array_equal(log.scans.timestamps, t)
    ordered = io.read_rosbag(path, sort_by_stamp=True)
    order = np.argsort(t, kind="stable")
    np.testing.assert_array_equal(ordered.scans.timestamps, t[order])
    np.testing.assert_array_equal(ordered.scans.ranges, log.scans.ranges[order])
    np.testing.assert_array_equal(ordered.scans.robot_poses, log.scans.robot_poses[order])


@needs_rosbags
def test_messages_recorded_out_of_order_are_sorted(tmp_path):
    path = tmp_path / "late.bag"
    bag = _Bag(path)
    for t in (1.0, 3.0, 2.0, 4.0):  # the third written late
        bag.odometry("/odom", t, _moving(t))
        bag.scan("/scan", t, [t, 1.0])
    bag.close()
    log = io.read_rosbag(path)
    np.testing.assert_array_equal(log.scans.timestamps, [1, 2, 3, 4])
    np.testing.assert_array_equal(log.scans.ranges[:, 0], [1, 2, 3, 4])
    np.testing.assert_allclose(log.scans.robot_poses, [_moving(t) for t in (1, 2, 3, 4)], atol=1e-15)


@needs_rosbags
def test_a_corrupt_message_is_skipped_and_counted(tmp_path):
    path = tmp_path / "corrupt.bag"
    bag = _Bag(path)
    for k, t in enumerate(np.arange(1.0, 6.0)):
        bag.odometry("/odom", t, _moving(t))
        if k == 2:
            bag.write("/scan", "sensor_msgs/msg/LaserScan", t, raw=b"\x01\x02\x03")  # cut off mid-write
        else:
            bag.scan("/scan", t, [1.0, 2.0])
    bag.close()
    with pytest.warns(UserWarning, match=r"corrupt\.bag: skipped 1 message \(first: message 6: /scan: "):
        log = io.read_rosbag(path)
    assert len(log.scans) == 4 and log.skipped_rows == 1
    assert log.skipped_lines == [6] and log.skipped_reasons[0].startswith("/scan: ")
    np.testing.assert_array_equal(log.scans.timestamps, [1, 2, 4, 5])


@needs_rosbags
def test_scans_outside_the_odometry_are_skipped(tmp_path):
    path = tmp_path / "short_odometry.bag"
    bag = _Bag(path)
    for t in (1.0, 2.0, 3.0, 4.0):
        bag.scan("/scan", t, [1.0, 2.0])
        if 2 <= t <= 3:
            bag.odometry("/odom", t, _moving(t))
    bag.close()
    with pytest.warns(UserWarning, match="skipped 2 messages .*outside the poses' time span"):
        log = io.read_rosbag(path)
    np.testing.assert_array_equal(log.scans.timestamps, [2, 3])


@needs_rosbags
def test_no_return_and_too_close_readings(tmp_path):
    """REP 117: +inf / NaN / beyond range_max are no return (the value range_max, as a CARMEN
    log's max reading), -inf / below range_min no reading (NaN); ranges in mm come back exact."""
    path = tmp_path / "r.bag"
    bag = _Bag(path)
    bag.scan("/scan", 1.0, [1.07, np.inf, np.nan, 12.0, 0.05, -np.inf, 2.518], range_max=10.0, range_min=0.1)
    bag.scan("/scan", 2.0, [1.0, 2.0], range_max=10.0, range_min=0.1)
    bag.close()
    s = io.read_rosbag(path).scans
    np.testing.assert_array_equal(s.ranges[0], [1.07, 10, 10, 10, np.nan, np.nan, 2.518])
    np.testing.assert_array_equal(s.ranges[1], [1.0, 2.0] + [np.nan] * 5)
    np.testing.assert_array_equal(s.num_beams, [7, 2])
    np.testing.assert_array_equal(s.max_ranges, [10.0, 10.0])
    np.testing.assert_array_equal(s.start_angles, F32([-1.5, -1.5]))
    assert s.no_return_range() == 10.0
    assert not io.has_odometry(s)


@needs_rosbags
@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
def test_truncated_index_is_read_by_walking_the_chunks(tmp_path, raw_log, monkeypatch, compression):
    from rosbags.rosbag1 import Writer

    if compression != "none":
        plain_open = Writer.open

        def compressed_open(self):
            self.set_compression(Writer.CompressionFormat[compression.upper()])
            plain_open(self)

        monkeypatch.setattr(Writer, "open", compressed_open)
    path = tmp_path / "a.bag"
    io.write_rosbag(raw_log, path)
    monkeypatch.undo()
    whole = io.read_rosbag(path)
    data = path.read_bytes()
    index_pos = int.from_bytes(data[data.index(b"index_pos=") + 10:][:8], "little")
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[:index_pos])  # the index (connections, chunk infos) lost
    log = io.read_rosbag(cut)
    assert "read by walking its chunks" in log.index_note
    for name in ("ranges", "laser_poses", "timestamps"):
        np.testing.assert_array_equal(getattr(log.scans, name), getattr(whole.scans, name))


@needs_rosbags
def test_rosbag2_storage_file_is_read_through_its_folder(tmp_path, raw_log):
    folder = tmp_path / "ros2"
    io.write_rosbag(raw_log, folder, format="rosbag2")
    db3 = next(folder.glob("*.db3"))
    a, b = io.read_rosbag(folder), io.read_rosbag(db3)
    np.testing.assert_array_equal(a.scans.laser_poses, b.scans.laser_poses)
    alone = tmp_path / "alone.db3"
    shutil.copy(db3, alone)
    with pytest.raises(ValueError, match="read with its bag folder's metadata.yaml"):
        io.read_rosbag(alone)
    with pytest.raises(FileNotFoundError):
        io.read_rosbag(tmp_path / "missing.bag")


def test_without_rosbags_the_error_says_how_to_install(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "rosbags", None)  # import rosbags now raises ImportError
    bag = tmp_path / "a.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n")
    with pytest.raises(ImportError, match="pip install rosbags"):
        io.read_rosbag(bag)
    assert cli.main(["slam", str(bag), "-o", str(tmp_path / "s"), "--no-progress"]) == 2
    assert "pip install rosbags" in capsys.readouterr().err


def test_import_does_not_need_rosbags():
    import subprocess

    code = "import sys; sys.modules['rosbags'] = None; import probslam, probslam.io; print('ok')"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)))
    assert run.stdout.strip() == "ok", run.stderr


# --- writers ---------------------------------------------------------------------------------------

@needs_rosbags
@pytest.mark.parametrize("odometry", ["odometry", "tf"])
@pytest.mark.parametrize("fmt", list(rosbag_writer.FORMATS))
def test_round_trip(tmp_path, raw_log, fmt, odometry):
    path = tmp_path / f"intel{_suffix(fmt)}"
    io.write_rosbag(raw_log, path, format=fmt, odometry=odometry)
    log = io.read_rosbag(path)
    s, r = raw_log.scans, log.scans
    # Ranges: the log's (float32 in the message, widened through their shortest decimal).
    np.testing.assert_array_equal(r.ranges, s.ranges)
    np.testing.assert_array_equal(r.num_beams, s.num_beams)
    np.testing.assert_array_equal(r.timestamps, s.timestamps)
    np.testing.assert_array_equal(r.start_angles, F32(s.start_angles))
    np.testing.assert_array_equal(r.angular_resolutions, F32(s.angular_resolutions))
    np.testing.assert_array_equal(r.max_ranges, np.full(len(s), s.no_return_range()))
    for got, want in ((r.robot_poses, s.robot_poses), (r.laser_poses, s.laser_poses)):
        np.testing.assert_array_equal(got[:, :2], want[:, :2])
        assert _headings_close(got[:, 2], want[:, 2], HEADING_ROUND_TRIP_TOL)
    assert log.skipped_rows == 0 and len(r) == 630


@needs_rosbags
def test_writer_errors(tmp_path, raw_log):
    path = tmp_path / "a.bag"
    io.write_rosbag(raw_log, path)
    with pytest.raises(FileExistsError, match="exists already"):
        io.write_rosbag(raw_log, path)
    with pytest.raises(ValueError, match="format must be one of"):
        io.write_rosbag(raw_log, tmp_path / "b", format="bag3")
    with pytest.raises(TypeError, match="log: expected a CarmenLog or LaserScans"):
        io.write_rosbag("log.txt", tmp_path / "c.bag")
    shifted = raw_log.scans.laser_poses.copy()
    shifted[-1, 0] += 0.5  # one scan's laser half a metre off: no single offset fits
    wobbly = dataclasses.replace(raw_log.scans, laser_poses=shifted)
    with pytest.raises(ValueError, match="laser's offset from the robot pose varies"):
        io.write_rosbag(wobbly, tmp_path / "d.bag")
    assert not (tmp_path / "d.bag").exists()
    io.write_rosbag(wobbly, tmp_path / "e.bag", poses="laser")
    np.testing.assert_array_equal(io.read_rosbag(tmp_path / "e.bag").scans.laser_poses[:, :2],
                                  wobbly.laser_poses[:, :2])


# --- SLAM and mapping on bags ----------------------------------------------------------------------

@pytest.mark.slow  # a whole log through SLAM twice
@needs_rosbags
@pytest.mark.parametrize("fmt", ["rosbag1", "mcap"])
def test_slam_on_the_bag_equals_slam_on_the_log(tmp_path, raw_log, fmt):
    """The bag carries the log's ranges, stamps and poses exactly, and its beam angles as float32:
    SLAM on the bag is SLAM on the log with those angles, to the headings' last bit."""
    path = tmp_path / f"intel{_suffix(fmt)}"
    io.write_rosbag(raw_log, path, format=fmt, odometry="tf" if fmt == "mcap" else "odometry")
    s = raw_log.scans
    as_held = dataclasses.replace(s, start_angles=F32(s.start_angles), angular_resolutions=F32(s.angular_resolutions))
    on_log = ps.run_slam(as_held, progress=False)
    on_bag = ps.run_slam(str(path), progress=False)
    np.testing.assert_array_equal(on_bag.timestamps, on_log.timestamps)
    assert np.abs(ps.eval.relative_poses(on_log.poses, on_bag.poses)).max() <= SLAM_MATCH_TOL
    assert on_bag.summary.submaps == on_log.summary.submaps and on_bag.odometry


def _real_bag(shared_data, name):
    """The real bag ``name`` of the shared data as read_rosbag reads it (skips when absent)."""
    path = shared_data / name
    if not path.exists():
        pytest.skip(f"{path} not present")
    return io.read_rosbag(path)


@needs_rosbags
def test_real_bag_with_a_broken_index(shared_data):
    log = _real_bag(shared_data, DEMO_BAG)
    assert len(log.scans) == 360 and log.skipped_rows == 0
    assert "AssertionError" in log.index_note
    assert log.scans.ranges.shape == (360, 681) and log.pose_source == "none"
    np.testing.assert_allclose(log.scans.start_angles, -2.0862, atol=1e-4)
    np.testing.assert_allclose(log.scans.max_ranges, 5.6)
    assert not io.has_odometry(log.scans)
    span = log.scans.timestamps[-1] - log.scans.timestamps[0]
    assert 35 < span < 37


@needs_rosbags
def test_real_stationary_bag(shared_data):
    log = _real_bag(shared_data, STATIONARY_BAG)
    assert len(log.scans) == 1265 and log.index_note == "" and log.skipped_rows == 0
    assert log.scans.ranges.shape == (1265, 512)
    assert np.all(np.diff(log.scans.timestamps) > 0)
    # inf readings (nothing within 5.6 m) are the no-return value.
    assert np.count_nonzero(log.scans.ranges == 5.6) > 0 and np.nanmax(log.scans.ranges) == 5.6


#: A robot that stands still, mapped by scan matching alone while people walk past: its estimate
#: within one cell of the map (0.05 m) of where it started, and its heading within 1 deg (0.1 m,
#: two cells, at the laser's 5.6 m). Measured: 0.036 m and 0.67 deg at the worst scan.
STANDING_POSITION_TOL, STANDING_HEADING_TOL = 0.05, math.radians(1.0)


@pytest.mark.slow  # 1265 scans of 512 beams through SLAM, about 10 s
@needs_rosbags
def test_slam_keeps_a_standing_robot_still_among_walking_people(shared_data):
    """A real bag the library was not developed on, with a truth it states: the robot does not
    move (leg_tracker's demo), the bag has no odometry, and people walk through the scans."""
    log = _real_bag(shared_data, STATIONARY_BAG)
    result = ps.run_slam(log.scans, progress=False)
    assert len(result.poses) == 1265 and not result.odometry
    assert np.hypot(result.poses[:, 0], result.poses[:, 1]).max() <= STANDING_POSITION_TOL
    assert np.abs(result.poses[:, 2]).max() <= STANDING_HEADING_TOL


# --- command line ----------------------------------------------------------------------------------

@pytest.mark.slow  # a whole log through SLAM twice
@needs_rosbags
def test_cli_slam_and_map_on_bags(tmp_path, raw_log, capsys):
    raw = tmp_path / "raw.bag"
    io.write_rosbag(raw_log, raw)
    assert cli.main(["slam", str(raw), "-o", str(tmp_path / "s"), "--no-progress", "--no-plot"]) == 0
    out = capsys.readouterr().out
    assert "bag:           scans from /scan; poses from odometry /odom" in out and "34 scans stamped" in out
    assert (tmp_path / "s.yaml").exists() and (tmp_path / "s_trajectory.tum").exists()
    corrected = io.read_carmen_log(ps.data.path("intel_excerpt.log.gz"))
    folder = tmp_path / "corrected"
    io.write_rosbag(corrected, folder, format="mcap", pose_topic="/pose")
    assert cli.main(["map", str(folder), "--pose-topic", "/pose", "-o", str(tmp_path / "m"), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "poses from poses /pose" in out and "scans:         180" in out
    c = corrected.scans
    as_held = dataclasses.replace(c, start_angles=F32(c.start_angles), angular_resolutions=F32(c.angular_resolutions))
    expected = ps.map_laser_log(as_held, progress=False).grid
    got = io.load_ros_map(tmp_path / "m.yaml")
    # The headings' last bits (HEADING_ROUND_TRIP_TOL) move the map's origin by about 1e-15 m.
    assert (got.width, got.height) == (expected.width, expected.height)
    np.testing.assert_allclose(got.origin, expected.origin, atol=SLAM_MATCH_TOL)
    # The map as saved (map_server's three classes) is the one of the log as the bag holds it.
    classes = lambda g: np.digitize(g.probability(), [0.196, 0.65])  # noqa: E731
    np.testing.assert_array_equal(classes(got), classes(expected))


@needs_rosbags
def test_cli_bag_errors_exit_2(tmp_path, raw_log, capsys):
    raw = tmp_path / "raw.bag"
    io.write_rosbag(raw_log, raw)
    out = str(tmp_path / "s")
    assert cli.main(["slam", str(raw), "--scan-topic", "/front", "-o", out, "--no-progress"]) == 2
    assert "no topic '/front'" in capsys.readouterr().err
    assert cli.main(["map", str(raw), "--pose-topic", "/scan", "-o", out, "--no-progress"]) == 2
    assert "topic '/scan' has message type sensor_msgs/msg/LaserScan" in capsys.readouterr().err
    assert cli.main(["slam", ps.data.path(INTEL_RAW), "--odom-topic", "/odom", "-o", out]) == 2
    assert "--odom-topic applies to ROS bags" in capsys.readouterr().err
    assert cli.main(["slam", str(raw), "--laser-offset", "0", "nan", "0", "-o", out]) == 2
    assert "--laser-offset: must contain only finite values" in capsys.readouterr().err
    assert cli.main(["slam", str(tmp_path / "missing.bag"), "-o", out]) == 2
    assert "missing.bag: no such file" in capsys.readouterr().err
    scans_only = tmp_path / "scans_only.bag"
    bag = _Bag(scans_only)
    bag.scan("/scan", 1.0, [1.0, 2.0])
    bag.close()
    assert cli.main(["map", str(scans_only), "-o", out, "--no-progress"]) == 2
    assert "no poses to map with" in capsys.readouterr().err


#: ACES as a bag against ACES as a .clf, mean translational relations error: the bag's float32 beam
#: angles change which loop closures the matcher accepts (77 against 99 here), which moved the
#: score by 0.35 mm (0.0429 against 0.0425 m, 2026-11-26); 2 mm is well below what any real
#: difference in the poses or scans read (a centimetre or more) would cost.
ACES_RELATIONS_TOL = 0.002


@needs_rosbags
@pytest.mark.slow
def test_aces_bag_gives_the_relations_error_of_the_clf(shared_data, tmp_path):
    aces = shared_data / "laser_2d/aces"
    if not (aces / "aces.clf.bz2").exists():
        pytest.skip("ACES not present")
    log = io.read_carmen_log(aces / "aces.clf.bz2")
    io.write_rosbag(log, tmp_path / "aces.bag")
    relations = ps.eval.relations_on_logger_time(aces / "aces.relations", log.scans)  # stamped with the ipc time
    errors = [ps.eval.relations_error(r.timestamps, r.poses, relations)
              for r in (ps.run_slam(log, progress=False), ps.run_slam(tmp_path / "aces.bag", progress=False))]
    assert errors[0].skipped == errors[1].skipped == 0
    assert abs(errors[0].trans_mean - errors[1].trans_mean) <= ACES_RELATIONS_TOL


@needs_rosbags
@pytest.mark.parametrize("fmt", ["rosbag1", "rosbag2"])
def test_a_damaged_chunk_or_storage_is_read_as_far_as_it_can_be(tmp_path, raw_log, fmt):
    """ROS 1: one chunk's bytes overwritten; the index still opens, rosbags stops at the chunk,
    the walk skips it and reads the others. ROS 2: the sqlite3 file cut short: an error naming
    the bag, never a traceback of the storage layer."""
    path = tmp_path / f"a{_suffix(fmt)}"
    from rosbags.rosbag1 import Writer

    if fmt == "rosbag1":
        original = Writer.__init__

        def small_chunks(self, p):  # several chunks, so that one can be damaged
            original(self, p)
            self.chunk_threshold = 64 << 10

        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(Writer, "__init__", small_chunks)
            io.write_rosbag(raw_log, path)
        data = bytearray(path.read_bytes())
        chunks = [i for i in range(len(data)) if data.startswith(b"op=\x05", i)]
        assert len(chunks) >= 4
        # 4 kB in the middle of a chunk's data overwritten: a few message records, not the chunk's
        # own header (which rosbags reads when it opens the bag).
        middle = chunks[len(chunks) // 2] + 32 * 1024
        data[middle:middle + 4096] = b"\xff" * 4096
        path.write_bytes(bytes(data))
        with pytest.warns(UserWarning, match="skipped"):
            log = io.read_rosbag(path)
        assert log.index_note.startswith("rosbags stopped reading")
        assert 500 < len(log.scans) < 630
        # Every scan read is one of the log's, with its ranges; its pose is the log's, or where
        # the odometry message of its stamp was lost, interpolated between its neighbours.
        rows = [int(np.flatnonzero(raw_log.scans.timestamps == t)[0]) for t in log.scans.timestamps]
        np.testing.assert_array_equal(log.scans.ranges, raw_log.scans.ranges[rows])
        exact = np.all(log.scans.robot_poses[:, :2] == raw_log.scans.robot_poses[rows, :2], axis=1)
        assert exact.mean() > 0.95
    else:
        io.write_rosbag(raw_log, path, format=fmt)
        db3 = next(path.glob("*.db3"))
        db3.write_bytes(db3.read_bytes()[:4096])
        with pytest.raises(ValueError, match=str(path.name)):
            io.read_rosbag(path)


@needs_rosbags
def test_odometry_without_child_frame_takes_the_offset_above_the_laser(tmp_path):
    path = tmp_path / "nochild.bag"
    bag = _Bag(path)
    bag.tf(0.0, "base_link", "laser", (0.3, 0.0, 0.1), static=True)
    for t in (1.0, 2.0, 3.0):
        bag.odometry("/odom", t, _moving(t), child="")
        bag.scan("/scan", t, [1.0, 2.0])
    bag.close()
    log = io.read_rosbag(path)
    assert log.laser_offset_source == "tf_static"
    np.testing.assert_allclose(log.scans.laser_poses, _compose_all([_moving(t) for t in (1, 2, 3)], (0.3, 0, 0.1)),
                               atol=1e-12)


@needs_rosbags
@pytest.mark.parametrize("yaw", [0.0, 0.3])
def test_a_laser_mounted_upside_down_has_its_beams_mirrored(tmp_path, yaw):
    """Reference: the beam end points rotated in 3-D by scipy from the tf quaternion (laser
    turned by yaw about z, then by pi about its x axis), against the planar end points of the
    scans read (laser pose + beam angle)."""
    from scipy.spatial.transform import Rotation

    mount = Rotation.from_euler("z", yaw) * Rotation.from_euler("x", np.pi)
    qx, qy, qz, qw = mount.as_quat()
    path = tmp_path / "flipped.bag"
    bag = _Bag(path)
    header = bag.build.header(0, "base_link")
    tf = bag.build.transform(header, "laser", (0.2, 0.1, 0.0))
    rotation = bag.store.types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw)
    tf = dataclasses.replace(tf, transform=dataclasses.replace(tf.transform, rotation=rotation))
    bag.write("/tf_static", "tf2_msgs/msg/TFMessage", 0.0, bag.build.tf([tf]))
    ranges = [1.0, 2.0, 3.0]
    for t in (1.0, 2.0):
        bag.odometry("/odom", t, (0.0, 0.0, 0.0))
        bag.scan("/scan", t, ranges, start=-0.5, step=0.5)
    bag.close()
    log = io.read_rosbag(path)
    assert log.laser_upside_down and "upside down" in log.describe()
    s = log.scans
    angles = s.beam_angles()[0]
    planar = s.laser_poses[0, :2] + np.column_stack([np.cos(s.laser_poses[0, 2] + angles),
                                                     np.sin(s.laser_poses[0, 2] + angles)]) * np.array(ranges)[:, None]
    beams = F32([-0.5, 0.0, 0.5])
    in_laser = np.column_stack([np.cos(beams), np.sin(beams), np.zeros(3)]) * np.array(ranges)[:, None]
    in_base = mount.apply(in_laser) + [0.2, 0.1, 0.0]
    np.testing.assert_allclose(planar, in_base[:, :2], atol=1e-12)


def _as_humble_bag(folder):
    """The ROS 2 sqlite3 bag rosbags wrote in ``folder`` turned into what Foxy / Galactic / Humble
    record: metadata.yaml version 5 (no ros_distro, custom_data or type hashes) and a schema-3
    database without the message_definitions table (and without Iron's metadata table), so the
    bag holds no type definitions at all."""
    import sqlite3

    from ruamel.yaml import YAML

    yaml = YAML(typ="safe")
    meta_path = folder / "metadata.yaml"
    meta = yaml.load(meta_path.read_text())
    info = meta["rosbag2_bagfile_information"]
    info["version"] = 5
    for key in ("ros_distro", "custom_data"):
        info.pop(key, None)
    for topic in info["topics_with_message_count"]:
        topic["topic_metadata"].pop("type_description_hash", None)
    with open(meta_path, "w") as f:
        yaml.dump(meta, f)
    for db in folder.glob("*.db3"):
        con = sqlite3.connect(db)
        con.executescript("""
            DROP TABLE message_definitions;
            DROP TABLE metadata;
            CREATE TABLE humble_topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
                                       serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
            INSERT INTO humble_topics SELECT id, name, type, serialization_format, offered_qos_profiles FROM topics;
            DROP TABLE topics;
            ALTER TABLE humble_topics RENAME TO topics;
            UPDATE schema SET schema_version = 3, ros_distro = 'humble';
        """)
        con.commit()
        con.close()


@needs_rosbags
@pytest.mark.parametrize("odometry", ["odometry", "tf"])
def test_a_ros2_bag_without_type_definitions_is_read_with_the_standard_messages(tmp_path, raw_log, odometry):
    # Issue 48: bags recorded before Iron store no message definitions ("Bag contains no type
    # definitions"); they are read with the distribution's standard messages.
    with_definitions, humble = tmp_path / "iron", tmp_path / "humble"
    io.write_rosbag(raw_log, with_definitions, format="rosbag2", odometry=odometry)
    io.write_rosbag(raw_log, humble, format="rosbag2", odometry=odometry)
    _as_humble_bag(humble)
    assert "version: 5" in (humble / "metadata.yaml").read_text()
    from rosbags.highlevel import AnyReader
    with pytest.raises(Exception, match="no type definitions"):  # rosbags alone refuses it
        AnyReader([humble]).open()
    a, b = io.read_rosbag(with_definitions), io.read_rosbag(humble)
    assert b.skipped_rows == 0 and len(b.scans) == len(raw_log.scans) == 630
    for name in ("ranges", "timestamps", "robot_poses", "laser_poses", "start_angles", "angular_resolutions"):
        np.testing.assert_array_equal(getattr(b.scans, name), getattr(a.scans, name))
    assert (b.pose_source, b.laser_offset_source, b.topics) == (a.pose_source, a.laser_offset_source, a.topics)
    np.testing.assert_array_equal(b.scans.ranges, raw_log.scans.ranges)


@needs_rosbags
def test_a_fifo_is_refused_not_waited_on(tmp_path, raw_log):
    # Issue 48: read_rosbag on a FIFO blocked forever in open(). Run in a child process with a
    # timeout, so a regression fails rather than hangs.
    import subprocess

    fifo = tmp_path / "pipe.bag"
    os.mkfifo(fifo)
    folder = tmp_path / "ros2"
    io.write_rosbag(raw_log, folder, format="rosbag2")
    db3 = next(folder.glob("*.db3"))
    db3.unlink()
    os.mkfifo(db3)  # the storage file of a real folder is a FIFO
    code = ("import sys\nfrom probslam import io\n"
            "try:\n    io.read_rosbag(sys.argv[1])\nexcept ValueError as e:\n    print(e)\n")
    for path, named in ((fifo, fifo), (folder, db3), (db3, db3)):
        try:
            run = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120,
                                 env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)))
        except subprocess.TimeoutExpired:
            pytest.fail(f"read_rosbag({path}) blocked")
        assert run.stdout.strip() == f"path: {str(named)!r} is not a regular file", run.stderr
