"""Trajectory files: TUM, KITTI and probslam's own ``timestamp x y theta``, written and read.

- **TUM** (the TUM RGB-D benchmark's format, what evo reads with ``--tum``): one row per pose,
  ``t x y z qx qy qz qw`` (s, m, unit quaternion, Hamilton convention, x y z w order). A 2-D pose
  ``(x, y, theta)`` is written as ``z = 0`` and the yaw quaternion ``(0, 0, sin(theta/2),
  cos(theta/2))``.
- **KITTI** (the KITTI odometry benchmark's ``poses`` files, evo's ``--kitti``): one row per
  pose, the 12 numbers of the 3x4 matrix ``[R | t]`` row by row, the 2-D pose as the rotation
  about z by theta. KITTI rows carry no time: the writer puts the timestamps, one per line, in a
  times file beside it (``kitti_times_path``: ``NAME_times.txt`` for ``NAME.kitti``, as KITTI
  ships a ``times.txt`` beside each sequence's poses), and the reader takes them from there (or
  the row index, and says so). The pose is in probslam's frame (x forward, y left, z up), not
  KITTI's camera frame (z forward, y down): the ground plane is x-y here.
- **xyt**: ``# timestamp x y theta`` then one ``t x y theta`` row per pose (s, m, m, rad), what
  ``probslam`` commands wrote before TUM (``--trajectory-format xyt``).

Positions without a heading, ``t x y`` rows (a GPS track such as the original Victoria Park
run's gps.dat), are read by ``read_positions``: a reference to score a path against
(``probslam.eval.position_error``), not a trajectory.

Units: seconds, metres, radians; theta wrapped to (-pi, pi]. Text is written with nine decimals
(1 ns, 1 nm, 1e-9 in each quaternion and matrix entry).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from typing import List, Optional, Union

import numpy as np

from .. import geometry
from .._args import distinct_numbers, real_array
from .._core import wrap_angle
from ._files import file_path, numeric_rows, numeric_table, require_regular_file, text_lines

PathLike = Union[str, "os.PathLike[str]"]

#: The formats ``write_trajectory`` and ``read_trajectory`` take.
TRAJECTORY_FORMATS = ("tum", "kitti", "xyt")

#: The file name extension each format is written with by the command line.
EXTENSIONS = {"tum": ".tum", "kitti": ".kitti", "xyt": ".txt"}

#: Field counts of a row: TUM 8, KITTI 12, xyt 4 (what ``format="auto"`` tells them apart by).
_FIELDS = {"tum": 8, "kitti": 12, "xyt": 4}

#: A TUM or KITTI row is planar when its z, and the rotation's parts that tilt the z axis (qx,
#: qy; the matrix's third row and column off the diagonal), are within this of zero. Our writer
#: writes exact zeros; 1e-6 admits other tools' rounding (a 3-D pipeline printing 1e-9 or a
#: quaternion normalised in float32, ~6e-8) while a real tilt of 1e-6 rad (0.2 arc seconds) or
#: a height of 1 um is below anything a 2-D pose could use.
PLANAR_TOLERANCE = 1e-6

#: A quaternion is refused (its row skipped) when its norm differs from 1 by more than this:
#: text with four or more decimals keeps the norm within 1e-3; a larger error is not a rotation.
QUATERNION_NORM_TOLERANCE = 1e-3

_FORMAT = "%.9f"


@dataclass
class Trajectory:
    """A trajectory read from a file.

    timestamps (N,) s; poses (N, 3) ``(x m, y m, theta rad)``, theta wrapped to (-pi, pi];
    format: the file's ("tum", "kitti" or "xyt"); projected_rows: TUM / KITTI rows that were not
    planar (a height or a tilt beyond ``PLANAR_TOLERANCE``), read as their 2-D projection (x, y
    and the yaw of the rotation); skipped_rows: unreadable rows the reader skipped, and
    skipped_lines the line numbers of the first ``io._files.MAX_REPORTED_LINES`` of them;
    times_from_index: KITTI without a times file, the row index taken as the time.
    """

    timestamps: np.ndarray
    poses: np.ndarray
    format: str
    projected_rows: int = 0
    skipped_rows: int = 0
    skipped_lines: List[int] = field(default_factory=list)
    times_from_index: bool = False

    def __len__(self) -> int:
        return int(self.timestamps.shape[0])


def kitti_times_path(path: PathLike) -> str:
    """The times file beside a KITTI poses file: ``NAME_times.txt`` for ``NAME.kitti`` (or for
    ``NAME.txt``, ``NAME`` ...), one timestamp (s) per line."""
    return os.path.splitext(file_path(path))[0] + "_times.txt"


def _checked(timestamps: object, poses: object):
    ts = real_array(timestamps, "timestamps", (None,))
    ps = real_array(poses, "poses", (len(ts), 3))
    return ts, ps


def _rotations(theta: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations about z by theta."""
    r = np.zeros((len(theta), 3, 3))
    r[:, :2, :2], r[:, 2, 2] = geometry.rotations(theta), 1.0
    return r


