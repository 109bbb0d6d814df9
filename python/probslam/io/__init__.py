"""Readers and writers: CARMEN laser logs, ROS bags (``rosbags`` needed only for them), ROS map_server maps, lossless grids, PNG pictures."""

from .carmen import CarmenLog, LaserScans, Odometry, read_carmen_log
from .landmark_datasets import MRCLAM_RANGE_SCALE, Mrclam, VictoriaPark, read_mrclam, read_victoria_park
from .maps import load_grid, load_ros_map, save_grid, save_ros_map, write_png
from . import rosbag
from .rosbag import RosbagLog, read_rosbag
from .rosbag_writer import write_rosbag

__all__ = [
    "MRCLAM_RANGE_SCALE",
    "CarmenLog",
    "LaserScans",
    "Mrclam",
    "Odometry",
    "RosbagLog",
    "VictoriaPark",
    "load_grid",
    "load_ros_map",
    "read_carmen_log",
    "read_mrclam",
    "read_rosbag",
    "read_victoria_park",
    "save_grid",
    "save_ros_map",
    "write_png",
    "write_rosbag",
]
