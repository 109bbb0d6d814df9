"""Readers and writers: CARMEN laser logs, ROS map_server maps, lossless grids, PNG pictures,
trajectories (TUM, KITTI)."""

from .carmen import CarmenLog, LaserScans, Odometry, read_carmen_log
from .landmark_datasets import MRCLAM_RANGE_SCALE, Mrclam, VictoriaPark, read_mrclam, read_victoria_park
from .maps import load_grid, load_ros_map, save_grid, save_ros_map, write_png
from .trajectory import TRAJECTORY_FORMATS, Trajectory, kitti_times_path, read_trajectory, write_trajectory

__all__ = [
    "MRCLAM_RANGE_SCALE",
    "CarmenLog",
    "LaserScans",
    "Mrclam",
    "Odometry",
    "TRAJECTORY_FORMATS",
    "Trajectory",
    "VictoriaPark",
    "kitti_times_path",
    "load_grid",
    "load_ros_map",
    "read_carmen_log",
    "read_mrclam",
    "read_trajectory",
    "read_victoria_park",
    "save_grid",
    "save_ros_map",
    "write_png",
    "write_trajectory",
]
