"""Readers for landmark SLAM datasets: UTIAS MRCLAM, Victoria Park (iSAM / GTSAM text) and the
original Victoria Park run (ACFR: vehicle inputs, tree detections, GPS)."""

from __future__ import annotations

import dataclasses
import math
import os
import pathlib
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple, Union

import numpy as np

from .. import _core
from ._files import file_path, numeric_table, require_regular_file, text_lines

PathLike = Union[str, "os.PathLike[str]"]

#: MRCLAM subjects 1-5 are robots, 6-20 landmarks.
MRCLAM_LANDMARK_SUBJECTS = range(6, 21)

#: MRCLAM's "range" is the landmark's distance along the camera's optical axis (its depth), not
#: its distance from the robot: against Dataset 7's Vicon poses the distance is
#: MRCLAM_RANGE_SCALE * range / cos(bearing). The raw range is 0.09 m long at the image centre
#: and 0.31 m short at its edges; corrected, the robust std-dev of the range error falls from
#: 0.067 m to 0.021 m. Fitted by ``datasets.mrclam.fit_range_scale`` on Dataset 7, robot 1; on
#: Dataset 1 it shrinks the pose-free same-scan distance residuals from 0.091 m to 0.035 m.
MRCLAM_RANGE_SCALE = 0.971


#: A data file (odometry, measurements, ground truth) may hold a few unreadable rows (a line cut
#: short when the logger stopped, a corrupt number): they are skipped and counted. More than this
#: fraction of a file's rows means it is not in the format we read, and the file is refused. One
#: limit for every reader, the C++ ones included (kMaxBadRowFraction).
MAX_BAD_ROW_FRACTION = _core.MAX_BAD_ROW_FRACTION


class _Rows:
    """Rows read from one text file, the first error of each kind kept for the message."""

    def __init__(self, path: str):
        self.path, self.rows, self.bad, self.first_error = path, [], 0, None

    def skip(self, number: int, reason: str) -> None:
        self.bad += 1
        if self.first_error is None:
            self.first_error = f"{self.path}:{number}: {reason}"

    def check(self, strict: bool) -> None:
        """Raise the first error if any row was bad (strict) or too many were."""
        if self.bad and (strict or self.bad > MAX_BAD_ROW_FRACTION * (len(self.rows) + self.bad)):
            raise ValueError(self.first_error if strict else
                             f"{self.first_error} ({self.bad} of {len(self.rows) + self.bad} rows unreadable, "
                             f"more than MAX_BAD_ROW_FRACTION = {MAX_BAD_ROW_FRACTION})")


def _numbers(fields: List[str]) -> Optional[List[float]]:
    """The fields as finite floats, or None (Python's float() also takes 'nan', 'inf', '1_0')."""
    try:
        values = [float(x) for x in fields]
    except ValueError:
        return None
    if not all(map(math.isfinite, values)) or any("_" in x for x in fields):
        return None
    return values


def _table(path: PathLike, columns: int, strict: bool = False) -> Tuple[np.ndarray, int]:
    """Rows of `columns` finite numbers from a text file ('#' starts a comment) and the number of
    rows skipped as unreadable; ``strict``: any unreadable row is an error naming its line."""
    path = file_path(path)
    require_regular_file(path)
    rows = _Rows(path)
    for number, line in text_lines(path):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        values = _numbers(fields)
        if len(fields) != columns:
            rows.skip(number, f"expected {columns} fields, got {len(fields)}")
        elif values is None:
            rows.skip(number, f"not {columns} finite numbers: {line.strip()[:80]!r}")
        else:
            rows.rows.append(values)
    rows.check(strict)
    return np.array(rows.rows, float).reshape(-1, columns), rows.bad


def _subject_of(folder: pathlib.Path) -> Dict[int, int]:
    """Barcodes.dat: barcode -> subject, both integers (the map's key: read strictly)."""
    table, _ = _table(folder / "Barcodes.dat", 2, strict=True)
    if not np.all((table == np.round(table)) & (np.abs(table) < 2 ** 31)):
        raise ValueError(f"{folder / 'Barcodes.dat'}: subjects and barcodes must be integers")
    return {int(b): int(s) for s, b in table}


