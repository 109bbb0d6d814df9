"""Laser logs as the laser pipelines take them: a CARMEN log (the Freiburg / Radish logs:
FLASER / ROBOTLASER1 / ODOM lines, plain or compressed) that holds scans (``read_carmen_scans``),
a ROS bag or a CARMEN log by what the path is (``read_laser_log``), and what a log carries
(``has_odometry``). The readers of each format are ``read_carmen_log`` and ``read_rosbag``.
"""

from __future__ import annotations

import os
from typing import Union

import numpy as np

from .._args import require_instance
from ._files import file_path
from .carmen import CarmenLog, LaserScans, read_carmen_log
from .rosbag import is_bag, read_rosbag

PathLike = Union[str, "os.PathLike[str]"]

#: Laser poses that move less than this over a whole log (metres, radians) mean the log carries
#: no odometry (MIT CSAIL's FLASER lines repeat one pose): scan matching alone then.
NO_ODOMETRY_MOTION = 1e-6


def read_carmen_scans(path: PathLike) -> CarmenLog:
    """The log at ``path``, which must hold laser scans: besides the reader's errors
    (``io.read_carmen_log``), a ValueError naming the file when it has none."""
    path = file_path(path)
    log = read_carmen_log(path)
    if len(log.scans) == 0:
        raise ValueError(f"{path}: no laser scans (FLASER or ROBOTLASER1 lines)")
    return log


def read_laser_log(path: PathLike) -> CarmenLog:
    """The laser log at ``path``: a ROS bag (``io.read_rosbag``, its topics found by their types;
    a ``RosbagLog``) or a CARMEN log (``read_carmen_scans``)."""
    return read_rosbag(path) if is_bag(path) else read_carmen_scans(path)


def has_odometry(scans: LaserScans) -> bool:
    """Whether the laser poses of the log move at all (some logs repeat one pose throughout)."""
    require_instance(scans, LaserScans, "scans")
    p = scans.laser_poses
    return bool(len(p) > 1 and np.ptp(p, axis=0).max() > NO_ODOMETRY_MOTION)


__all__ = ["NO_ODOMETRY_MOTION", "has_odometry", "read_carmen_scans", "read_laser_log"]
