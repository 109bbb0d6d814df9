"""Victoria Park, the original run (ACFR, University of Sydney; J. Guivant and E. Nebot 2001): a
utility car's encoder speed and steering at 40 Hz, every tree its laser's detector found (range,
bearing, trunk diameter; no identities) and GPS fixes, over 1,549 s and about 4 km. Read
(``load``), with the car's geometry and the start pose the runs on this data use.

This is the run the SLAM lecture's FastSLAM result was measured on ("100 particles, position
error < 5 m RMS" against its GPS), not the iSAM / GTSAM conversion of ``datasets.victoria_park``.
The file reader is ``probslam.io.read_victoria_park_acfr``; the score against GPS is
``probslam.eval.position_error``. Units: metres, radians, seconds.
"""

from __future__ import annotations

import math
import os
import pathlib
from typing import Union

import numpy as np

from .. import _core
from .._args import require_instance
from ..io._files import file_path
from ..io.landmark_datasets import VICTORIA_PARK_ACFR_FILES, VictoriaParkAcfr, _data_file, read_victoria_park_acfr

PathLike = Union[str, "os.PathLike[str]"]

# The car's geometry (Guivant and Nebot's model; the dataset's info.txt and its drawing car.bmp,
# as the dataset's README gives them). The model's state is the laser's position and the heading.
#: L (m): the wheelbase, rear axle to front axle.
WHEELBASE = 2.83
#: H (m): the encoder's wheel (rear left) from the rear axle's centre, to the left.
ENCODER_OFFSET = 0.76
#: a (m): the laser (and the GPS antenna) ahead of the rear axle: 0.95 m ahead of the front axle
#: plus the wheelbase (code that puts it 0.95 m ahead of the rear axle misplaces it).
LASER_AHEAD = 0.95 + WHEELBASE
#: b (m): the laser to the side of the car's axis, to the left (the model's sign).
LASER_LEFT = 0.50

#: The heading (rad) at the start, in the GPS's frame: 35.5 deg, the value the published runs on
#: this data start from (e.g. Mrstarr/Applied-Estimation-project, workspace/main.m, whose GPS
#: track the dataset's gps.dat is); the README's "about 36 deg". The GPS agrees: its first 20 m
#: run at 36.4 deg. Not fitted to any result.
START_HEADING = math.radians(35.5)


#: The largest distance (m) a range or GPS coordinate may be: the filters refuse coordinates
#: beyond it (C++ kMaxCoordinate).
MAX_COORDINATE = _core.MAX_COORDINATE


def load(folder: PathLike) -> VictoriaParkAcfr:
    """The run in ``folder``, ready to run: read by ``io.read_victoria_park_acfr`` (inputs.dat,
    measurements.dat, and gps.dat when present; its errors and row policy), and a ValueError
    naming the folder when a range or a GPS coordinate lies beyond ``MAX_COORDINATE``."""
    folder = pathlib.Path(file_path(folder, "folder"))
    data = read_victoria_park_acfr(folder)
    far = [name for name, values in (("measurements.dat ranges", data.measurements[:, 1]),
                                     ("gps.dat positions", None if data.gps is None else data.gps[:, 1:]))
           if values is not None and np.max(np.abs(values)) > MAX_COORDINATE]
    if far:
        raise ValueError(f"{folder}: {' and '.join(far)} beyond {MAX_COORDINATE:g} m (MAX_COORDINATE)")
    return data


def is_run_folder(path: PathLike) -> bool:
    """Whether ``path`` is a folder holding the run's files (``VICTORIA_PARK_ACFR_FILES``, each
    plain or .gz / .bz2)."""
    path = pathlib.Path(file_path(path))
    return path.is_dir() and all(_data_file(path, name).exists() for name in VICTORIA_PARK_ACFR_FILES)


def start_pose(data: VictoriaParkAcfr) -> np.ndarray:
    """(3,) where runs start the car's laser: the first GPS fix, heading ``START_HEADING``; with no
    GPS the origin, heading 0 (the map's frame is then the start pose's)."""
    require_instance(data, VictoriaParkAcfr, "data")
    if data.gps is None:
        return np.zeros(3)
    return np.array([data.gps[0, 1], data.gps[0, 2], START_HEADING])


__all__ = ["ENCODER_OFFSET", "LASER_AHEAD", "LASER_LEFT", "MAX_COORDINATE", "START_HEADING", "VictoriaParkAcfr",
           "WHEELBASE", "is_run_folder", "load", "start_pose"]