@dataclass
class Mrclam:
    """One robot of a UTIAS MRCLAM dataset. Times in seconds, metres, radians.

    odometry: (M, 3) ``(t, v, w)``; measurements: (K, 4) ``(t, subject, range, bearing)`` of
    landmarks only (other robots' barcodes removed; barcodes mapped to subjects);
    groundtruth: (G, 4) ``(t, x, y, theta)`` or None; landmarks: (15, 3) ``(subject, x, y)``.
    """

    odometry: np.ndarray
    measurements: np.ndarray
    groundtruth: Optional[np.ndarray]
    landmarks: np.ndarray
    robot_measurements: int  # sightings of other robots that were dropped
    #: rows skipped while reading, by reason: "<file>: barcode not in Barcodes.dat" (a barcode
    #: the data's own table does not list), "<file>: unreadable" (see ``read_mrclam``)
    skipped_rows: Dict[str, int] = field(default_factory=dict)

    def scans(self) -> List[slice]:
        """Row slices of ``measurements`` sharing one time stamp (one camera frame each; the rows
        are sorted by time)."""
        if len(self.measurements) == 0:
            return []
        starts = np.flatnonzero(np.r_[True, np.diff(self.measurements[:, 0]) != 0])
        return [slice(a, b) for a, b in zip(starts, np.r_[starts[1:], len(self.measurements)])]

    @property
    def landmark_positions(self) -> Dict[int, np.ndarray]:
        """Surveyed landmark positions: subject id -> (2,) x, y in metres (Landmark_Groundtruth.dat)."""
        return {int(s): xy for s, xy in zip(self.landmarks[:, 0], self.landmarks[:, 1:3])}

    def with_survey_swapped(self, pairs) -> "Mrclam":
        """A copy whose surveyed positions of each subject pair ``(a, b)`` are exchanged, for data
        whose survey labels disagree with the barcodes (Dataset 1: subjects 11 and 17, see
        ``datasets.mrclam.survey_label_swaps``). Measurements are left as the robot saw them."""
        landmarks = self.landmarks.copy()
        row = {int(s): k for k, s in enumerate(landmarks[:, 0])}
        for a, b in pairs:
            if int(a) not in row or int(b) not in row:
                raise ValueError(f"pairs: subjects must be surveyed landmarks, got ({a}, {b})")
            ka, kb = row[int(a)], row[int(b)]
            landmarks[[ka, kb], 1:] = landmarks[[kb, ka], 1:]
        return dataclasses.replace(self, landmarks=landmarks)

    def with_euclidean_ranges(self, scale: float = MRCLAM_RANGE_SCALE) -> "Mrclam":
        """A copy whose ranges are distances from the robot, ``scale * range / cos(bearing)``,
        for MRCLAM's camera, which reports depth along its axis (see ``MRCLAM_RANGE_SCALE``)."""
        scale = float(scale)
        if not np.isfinite(scale) or scale <= 0:
            raise ValueError(f"scale: must be finite and > 0, got {scale}")
        m = self.measurements.copy()
        if len(m) and not np.all(np.abs(m[:, 3]) < np.pi / 2):
            raise ValueError("measurements: a depth reading needs |bearing| < pi/2 (in front of the camera)")
        with np.errstate(over="ignore"):
            m[:, 2] *= scale / np.cos(m[:, 3])
        if not np.all(np.isfinite(m[:, 2])):
            raise ValueError(f"scale: {scale} makes ranges overflow")
        return dataclasses.replace(self, measurements=m)


def _data_file(folder: pathlib.Path, name: str) -> pathlib.Path:
    """``folder/name``, or ``folder/name.gz`` / ``.bz2`` when only a compressed copy is there (the
    bundled excerpt, ``probslam.data.path("mrclam")``)."""
    for candidate in (name, name + ".gz", name + ".bz2"):
        if (folder / candidate).exists():
            return folder / candidate
    return folder / name