def write_trajectory(timestamps: object, poses: object, path: PathLike, format: str = "tum") -> List[str]:
    """Write a 2-D trajectory: timestamps (N,) s, poses (N, 3) ``(x, y, theta)`` (m, rad), both
    finite, in ``format`` ("tum", "kitti" or "xyt", see the module's docstring). Returns the
    files written: the path, and for KITTI its times file (``kitti_times_path``).

    Errors: ``TypeError`` / ``ValueError`` naming the argument for anything but finite real
    arrays of those shapes or an unknown format; the file's own ``OSError``."""
    if format not in TRAJECTORY_FORMATS:
        raise ValueError(f"format must be one of {', '.join(map(repr, TRAJECTORY_FORMATS))}, got {format!r}")
    ts, ps = _checked(timestamps, poses)
    path = file_path(path)
    theta = wrap_angle(ps[:, 2]) if len(ps) else ps[:, 2]
    n = len(ts)
    if format == "xyt":
        np.savetxt(path, np.column_stack([ts, ps[:, :2], theta]), fmt=_FORMAT, header="timestamp x y theta")
        return [path]
    if format == "tum":
        half = 0.5 * theta
        rows = np.column_stack([ts, ps[:, :2], np.zeros((n, 3)), np.sin(half), np.cos(half)])
        np.savetxt(path, rows, fmt=_FORMAT, header="timestamp x y z qx qy qz qw")
        return [path]
    matrices = np.concatenate([_rotations(theta), np.column_stack([ps[:, :2], np.zeros(n)])[:, :, None]], axis=2)
    # KITTI's poses files have no header (evo and the devkit read every line as numbers).
    np.savetxt(path, matrices.reshape(n, 12), fmt=_FORMAT)
    times = kitti_times_path(path)
    np.savetxt(times, ts, fmt=_FORMAT)
    return [path, times]


def write_trajectory_3d(timestamps: object, poses: object, path: PathLike, format: str = "tum") -> List[str]:
    """Write a 3-D trajectory: timestamps (N,) s, poses (N, 7) ``(x, y, z, qx, qy, qz, qw)`` (m, a
    unit quaternion; ``PoseGraph3D.poses``), as TUM rows or KITTI [R | t] rows with the times
    file beside them (``format`` "tum" or "kitti"; "xyt" has no room for a 3-D pose: ValueError).
    Returns the files written. Errors as ``write_trajectory``, and ValueError naming ``poses`` for
    a quaternion further than ``QUATERNION_NORM_TOLERANCE`` from unit norm."""
    if format not in ("tum", "kitti"):
        raise ValueError(f"format must be 'tum' or 'kitti' for a 3-D trajectory, got {format!r}")
    ts = real_array(timestamps, "timestamps", (None,))
    ps = real_array(poses, "poses", (len(ts), 7))
    q = ps[:, 3:7]
    norms = np.linalg.norm(q, axis=1)
    if len(ps) and np.max(np.abs(norms - 1.0)) > QUATERNION_NORM_TOLERANCE:
        raise ValueError("poses must hold unit quaternions (columns 3-6, x y z w)")
    path = file_path(path)
    if format == "tum":
        np.savetxt(path, np.column_stack([ts, ps]), fmt=_FORMAT, header="timestamp x y z qx qy qz qw")
        return [path]
    x, y, z, w = (q / norms[:, None]).T
    r = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                  2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                  2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=1).reshape(-1, 3, 3)
    matrices = np.concatenate([r, ps[:, :3, None]], axis=2)
    np.savetxt(path, matrices.reshape(len(ts), 12), fmt=_FORMAT)
    times = kitti_times_path(path)
    np.savetxt(times, ts, fmt=_FORMAT)
    return [path, times]


