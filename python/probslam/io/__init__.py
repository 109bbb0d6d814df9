"""Readers and writers: CARMEN laser logs, ROS map_server maps, lossless grids, PNG pictures."""

from .carmen import CarmenLog, LaserScans, Odometry, read_carmen_log
from .maps import load_grid, load_ros_map, save_grid, save_ros_map, write_png

__all__ = [
    "CarmenLog",
    "LaserScans",
    "Odometry",
    "load_grid",
    "load_ros_map",
    "read_carmen_log",
    "save_grid",
    "save_ros_map",
    "write_png",
]
