"""Laser scans -> MRPT rawlog (``write_mrpt_rawlog``), to run MRPT's icp-slam and rbpf-slam on the
same log as probslam (benchmarks/bench_slam_cost.py compares them).

Why not MRPT's own ``carmen2rawlog`` (2.5.8): it stamps every observation with the conversion
time, assumes 0.5 degree beams and an 81 m maximum range, and writes an observations-only
rawlog, which ``rbpf-slam`` cannot read. This writes the "actions / sensory frames" format both
apps read: for every FLASER scan a ``CActionCollection`` holding one ``CActionRobotMovement2D``
(the odometry increment since the previous scan, MRPT's default Gaussian motion model) followed
by a ``CSensoryFrame`` holding one ``CObservation2DRangeScan`` with

- the FLASER timestamp (seconds since 1970 -> MRPT's 100 ns ticks since 1601),
- the log's beam geometry as probslam's CARMEN reader gives it (first beam's bearing, step,
  beam count; 1 degree for the 180-beam SICK logs). MRPT spreads N beams evenly over
  ``[-aperture / 2, aperture / 2]`` of the sensor frame, so the aperture is ``step * (N - 1)``
  and the sensor is yawed so that its first beam falls on the log's first bearing (-0.5 degree
  for beams at -90 .. 89 degrees),
- readings at or beyond the sensor's no-return range (``LaserScans.no_return_range``: the stated
  maximum, else the recurring largest reading, 81.83 m on ACES), NaN or <= 0 marked invalid.

The laser's mounting on the robot is taken from the first scan (its laser pose relative to its
odometry pose: zero on ACES, Intel and FR079).

The bytes: MRPT's ``CArchive`` object framing (class-name length | 0x80, the class name, the
class's serialization version, its fields, the end flag 0x88), little endian; the fields and
versions those of MRPT 2.5.8, checked against what its ``carmen2rawlog`` writes and read back
with its ``rawlog-edit --info``.
"""

from __future__ import annotations

import math
import os
import struct
from typing import BinaryIO, Tuple

import numpy as np

from ..geometry import between
from .carmen import LaserScans

#: MRPT TTimeStamp: 100 ns ticks since 1601-01-01 (the Windows FILETIME epoch).
TICKS_PER_SECOND = 10_000_000
UNIX_EPOCH_IN_TICKS = 116_444_736_000_000_000
END_FLAG = 0x88
#: The serialization versions MRPT 2.5.8 writes (and this writer's field lists follow).
VERSIONS = {"mrpt::obs::CActionCollection": 0, "mrpt::obs::CActionRobotMovement2D": 7,
            "mrpt::poses::CPose2D": 1, "mrpt::obs::CSensoryFrame": 2,
            "mrpt::obs::CObservation2DRangeScan": 7, "mrpt::poses::CPose3D": 3}
#: CActionRobotMovement2D's default motion models (MRPT's TMotionModelOptions defaults): the
#: Gaussian model (a1..a4, minStdXY m, minStdPHI rad) and Thrun's (particles, alpha1..4,
#: additional std xy, phi). The rawlog carries them; both apps use what it carries.
GAUSSIAN_MODEL = (0.01, math.degrees(0.001), math.radians(1.0), 0.05, 0.01, math.radians(0.2))
THRUN_MODEL = (300, 0.05, math.radians(4.0), 0.01, math.degrees(0.0001), 0.001, math.radians(0.05))
#: Range noise (1 sigma, m) stated in each scan; MRPT's default, and carmen2rawlog's.
RANGE_STD = 0.01
SENSOR_LABEL = "FLASER"


def mrpt_ticks(seconds: float) -> int:
    return int(round(seconds * TICKS_PER_SECOND)) + UNIX_EPOCH_IN_TICKS


def _string(s: str) -> bytes:
    raw = s.encode()
    return struct.pack("<I", len(raw)) + raw


def _object(class_name: str, fields: bytes) -> bytes:
    name = class_name.encode()
    return bytes([len(name) | 0x80]) + name + bytes([VERSIONS[class_name]]) + fields + bytes([END_FLAG])


def _pose2d(x: float, y: float, phi: float) -> bytes:
    return _object("mrpt::poses::CPose2D", struct.pack("<3d", x, y, phi))