def _quaternion_check(values: List[float]) -> str:
    norm = float(np.linalg.norm(values[4:8]))
    return "" if abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE else f"quaternion norm {norm:g}, not 1"


def _rotation_check(values: List[float]) -> str:
    r = np.array(values).reshape(3, 4)[:, :3]
    error = float(np.max(np.abs(r.T @ r - np.eye(3))))
    # The same bound as a quaternion's norm: a matrix printed with four decimals is within it.
    return "" if error <= QUATERNION_NORM_TOLERANCE and np.linalg.det(r) > 0 else "not a rotation matrix"


def _tum_poses(table: np.ndarray):
    """(timestamps, poses, non-planar rows) of TUM rows."""
    q = table[:, 4:8] / np.linalg.norm(table[:, 4:8], axis=1, keepdims=True)
    qx, qy, qz, qw = q.T
    # The yaw of the ZYX (yaw, pitch, roll) angles: the heading of the rotated x axis projected
    # on the ground plane, which is the 2-D pose's theta for a planar rotation.
    yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    tilted = (np.abs(table[:, 3]) > PLANAR_TOLERANCE) | (np.abs(qx) > PLANAR_TOLERANCE) | (np.abs(qy) > PLANAR_TOLERANCE)
    return table[:, 0], np.column_stack([table[:, 1:3], yaw]), int(np.count_nonzero(tilted))


def _kitti_poses(table: np.ndarray):
    """(poses, non-planar rows) of KITTI rows."""
    m = table.reshape(-1, 3, 4)
    yaw = np.arctan2(m[:, 1, 0], m[:, 0, 0])
    tilt = np.abs(np.stack([m[:, 0, 2], m[:, 1, 2], m[:, 2, 0], m[:, 2, 1], m[:, 2, 3]], axis=1))
    tilted = np.any(tilt > PLANAR_TOLERANCE, axis=1)
    return np.column_stack([m[:, 0, 3], m[:, 1, 3], yaw]), int(np.count_nonzero(tilted))


def _kitti_times(path: str, times_path: Optional[str], ordinals: np.ndarray, rows: int):
    """The times of a KITTI file's readable rows from its times file, one time for each of the
    file's ``rows`` rows (``ordinals``: the readable rows' places among them, so that a skipped
    pose row drops its time), or None when there is no times file."""
    if times_path is None:
        times_path = kitti_times_path(path)
        if not os.path.isfile(times_path):
            return None
    times = numeric_rows(file_path(times_path, "times_path"), (1,), "time")
    if times.skipped:
        raise ValueError(f"{times_path}: {times.skipped} unreadable time rows (first line "
                         f"{times.skipped_lines[0]}: {times.first_reason}); a time row cannot be skipped without "
                         f"shifting every later pose's time")
    if len(times.table) != rows:
        raise ValueError(f"{times_path}: {len(times.table)} times for the {rows} rows of {path}")
    return times.table[ordinals, 0]


