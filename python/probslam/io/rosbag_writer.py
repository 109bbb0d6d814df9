"""ROS bags out: a CARMEN log (or any ``LaserScans``) written as a ROS 1 bag, a ROS 2 sqlite3 bag
or a ROS 2 mcap bag with ``rosbags``' writers, in the layout ``rosbag.read_rosbag`` reads (and
a robot records): LaserScan, Odometry or tf, the laser's offset in tf_static."""

from __future__ import annotations

import math
import os
from typing import Optional, Union

import numpy as np

from ..geometry import between
from ._files import file_path
from .carmen import CarmenLog, LaserScans
from .rosbag import PathLike, _rosbags

#: ``write_rosbag``'s formats.
FORMATS = ("rosbag1", "rosbag2", "mcap")

#: ``write_rosbag`` refuses a log whose laser sits at offsets from the robot pose that differ by
#: more than this (metres, radians): tf_static holds one offset. CARMEN logs print poses with
#: 3 to 6 decimals, so offsets computed from them vary by up to about 1e-3 from rounding alone.
OFFSET_SPREAD_TOL = 2e-3


class _Messages:
    """Builds the messages of one typestore (ROS 1 headers carry a ``seq``, ROS 2 ones do not)."""

    def __init__(self, store) -> None:
        self.store = store
        self.t = store.types
        self.seq = "seq" in self.t["std_msgs/msg/Header"].__dataclass_fields__

    def header(self, stamp_ns: int, frame: str, seq: int = 0):
        sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
        stamp = self.t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        if self.seq:
            return self.t["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame)
        return self.t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def pose(self, p):
        q = self.t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(p[2] / 2), w=math.cos(p[2] / 2))
        return self.t["geometry_msgs/msg/Pose"](position=self.t["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=0.0),
                                                orientation=q)

    def transform(self, header, child: str, p):
        pose = self.pose(p)
        vec = self.t["geometry_msgs/msg/Vector3"](x=pose.position.x, y=pose.position.y, z=0.0)
        return self.t["geometry_msgs/msg/TransformStamped"](
            header=header, child_frame_id=child,
            transform=self.t["geometry_msgs/msg/Transform"](translation=vec, rotation=pose.orientation))

    def tf(self, transforms):
        return self.t["tf2_msgs/msg/TFMessage"](transforms=list(transforms))

    def odometry(self, header, child: str, p):
        zero = self.t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = self.t["geometry_msgs/msg/Twist"](linear=zero, angular=zero)
        return self.t["nav_msgs/msg/Odometry"](
            header=header, child_frame_id=child,
            pose=self.t["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(p), covariance=np.zeros(36)),
            twist=self.t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)))

    def pose_stamped(self, header, p):
        return self.t["geometry_msgs/msg/PoseStamped"](header=header, pose=self.pose(p))

    def scan(self, header, ranges: np.ndarray, start: float, step: float, range_max: float, range_min: float = 0.0):
        return self.t["sensor_msgs/msg/LaserScan"](
            header=header, angle_min=float(start), angle_max=float(start + step * (len(ranges) - 1)),
            angle_increment=float(step), time_increment=0.0, scan_time=0.0, range_min=float(range_min),
            range_max=float(range_max), ranges=np.asarray(ranges, dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32))


def _laser_offset_of(scans: LaserScans) -> np.ndarray:
    """The laser's pose in the robot's frame, one for the whole log (the mean over the scans);
    ValueError when the scans' offsets differ by more than OFFSET_SPREAD_TOL."""
    rel = between(scans.robot_poses, scans.laser_poses)
    heading = math.atan2(np.sin(rel[:, 2]).mean(), np.cos(rel[:, 2]).mean())
    offset = np.array([rel[:, 0].mean(), rel[:, 1].mean(), heading])
    spread = np.abs(between(offset, rel)).max(axis=0)
    if spread.max() > OFFSET_SPREAD_TOL:
        raise ValueError(f"log: the laser's offset from the robot pose varies by up to ({spread[0]:.3g} m, "
                         f"{spread[1]:.3g} m, {spread[2]:.3g} rad) over the scans, more than tf_static's one "
                         f"offset can hold (OFFSET_SPREAD_TOL {OFFSET_SPREAD_TOL}); write with "
                         "laser_offset_in_tf_static=False and poses='laser'")
    return offset


def _stamp_ns(t: float) -> int:
    """Seconds as integer nanoseconds (a ROS time), rounded to the nearest."""
    sec = math.floor(t)
    return int(sec) * 1_000_000_000 + int(round((t - sec) * 1e9))