def _pose3d_yaw(x: float, y: float, yaw: float) -> bytes:
    c, s = math.cos(yaw), math.sin(yaw)
    rotation = (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)  # row major
    return _object("mrpt::poses::CPose3D", struct.pack("<12d", x, y, 0.0, *rotation))


def odometry_action(increment: Tuple[float, float, float], seconds: float) -> bytes:
    """A CActionCollection with one CActionRobotMovement2D (estimation method: odometry)."""
    movement = (struct.pack("<I", 0) + _pose2d(*increment) + struct.pack("<I", 0)  # emOdometry, mmGaussian
                + struct.pack("<6f", *GAUSSIAN_MODEL) + struct.pack("<I6f", *THRUN_MODEL)
                + struct.pack("<??Q", False, False, mrpt_ticks(seconds)))  # no velocities, no encoders
    return _object("mrpt::obs::CActionCollection",
                   struct.pack("<I", 1) + _object("mrpt::obs::CActionRobotMovement2D", movement))


def scan_frame(ranges: np.ndarray, valid: np.ndarray, aperture: float, max_range: float,
               sensor: Tuple[float, float, float], seconds: float) -> bytes:
    """A CSensoryFrame with one CObservation2DRangeScan (beams counter-clockwise)."""
    n = len(ranges)
    scan = (struct.pack("<f?f", aperture, True, max_range) + _pose3d_yaw(*sensor) + struct.pack("<I", n)
            + np.asarray(ranges, dtype="<f4").tobytes() + np.asarray(valid, dtype=np.uint8).tobytes()
            + struct.pack("<fQf", RANGE_STD, mrpt_ticks(seconds), 0.0) + _string(SENSOR_LABEL)
            # deltaPitch (a double in 2.5.8's layout) and the intensity flag
            + struct.pack("<d?", 0.0, False))
    return _object("mrpt::obs::CSensoryFrame",
                   struct.pack("<I", 1) + _object("mrpt::obs::CObservation2DRangeScan", scan))


def laser_mount(scans: LaserScans) -> Tuple[float, float, float]:
    """The laser's pose on the robot: the first scan's laser pose relative to its odometry pose."""
    return tuple(between(scans.robot_poses[0], scans.laser_poses[0]).tolist())


def write_rawlog(scans: LaserScans, out: BinaryIO) -> int:
    """Write ``LaserScans`` (a raw log: odometry in ``robot_poses``) as action / sensory-frame
    pairs to a binary stream; returns the number of pairs. ValueError for a log without scans
    or with a scan of fewer than 2 beams."""
    if not isinstance(scans, LaserScans):
        raise TypeError(f"scans: expected LaserScans, got {type(scans).__name__}")
    if len(scans) == 0:
        raise ValueError("scans: the log has no laser scans")
    no_return = scans.no_return_range()
    finite = scans.ranges[np.isfinite(scans.ranges)]
    max_range = no_return if math.isfinite(no_return) else float(finite.max(initial=0.0))
    mount = laser_mount(scans)
    for i in range(len(scans)):
        n = int(scans.num_beams[i])
        if n < 2:
            raise ValueError(f"scans: scan {i} has {n} beams; MRPT's scan geometry needs at least 2")
        step = float(scans.angular_resolutions[i])
        aperture = step * (n - 1)
        ranges = scans.ranges[i, :n]
        valid = np.isfinite(ranges) & (ranges > 0.0) & (ranges < no_return)
        ranges = np.where(np.isfinite(ranges), ranges, max_range)
        yaw = math.remainder(mount[2] + float(scans.start_angles[i]) + 0.5 * aperture, 2.0 * math.pi)
        increment = (0.0, 0.0, 0.0) if i == 0 else tuple(between(scans.robot_poses[i - 1], scans.robot_poses[i]).tolist())
        t = float(scans.timestamps[i])
        out.write(odometry_action(increment, t))
        out.write(scan_frame(ranges, valid, aperture, max_range, (mount[0], mount[1], yaw), t))
    return len(scans)


def write_mrpt_rawlog(scans: LaserScans, path: "os.PathLike[str] | str") -> int:
    """Write ``scans`` as an MRPT rawlog file at ``path``; returns the number of scans."""
    with open(path, "wb") as f:
        return write_rawlog(scans, f)


__all__ = ["laser_mount", "mrpt_ticks", "odometry_action", "scan_frame", "write_mrpt_rawlog", "write_rawlog"]
