"""CARMEN log reader (FLASER, ROBOTLASER1, ODOM, PARAM); parsing is done in C++."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Dict, Union

import numpy as np

from .. import _core
from ._files import read_compressed, require_regular_file

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
    #: scans skipped because padding every scan to their width would exceed 4x the beams read
    skipped_wide_scans: int = 0


def read_carmen_log(path: PathLike) -> CarmenLog:
    """Read a CARMEN log (plain, ``.gz`` or ``.bz2``).

    FLASER beams start at -90 degrees; their step is ``PARAM laser_front_laser_resolution``
    when the log has it, else 180 degrees / n (even n) or / (n - 1) (odd n).

    Errors: a missing file raises ``FileNotFoundError``; a path that is not a regular file, a
    corrupt ``.gz`` / ``.bz2`` stream or one expanding beyond ``MAX_DECOMPRESSED_BYTES`` raises
    ``ValueError`` naming the file. A malformed FLASER / ROBOTLASER1 / ODOM / PARAM line is fatal
    (``ValueError("file:line: ...")``, whatever bytes it holds): it means the file is not the
    format we read. Row-level: other message types are ignored, and scans so much wider than the
    rest that padding to them would exceed 4x the beams read are skipped, counted in
    ``skipped_wide_scans``.
    """
    path = os.fspath(path)
    require_regular_file(path)
    if os.path.splitext(path)[1] in (".gz", ".bz2"):
        raw = _core.parse_carmen_log(read_compressed(path), path)
    else:
        raw = _core.read_carmen_log(path)
    return CarmenLog(LaserScans(**raw["scans"]), Odometry(**raw["odometry"]), dict(raw["params"]),
                     int(raw["skipped_wide_scans"]))
