"""CARMEN log reader (FLASER, ROBOTLASER1, ODOM, PARAM); parsing is done in C++."""

from __future__ import annotations

import bz2
import gzip
import os
from dataclasses import dataclass, field
from typing import Dict, Union

import numpy as np

from .. import _core

PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class LaserScans:
    """Laser scans, one row per scan (S scans, B beams at most).

    ranges: (S, B) metres, NaN-padded; laser_poses / robot_poses: (S, 3) ``(x, y, theta)``;
    start_angles, angular_resolutions: (S,) radians relative to the laser heading;
    max_ranges: (S,) metres (NaN where the log does not say); num_beams: (S,);
    timestamps: (S,) seconds (ipc timestamp).
    """

    ranges: np.ndarray
    laser_poses: np.ndarray
    robot_poses: np.ndarray
    start_angles: np.ndarray
    angular_resolutions: np.ndarray
    max_ranges: np.ndarray
    num_beams: np.ndarray
    timestamps: np.ndarray

    def __len__(self) -> int:
        return int(self.ranges.shape[0])

    def beam_angles(self) -> np.ndarray:
        """(S, B) bearing of every beam relative to the laser heading, radians."""
        beams = np.arange(self.ranges.shape[1], dtype=float)
        return self.start_angles[:, None] + self.angular_resolutions[:, None] * beams[None, :]


@dataclass
class Odometry:
    """ODOM messages: poses (M, 3), velocities (M, 2) ``(tv m/s, rv rad/s)``, timestamps (M,)."""

    poses: np.ndarray
    velocities: np.ndarray
    timestamps: np.ndarray


@dataclass
class CarmenLog:
    scans: LaserScans
    odometry: Odometry
    params: Dict[str, str] = field(default_factory=dict)


def read_carmen_log(path: PathLike) -> CarmenLog:
    """Read a CARMEN log (plain, ``.gz`` or ``.bz2``).

    FLASER beams start at -90 degrees; their step is ``PARAM laser_front_laser_resolution``
    when the log has it, else 180 degrees / n (even n) or / (n - 1) (odd n). A malformed
    line raises ``ValueError`` naming the file and line number.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"path: no such log file: {path!r}")
    opener = {".gz": gzip.open, ".bz2": bz2.open}.get(os.path.splitext(path)[1])
    if opener is None:
        raw = _core.read_carmen_log(path)
    else:
        with opener(path, "rt", encoding="ascii") as f:
            raw = _core.parse_carmen_log(f.read(), path)
    return CarmenLog(LaserScans(**raw["scans"]), Odometry(**raw["odometry"]), dict(raw["params"]))