def write_rosbag(log: Union[CarmenLog, LaserScans], path: PathLike, *, format: str = "rosbag1",
                 odometry: str = "odometry", laser_offset_in_tf_static: bool = True, poses: str = "robot",
                 range_min: float = 0.0,
                 pose_topic: Optional[str] = None, scan_topic: str = "/scan", odom_topic: str = "/odom",
                 odom_frame: str = "odom", base_frame: str = "base_link", laser_frame: str = "laser") -> None:
    """Write a log's scans and poses as a ROS bag (for users converting CARMEN logs, and tests).

    format: "rosbag1" (a ``.bag`` file), "rosbag2" (a folder with sqlite3 storage) or "mcap" (a
    ROS 2 folder with mcap storage). Per scan: a ``sensor_msgs/LaserScan`` on ``scan_topic``
    (frame ``laser_frame``; ranges as float32, the message's type; range_max the log's no-return
    reading, ``LaserScans.no_return_range``, else just above its largest reading) and the robot
    pose at the scan's stamp, as ``nav_msgs/Odometry`` on ``odom_topic`` (odometry="odometry")
    or as ``tf`` ``odom_frame -> base_frame`` (odometry="tf"). ``poses="robot"`` writes the
    scans' robot poses and the laser's offset from them once in ``tf_static`` (``base_frame ->
    laser_frame``; with ``laser_offset_in_tf_static=False`` it is left out, and a reader needs
    ``laser_offset``); ``poses="laser"`` writes the laser poses as the robot's (offset zero).
    ``pose_topic``: the same poses as ``geometry_msgs/PoseStamped`` there too (frame "map"), for
    ``map_laser_log`` of a corrected log. odometry="none" writes no pose at all (a robot without
    odometry; ``read_rosbag`` then says so). range_min m: the LaserScans' range_min (a driver
    reporting 0 for no return states a range_min above it). Record times are the stamps made
    non-decreasing (a recorder's clock does not go back; stamps that do are kept in the headers).

    Errors: rosbags missing: ImportError; an existing ``path``: FileExistsError; a bad option
    or a log whose laser offset varies (see ``OFFSET_SPREAD_TOL``): ValueError. A failed write
    leaves nothing at ``path``.
    """
    import shutil

    scans = log.scans if isinstance(log, CarmenLog) else log
    if not isinstance(scans, LaserScans):
        raise TypeError(f"log: expected a CarmenLog or LaserScans, got {type(log).__name__}")
    path = file_path(path)
    _rosbags()
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    for name, value, allowed in (("format", format, FORMATS), ("odometry", odometry, ("odometry", "tf", "none")),
                                 ("poses", poses, ("robot", "laser"))):
        if value not in allowed:
            raise ValueError(f"{name} must be one of {allowed}, got {value!r}")
    if not (isinstance(range_min, (int, float)) and math.isfinite(range_min) and range_min >= 0):
        raise ValueError(f"range_min must be a finite number >= 0, got {range_min!r}")
    if len(scans) == 0:
        raise ValueError("log: no scans to write")
    for name in ("laser_poses", "robot_poses", "timestamps", "start_angles", "angular_resolutions"):
        if not np.all(np.isfinite(getattr(scans, name))):
            raise ValueError(f"log: scans.{name} must contain only finite values")
    if os.path.lexists(path):
        raise FileExistsError(f"path: {path!r} exists already (a bag is never overwritten)")
    robot = scans.robot_poses if poses == "robot" else scans.laser_poses
    offset = _laser_offset_of(scans) if poses == "robot" else np.zeros(3)
    no_return = scans.no_return_range()
    if not math.isfinite(no_return):
        top = np.nanmax(np.where(np.isfinite(scans.ranges), scans.ranges, np.nan)) if np.isfinite(scans.ranges).any() else 1.0
        no_return = float(np.nextafter(np.float32(top), np.float32(np.inf)))

    ros1 = format == "rosbag1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in store.types:
        # rosbags' Noetic store leaves out tf2_msgs; its one-line definition is ROS's own.
        from rosbags.typesys import get_types_from_msg

        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    build = _Messages(store)
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    if ros1:
        writer = Writer1(path)
    else:
        plugin = StoragePlugin.MCAP if format == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=9, storage_plugin=plugin)
    try:
        with writer:
            def connection(topic: str, msgtype: str):
                return writer.add_connection(topic, msgtype, typestore=store)

            c_scan = connection(scan_topic, "sensor_msgs/msg/LaserScan")
            c_odom = connection(odom_topic, "nav_msgs/msg/Odometry") if odometry == "odometry" else None
            c_tf = connection("/tf", "tf2_msgs/msg/TFMessage") if odometry == "tf" else None
            c_pose = connection(pose_topic, "geometry_msgs/msg/PoseStamped") if pose_topic else None
            record = _stamp_ns(float(scans.timestamps.min()))
            if laser_offset_in_tf_static:
                c_static = connection("/tf_static", "tf2_msgs/msg/TFMessage")
                static = build.tf([build.transform(build.header(record, base_frame), laser_frame, offset)])
                writer.write(c_static, record, serialize(static, "tf2_msgs/msg/TFMessage"))
            for i in range(len(scans)):
                stamp = _stamp_ns(float(scans.timestamps[i]))
                record = max(record, stamp)
                if c_odom is not None:
                    msg = build.odometry(build.header(stamp, odom_frame, i), base_frame, robot[i])
                    writer.write(c_odom, record, serialize(msg, "nav_msgs/msg/Odometry"))
                elif c_tf is not None:
                    msg = build.tf([build.transform(build.header(stamp, odom_frame, i), base_frame, robot[i])])
                    writer.write(c_tf, record, serialize(msg, "tf2_msgs/msg/TFMessage"))
                if c_pose is not None:
                    msg = build.pose_stamped(build.header(stamp, "map", i), robot[i])
                    writer.write(c_pose, record, serialize(msg, "geometry_msgs/msg/PoseStamped"))
                n = int(scans.num_beams[i])
                msg = build.scan(build.header(stamp, laser_frame, i), scans.ranges[i, :n], scans.start_angles[i],
                                 scans.angular_resolutions[i], no_return, range_min)
                writer.write(c_scan, record, serialize(msg, "sensor_msgs/msg/LaserScan"))
    except BaseException:
        if os.path.isdir(path):
            shutil.rmtree(path, ignore_errors=True)
        elif os.path.lexists(path):
            os.remove(path)
        raise
