"""The Intel Research Lab floor plan as a world for the inverse-model studies: the corrected log
(/work/shared/data/laser_2d/intel, GMapping-corrected poses) mapped with the ray model
(probslam.inverse_learning.known_map); occupied where the map says so, and where it decides
nothing (outside the building, unseen corners), so that sampled poses stay in explored free
space; and the cells the map decides (the only ones scored: the filled unknown is no floor
plan). None when the shared data are absent."""

import pathlib

import numpy as np

from probslam import io
from probslam import inverse_learning as il

INTEL = pathlib.Path("/work/shared/data/laser_2d/intel/intel-corrected.log.gz")
MAP_RANGE = 10.0  # the readings used to build the plan (m): beyond, the SICK's 1 deg beams spread over 17 cm


def intel_scans():
    return io.read_carmen_log(str(INTEL)).scans if INTEL.exists() else None


def intel_floor_plan(resolution):
    scans = intel_scans()
    if scans is None:
        return None
    grid, occupied, known = il.known_map(scans, resolution, MAP_RANGE)
    return grid, occupied | ~known, known