def read_mrclam(folder: PathLike, robot: int = 1) -> Mrclam:
    """Robot ``robot`` (1-5) of the MRCLAM dataset in ``folder``.

    Fatal (``ValueError("file:line: ...")``, ``FileNotFoundError`` for a missing file): any
    unreadable row of Barcodes.dat or Landmark_Groundtruth.dat (they define the map), and more
    than ``MAX_BAD_ROW_FRACTION`` unreadable rows in a data file. Row-level (skipped, counted in
    ``Mrclam.skipped_rows``): a few unreadable rows of the odometry, measurement or ground-truth
    files (wrong field count, not a finite number), and measurements of barcodes missing from
    Barcodes.dat (Dataset 1 robots 3 and 5, Dataset 7 robot 3 hold a few).

    The robot's data files may be compressed (``Robot1_Odometry.dat.gz`` or ``.bz2``).
    """
    folder = pathlib.Path(file_path(folder, "folder"))
    if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 1 <= robot <= 5:
        raise ValueError(f"robot: MRCLAM robots are numbered 1 to 5, got {robot!r}")
    subject_of = _subject_of(folder)
    skipped: Dict[str, int] = {}

    def data_table(name: str, columns: int) -> np.ndarray:
        table, bad = _table(_data_file(folder, name), columns)
        if bad:
            skipped[f"{name}: unreadable"] = bad
        return table

    odometry = data_table(f"Robot{robot}_Odometry.dat", 3)
    raw = data_table(f"Robot{robot}_Measurement.dat", 4)
    known = np.array([b == int(b) and int(b) in subject_of for b in raw[:, 1]], bool).reshape(-1)
    if not known.all():
        skipped[f"Robot{robot}_Measurement.dat: barcode not in Barcodes.dat"] = int(np.count_nonzero(~known))
        raw = raw[known]
    subjects = np.array([subject_of[int(b)] for b in raw[:, 1]], float)
    is_landmark = np.isin(subjects, list(MRCLAM_LANDMARK_SUBJECTS))
    measurements = np.column_stack([raw[:, 0], subjects, raw[:, 2], raw[:, 3]])[is_landmark]
    gt_name = f"Robot{robot}_Groundtruth.dat"
    groundtruth = data_table(gt_name, 4) if _data_file(folder, gt_name).exists() else None
    landmarks = _table(folder / "Landmark_Groundtruth.dat", 5, strict=True)[0][:, :3]
    order = np.argsort(odometry[:, 0], kind="stable")
    return Mrclam(odometry[order], measurements[np.argsort(measurements[:, 0], kind="stable")], groundtruth,
                  landmarks, int(np.count_nonzero(~is_landmark)), skipped)


@dataclass
class VictoriaPark:
    """Victoria Park in iSAM's text format (ODOMETRY / LANDMARK lines), noise as covariances.

    odometry: (E,) edges ``pose_from -> pose_to`` with ``delta`` (E, 3) in the frame of
    ``pose_from`` and ``delta_cov`` (E, 3, 3); observations of landmark ``landmark`` (L,) from
    pose ``pose`` (L,): ``xy`` (L, 2) in the robot frame, ``xy_cov`` (L, 2, 2).
    """

    pose_from: np.ndarray
    pose_to: np.ndarray
    delta: np.ndarray
    delta_cov: np.ndarray
    pose: np.ndarray
    landmark: np.ndarray
    xy: np.ndarray
    xy_cov: np.ndarray
    skipped_rows: int = 0  # unreadable records skipped (see read_victoria_park)
    repaired_rows: int = 0  # records whose noise was not positive definite, repaired (see read_victoria_park)


def _covariances(information: np.ndarray) -> np.ndarray:
    """Covariances (E, n, n) of a stack of information matrices: C = L^-T L^-1 from the Cholesky
    factor L (better conditioned than a general inverse), made exactly symmetric."""
    n = information.shape[-1]
    if len(information) == 0:
        return np.zeros((0, n, n))
    lower_inverse = np.linalg.solve(np.linalg.cholesky(information), np.broadcast_to(np.eye(n), information.shape))
    covariance = np.swapaxes(lower_inverse, -1, -2) @ lower_inverse
    return 0.5 * (covariance + np.swapaxes(covariance, -1, -2))


def _landmark_numbers(graph, points: np.ndarray) -> np.ndarray:
    """The file's own LANDMARK number of each point vertex id in ``points`` (the graph moves
    landmark numbers that meet pose numbers to ids of their own; see PoseGraph2D.landmark_ids)."""
    ids, numbers = graph.point_ids, graph.landmark_ids
    order = np.argsort(ids, kind="stable")
    return numbers[order][np.searchsorted(ids[order], points)].astype(np.int64)


def isam_noise_convention(path: PathLike) -> str:
    """What an iSAM text file's noise entries hold, by the one convention that tells the two
    published copies apart: 'covariance' for GTSAM's copy (a name containing 'gtsam', as GTSAM's
    examples/Data files are named), else iSAM's own 'sqrt_information'."""
    return "covariance" if "gtsam" in os.path.basename(os.fspath(path)).lower() else "sqrt_information"