def read_trajectory(path: PathLike, format: str = "auto", times_path: Optional[PathLike] = None) -> Trajectory:
    """Read a trajectory file written by ``write_trajectory`` or another tool.

    format: "tum" (8 numbers a row), "kitti" (12), "xyt" (4) or "auto": the field count of the
    first row of numbers decides. ``#`` starts a comment and blank lines are ignored. A TUM or
    KITTI row that is not planar is read as its 2-D projection (x, y and the yaw of the rotation),
    counted in ``projected_rows`` and announced by a warning. KITTI times come from
    ``times_path`` (default: ``kitti_times_path(path)`` when that file exists; else the row
    index, ``times_from_index``, with a warning); the times file must have one time per row of
    the poses file.

    Timestamps that decrease (a clock jump in a real log) are kept in the file's order, with a
    warning.

    Errors: a missing file raises ``FileNotFoundError``; a path that is not a regular file or a
    file with no readable row raises ``ValueError`` naming the file.
    Row-level, as the other readers: rows with another field count, words, NaN or inf, a
    quaternion whose norm is not 1 (within ``QUATERNION_NORM_TOLERANCE``) or a KITTI matrix that
    is not a rotation are skipped, counted in ``skipped_rows`` and announced by one warning
    naming the first line numbers.
    """
    path = file_path(path)
    if format != "auto" and format not in TRAJECTORY_FORMATS:
        raise ValueError(f"format must be 'auto' or one of {', '.join(map(repr, TRAJECTORY_FORMATS))}, "
                         f"got {format!r}")
    require_regular_file(path)
    counts = tuple(_FIELDS.values()) if format == "auto" else (_FIELDS[format],)
    checks = {8: _quaternion_check, 12: _rotation_check}
    read = numeric_rows(path, counts, "trajectory", lambda values: checks.get(len(values), lambda v: "")(values))
    read.warn(path, "trajectory")
    table = read.table
    kind = {n: name for name, n in _FIELDS.items()}[table.shape[1]]
    projected, from_index = 0, False
    if kind == "xyt":
        ts, ps = table[:, 0], table[:, 1:4].copy()
    elif kind == "tum":
        ts, ps, projected = _tum_poses(table)
    else:
        ps, projected = _kitti_poses(table)
        ts = _kitti_times(path, None if times_path is None else file_path(times_path, "times_path"), read.ordinals,
                          len(table) + read.skipped)
        if ts is None:
            from_index = True
            ts = read.ordinals.astype(float)
            warnings.warn(f"{path}: KITTI poses carry no time and {kitti_times_path(path)} does not exist: "
                          f"the row index is taken as the time", stacklevel=2)
    if projected:
        warnings.warn(f"{path}: {projected} of {len(table)} rows are not planar (a height or a tilt beyond "
                      f"{PLANAR_TOLERANCE:g}): read as their 2-D projection (x, y and the yaw)", stacklevel=2)
    decreasing = np.flatnonzero(np.diff(ts) < 0)
    if decreasing.size:
        # Real logs have clock jumps (the bundled Intel log steps back 1 s); evo reads such files
        # and associates them by a linear search, as ``eval.associate`` does.
        i = int(decreasing[0])
        before, after = distinct_numbers(ts[i], ts[i + 1])
        warnings.warn(f"{path}: timestamps decrease {decreasing.size} times, first at line {read.lines[i + 1]} "
                      f"({before} then {after}); kept in the file's order", stacklevel=2)
    ps[:, 2] = wrap_angle(ps[:, 2])
    return Trajectory(np.ascontiguousarray(ts, dtype=float), np.ascontiguousarray(ps), kind, projected,
                      read.skipped, read.skipped_lines, from_index)


#: Fields of a row of positions with times: ``t x y``.
POSITION_FIELDS = 3


@dataclass
class Positions:
    """Positions with times read from a file (``read_positions``), such as a GPS track.

    timestamps (G,) s, in the file's order; positions (G, 2) ``(x, y)`` m; skipped_rows:
    unreadable rows the reader skipped, and skipped_lines the line numbers of the first
    ``io._files.MAX_REPORTED_LINES`` of them."""

    timestamps: np.ndarray
    positions: np.ndarray
    skipped_rows: int = 0
    skipped_lines: List[int] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.timestamps.shape[0])


def read_positions(path: PathLike) -> Positions:
    """``t x y`` rows (s, m, m) of a text file: a GPS track or any reference without headings.
    ``#`` starts a comment and blank lines are ignored.

    Errors: a missing file raises ``FileNotFoundError``; a path that is not a regular file or a
    file with no readable row raises ``ValueError`` naming the file. Row-level, as the other
    readers: rows with another field count, words, NaN or inf are skipped, counted in
    ``skipped_rows`` and announced by one warning naming the first line numbers."""
    path = file_path(path)
    require_regular_file(path)
    read = numeric_table(path, POSITION_FIELDS, "position")
    read.warn(path, "position")
    return Positions(np.ascontiguousarray(read.table[:, 0]), np.ascontiguousarray(read.table[:, 1:3]),
                     read.skipped, read.skipped_lines)


def first_row_fields(path: PathLike) -> int:
    """The number of fields of the first row of a text file that is not blank or a comment
    (``#``), 0 when there is none: what a reader in format "auto" decides by."""
    path = file_path(path)
    require_regular_file(path)
    for _, line in text_lines(path):
        fields = line.split("#", 1)[0].split()
        if fields:
            return len(fields)
    return 0


__all__ = ["EXTENSIONS", "PLANAR_TOLERANCE", "POSITION_FIELDS", "Positions", "QUATERNION_NORM_TOLERANCE",
           "TRAJECTORY_FORMATS", "Trajectory", "first_row_fields", "kitti_times_path", "read_positions",
           "read_trajectory", "write_trajectory"]
