"""Readers and writers: CARMEN laser logs, ROS bags (``rosbags`` needed only for them), ROS
map_server maps, PNG pictures, trajectories (TUM, KITTI), landmark datasets (MRCLAM, Victoria Park as iSAM text and as the original run); MRPT rawlogs
(written, to run MRPT's apps on the same log)."""

from .carmen import CarmenLog, LaserScans, Odometry, read_carmen_log
from .laser_log import NO_ODOMETRY_MOTION, has_odometry, read_carmen_scans, read_laser_log
from .landmark_datasets import (MRCLAM_RANGE_SCALE, Mrclam, VictoriaPark, VictoriaParkAcfr, read_mrclam,
                                read_victoria_park, read_victoria_park_acfr)
from .maps import load_ros_map, save_ros_map, write_png
from . import mrpt_rawlog
from .mrpt_rawlog import write_mrpt_rawlog
from .trajectory import (TRAJECTORY_FORMATS, Positions, Trajectory, kitti_times_path, read_positions,
                         read_trajectory, write_trajectory, write_trajectory_3d)
from . import rosbag
from .rosbag import RosbagLog, read_rosbag
from .rosbag_writer import write_rosbag

__all__ = [
    "CarmenLog",
    "LaserScans",
    "MRCLAM_RANGE_SCALE",
    "Mrclam",
    "NO_ODOMETRY_MOTION",
    "Odometry",
    "Positions",
    "RosbagLog",
    "TRAJECTORY_FORMATS",
    "Trajectory",
    "VictoriaPark",
    "VictoriaParkAcfr",
    "has_odometry",
    "kitti_times_path",
    "load_ros_map",
    "mrpt_rawlog",
    "read_carmen_log",
    "read_carmen_scans",
    "read_laser_log",
    "read_mrclam",
    "read_positions",
    "read_rosbag",
    "read_trajectory",
    "read_victoria_park",
    "read_victoria_park_acfr",
    "save_ros_map",
    "write_mrpt_rawlog",
    "write_png",
    "write_rosbag",
    "write_trajectory",
    "write_trajectory_3d",
]