def read_victoria_park(path: PathLike, noise: str = "auto") -> VictoriaPark:
    """``noise``: 'sqrt_information' (iSAM's file: upper-triangular R, covariance (R^T R)^-1),
    'covariance' (GTSAM's copy), or 'auto' (``isam_noise_convention``: covariance if the file name
    contains 'gtsam').

    Read by the C++ iSAM reader (``probslam.graph.read_pose_graph_with_report``, format 'isam',
    rows 'skip'), the edges in file order; EDGE2 records (loop closures) would come out among
    the odometry. Fatal: a missing file (``FileNotFoundError``), a path that is not a regular
    file, and more than ``MAX_BAD_ROW_FRACTION`` unreadable records (``ValueError("file:line:
    ...")`` naming the first). Row-level (skipped, counted in ``VictoriaPark.skipped_rows``): a
    few records of an unknown type, with too few fields, numbers that are not finite, ids that
    are not int32 integers, or a noise matrix with no positive eigenvalue. A noise matrix that is
    symmetric but not positive definite is repaired under the pose-graph readers' information
    repair (docs/pose_graphs.md: eigenvalues raised to a floor), counted in
    ``VictoriaPark.repaired_rows``. A skipped ODOMETRY
    record leaves the poses after it unreachable: their records are skipped too (so, usually,
    fatal)."""
    path = file_path(path)
    if noise == "auto":
        noise = isam_noise_convention(path)
    if noise not in ("sqrt_information", "covariance"):
        raise ValueError(f"noise must be 'sqrt_information', 'covariance' or 'auto', got {noise!r}")
    graph, report = _core.read_pose_graph_with_report(path, "isam", noise, "skip")
    ends, delta, information = graph.pose_edges()
    points, xy, xy_information = graph.point_edges()
    return VictoriaPark(ends[:, 0].astype(np.int64), ends[:, 1].astype(np.int64), delta, _covariances(information),
                        points[:, 0].astype(np.int64), _landmark_numbers(graph, points[:, 1]), xy,
                        _covariances(xy_information), int(report.skipped_rows), int(report.repaired_rows))


#: The files of the original Victoria Park run (``read_victoria_park_acfr``): the vehicle's
#: inputs and the tree detections, which a folder must hold, and the GPS fixes, which it may.
VICTORIA_PARK_ACFR_FILES = ("inputs.dat", "measurements.dat")
VICTORIA_PARK_ACFR_GPS = "gps.dat"


@dataclass
class VictoriaParkAcfr:
    """The original Victoria Park run (ACFR, University of Sydney; Guivant and Nebot), as the
    dataset's README describes it: one time base (seconds), metres, radians; each table sorted by
    time (stably: rows of one time keep the file's order).

    inputs: (N, 3) ``(t, speed, steering)``: the rear left wheel's encoder speed (m/s) and the
    steering angle (rad, positive left), 40 Hz. measurements: (K, 4) ``(t, range, bearing,
    diameter)``: a tree's range to its trunk's centre (m), its bearing in the vehicle frame
    (rad, 0 ahead, positive to the left, wrapped to (-pi, pi]: the file's detector angle minus
    pi/2), the trunk's diameter (m). The detections of one laser scan share its time: scan ``s``
    is ``measurements[scan_starts[s]:scan_starts[s + 1]]`` (``scan``), taken at
    ``scan_times[s]``; scans with no tree have no row. gps: (G, 3) ``(t, x, y)``, the GPS
    antenna's position (at the laser) in the GPS's local frame, or None without ``gps.dat``.
    """

    inputs: np.ndarray
    measurements: np.ndarray
    scan_starts: np.ndarray
    gps: Optional[np.ndarray]
    #: rows skipped while reading, by reason: "<file>: unreadable" (a wrong field count, not a
    #: finite number) or "<file>: <the value's fault>" (see ``read_victoria_park_acfr``)
    skipped_rows: Dict[str, int] = field(default_factory=dict)

    @property
    def scan_times(self) -> np.ndarray:
        """(S,) the time of each scan with a detection, increasing."""
        return self.measurements[self.scan_starts[:-1], 0]

    def scan(self, index: int) -> np.ndarray:
        """(n, 4) the rows of scan ``index`` (0 <= index < ``len(scan_times)``), a view."""
        count = len(self.scan_starts) - 1
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < count:
            raise ValueError(f"index: a scan number in [0, {count}), got {index!r}")
        return self.measurements[self.scan_starts[index]:self.scan_starts[index + 1]]


