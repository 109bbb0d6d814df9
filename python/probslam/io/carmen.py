"""CARMEN log reader (FLASER, ROBOTLASER1, ODOM, PARAM); parsing is done in C++."""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field, fields
from typing import Dict, List, Optional, Tuple, Union

import numpy as np

from .. import _core
from ._files import compression, file_path, read_compressed, require_regular_file

PathLike = Union[str, "os.PathLike[str]"]

#: How many skipped lines a ``CarmenLog`` lists (and its warning names); all are counted.
MAX_REPORTED_LINES = _core.CARMEN_MAX_REPORTED_LINES

#: The PARAM a log states its odometry's noise by (``sim_laser.write_carmen`` writes it): the six
#: coefficients of an ``OdometryNoise`` in its field order, comma-separated, in one token.
ODOMETRY_NOISE_PARAM = "probslam_odometry_noise"
#: The coefficients of an odometry noise statement (trans_per_metre, trans_per_radian,
#: trans_floor, rot_per_radian, rot_per_metre, rot_floor).
ODOMETRY_NOISE_SIZE = 6


@dataclass
class LaserScans:
    """Laser scans, one row per scan (S scans, B beams at most).

    ranges: (S, B) metres, NaN-padded; laser_poses / robot_poses: (S, 3) ``(x, y, theta)``;
    start_angles, angular_resolutions: (S,) radians relative to the laser heading;
    max_ranges: (S,) metres (NaN where the log does not say); num_beams: (S,);
    timestamps: (S,) seconds, the log's logger time (each CARMEN record's last field: one clock
    from the start of logging, the one the corrected Radish logs carry);
    ipc_timestamps: (S,) seconds, the ipc time (the sending host's clock, the one the Freiburg
    relations files use), NaN where the source has none (a ROS bag, a simulation);
    odometry_noise: (S, 6) the noise the log states of its odometry at each scan, the six
    coefficients of an ``OdometryNoise`` (a simulation's,
    ``sim_laser.OdometryModel.stated_noise``; a CARMEN log's ``PARAM probslam_odometry_noise``),
    NaN where it states none (the CARMEN logs of the real robots, ROS bags as read today):
    ``slam.default_options`` takes it. Per scan, as every other field, so that a subset of the
    rows is a subset of every field.
    """

    ranges: np.ndarray
    laser_poses: np.ndarray
    robot_poses: np.ndarray
    start_angles: np.ndarray
    angular_resolutions: np.ndarray
    max_ranges: np.ndarray
    num_beams: np.ndarray
    timestamps: np.ndarray
    ipc_timestamps: Optional[np.ndarray] = None
    odometry_noise: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        if self.ipc_timestamps is None:
            self.ipc_timestamps = np.full(np.shape(self.timestamps), np.nan)
        if self.odometry_noise is None:
            self.odometry_noise = np.full((len(np.atleast_1d(self.timestamps)), ODOMETRY_NOISE_SIZE), np.nan)

    def __len__(self) -> int:
        return int(self.ranges.shape[0])

    def take(self, index) -> "LaserScans":
        """The scans at ``index`` (row indices, a slice or a boolean mask): every field has one
        row per scan, so each is indexed alike."""
        return LaserScans(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    def beam_angles(self) -> np.ndarray:
        """(S, B) bearing of every beam relative to the laser heading, radians."""
        beams = np.arange(self.ranges.shape[1], dtype=float)
        return self.start_angles[:, None] + self.angular_resolutions[:, None] * beams[None, :]

    def no_return_range(self) -> float:
        """The sensor's "no return" reading: the smallest maximum range the log states, else the
        largest reading if it recurs (SICK scanners report 81.83 / 81.91 m, simulators 50 m),
        else infinity."""
        stated = self.max_ranges[np.isfinite(self.max_ranges)]
        if stated.size:
            return float(stated.min())
        valid = self.ranges[np.isfinite(self.ranges)]
        if valid.size == 0:
            return float("inf")
        top = valid.max()
        return float(top) if np.count_nonzero(valid == top) > 1 else float("inf")


@dataclass
class Odometry:
    """ODOM messages: poses (M, 3), velocities (M, 2) ``(tv m/s, rv rad/s)``, timestamps (M,)
    (logger time, as LaserScans), ipc_timestamps (M,) (NaN where the source has none)."""

    poses: np.ndarray
    velocities: np.ndarray
    timestamps: np.ndarray
    ipc_timestamps: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        if self.ipc_timestamps is None:
            self.ipc_timestamps = np.full(np.shape(self.timestamps), np.nan)



def stated_odometry_noise(params: Dict[str, str], source: object = "log") -> Optional[Tuple[float, ...]]:
    """The odometry noise a log's ``ODOMETRY_NOISE_PARAM`` states; None where it states none, or
    (with a warning naming the log) states it malformed: six finite numbers >= 0, floors > 0."""
    text = params.get(ODOMETRY_NOISE_PARAM)
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if (len(values) != ODOMETRY_NOISE_SIZE or not all(math.isfinite(v) and v >= 0 for v in values)
            or values[2] <= 0 or values[5] <= 0):
        warnings.warn(f"{source}: PARAM {ODOMETRY_NOISE_PARAM} {text[:80]!r} is not six numbers >= 0 with "
                      "positive floors; ignored (the fixed odometry model is used)", stacklevel=3)
        return None
    return values


@dataclass
class CarmenLog:
    """A CARMEN log as read by ``read_carmen_log``: the laser scans (with their odometry and,
    in corrected logs, laser poses; metres, radians, seconds), the ODOM records, the PARAM
    lines, and what was skipped (counts, and the first malformed lines with their numbers)."""

    scans: LaserScans
    odometry: Odometry
    params: Dict[str, str] = field(default_factory=dict)
    #: scans skipped because padding every scan to their width would exceed 4x the beams read
    skipped_wide_scans: int = 0
    #: malformed lines skipped (see ``read_carmen_log``); the line numbers and reasons of the
    #: first ``MAX_REPORTED_LINES`` of them
    skipped_rows: int = 0
    skipped_lines: List[int] = field(default_factory=list)
    skipped_reasons: List[str] = field(default_factory=list)


def read_carmen_log(path: PathLike) -> CarmenLog:
    """Read a CARMEN log (plain or compressed: gzip, bzip2 or xz, told by its first bytes).

    FLASER beams start at -90 degrees; their step is ``PARAM laser_front_laser_resolution``
    when the log has it, else 180 degrees / n (even n) or / (n - 1) (odd n).

    Errors: a missing file raises ``FileNotFoundError``; a path that is not a regular file, a
    corrupt ``.gz`` / ``.bz2`` stream or one expanding beyond ``MAX_DECOMPRESSED_BYTES`` raises
    ``ValueError`` naming the file, and so does a log with no valid scan at all (the message
    gives how many lines were skipped and the first as ``file:line: reason``, whatever bytes it
    holds). Row-level (a real log is read even with a few bad lines): a malformed FLASER /
    ROBOTLASER1 / ODOM / PARAM line (too few fields, a beam count larger than the fields present
    as in a line cut off mid-write, a field that is not a number) and a line whose first field
    is not a message name are skipped, counted in ``skipped_rows`` (the first listed in
    ``skipped_lines`` / ``skipped_reasons``) and announced by one warning naming the first line
    numbers; other message types are ignored; scans so much wider than the rest that padding to
    them would exceed 4x the beams read are skipped, counted in ``skipped_wide_scans``.
    """
    path = file_path(path)
    require_regular_file(path)
    if compression(path):
        raw = _core.parse_carmen_log(read_compressed(path), path)
    else:
        raw = _core.read_carmen_log(path)
    log = CarmenLog(LaserScans(**raw["scans"]), Odometry(**raw["odometry"]), dict(raw["params"]),
                    int(raw["skipped_wide_scans"]), int(raw["skipped_rows"]), list(raw["skipped_lines"]),
                    list(raw["skipped_reasons"]))
    stated = stated_odometry_noise(log.params, path)
    if stated is not None:
        log.scans.odometry_noise[:] = stated
    if log.skipped_rows == 1:
        warnings.warn(f"{path}: skipped 1 malformed line (line {log.skipped_lines[0]}: {log.skipped_reasons[0]})",
                      stacklevel=2)
    elif log.skipped_rows:
        more = ", ..." if log.skipped_rows > len(log.skipped_lines) else ""
        warnings.warn(f"{path}: skipped {log.skipped_rows} malformed lines (lines "
                      f"{', '.join(map(str, log.skipped_lines))}{more}; first: {log.skipped_reasons[0]})",
                      stacklevel=2)
    return log