def _acfr_table(folder: pathlib.Path, name: str, columns: int, faults, skipped: Dict[str, int]) -> np.ndarray:
    """The rows of ``folder/name`` (or its .gz / .bz2 copy) sorted by time, unreadable rows and
    rows with a fault (``faults(table)``: (reason, mask) pairs) skipped and counted in ``skipped``;
    more than MAX_BAD_ROW_FRACTION of them raise naming the first."""
    path = str(_data_file(folder, name))
    require_regular_file(path)
    read = numeric_table(path, columns, name)
    first = (read.skipped_lines[0], read.first_reason) if read.skipped else None
    if read.skipped:
        skipped[f"{name}: unreadable"] = read.skipped
    keep = np.ones(len(read.table), bool)
    for reason, fault in faults(read.table):
        fault &= keep
        if fault.any():
            skipped[f"{name}: {reason}"] = int(np.count_nonzero(fault))
            line = int(read.lines[np.argmax(fault)])
            first = min(first, (line, reason)) if first else (line, reason)
            keep &= ~fault
    bad = read.skipped + int(np.count_nonzero(~keep))
    if bad > MAX_BAD_ROW_FRACTION * (len(read.table) + read.skipped):
        raise ValueError(f"{path}:{first[0]}: {first[1]} ({bad} of {len(read.table) + read.skipped} rows "
                         f"skipped, more than MAX_BAD_ROW_FRACTION = {MAX_BAD_ROW_FRACTION})")
    table = read.table[keep]
    return table[np.argsort(table[:, 0], kind="stable")]


def _input_faults(table: np.ndarray):
    # tan(steering) must be finite: the wheels turn less than a right angle either way.
    return [("steering not in (-pi/2, pi/2)", ~(np.abs(table[:, 2]) < np.pi / 2))]


def _measurement_faults(table: np.ndarray):
    return [("range not > 0", ~(table[:, 1] > 0)),
            ("bearing not in [0, pi] (the detector's angle across the scan)",
             ~((table[:, 2] >= 0) & (table[:, 2] <= np.pi))),
            ("diameter < 0", ~(table[:, 3] >= 0))]


def read_victoria_park_acfr(folder: PathLike) -> VictoriaParkAcfr:
    """The original Victoria Park run in ``folder``: ``inputs.dat`` (``t speed steering``),
    ``measurements.dat`` (``t range bearing diameter``, the bearing the detector's angle from 0
    at the vehicle's right to pi at its left) and, when present, ``gps.dat`` (``t x y``); each
    may be compressed (``.gz`` / ``.bz2``). Files of clean rows are parsed at numpy's speed
    (``io._files.numeric_table``).

    Fatal (``FileNotFoundError`` for a missing inputs.dat or measurements.dat, ``ValueError``
    naming the file): a path that is not a regular file, a file with no readable row, and more
    than ``MAX_BAD_ROW_FRACTION`` of a file's rows skipped (naming the first line). Row-level
    (skipped, counted in ``VictoriaParkAcfr.skipped_rows``): rows with another field count or
    not finite numbers; inputs with a steering angle not in (-pi/2, pi/2); detections with a
    range not > 0, a bearing outside [0, pi] or a negative diameter."""
    folder = pathlib.Path(file_path(folder, "folder"))
    skipped: Dict[str, int] = {}
    inputs = _acfr_table(folder, "inputs.dat", 3, _input_faults, skipped)
    measurements = _acfr_table(folder, "measurements.dat", 4, _measurement_faults, skipped)
    measurements[:, 2] = _core.wrap_angle(measurements[:, 2] - np.pi / 2)
    starts = np.flatnonzero(np.r_[True, np.diff(measurements[:, 0]) != 0]) if len(measurements) else []
    scan_starts = np.r_[starts, len(measurements)].astype(np.int64)
    gps = None
    if _data_file(folder, VICTORIA_PARK_ACFR_GPS).exists():
        gps = _acfr_table(folder, VICTORIA_PARK_ACFR_GPS, 3, lambda table: [], skipped)
    return VictoriaParkAcfr(inputs, measurements, scan_starts, gps, skipped)
