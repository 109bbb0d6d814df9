"""Readers for landmark SLAM datasets: UTIAS MRCLAM and Victoria Park (iSAM / GTSAM text)."""

from __future__ import annotations

import dataclasses
import os
import pathlib
from dataclasses import dataclass
from typing import Dict, List, Optional, Union

import numpy as np

PathLike = Union[str, "os.PathLike[str]"]

#: MRCLAM subjects 1-5 are robots, 6-20 landmarks.
MRCLAM_LANDMARK_SUBJECTS = range(6, 21)

#: MRCLAM's "range" is the landmark's distance along the camera's optical axis (its depth), not
#: its distance from the robot: against Dataset 7's Vicon poses the distance is
#: MRCLAM_RANGE_SCALE * range / cos(bearing). The raw range is 0.09 m long at the image centre
#: and 0.31 m short at its edges; corrected, the robust std-dev of the range error falls from
#: 0.067 m to 0.021 m. Fitted by ``landmark_slam.fit_range_scale`` on Dataset 7, robot 1; on
#: Dataset 1 it shrinks the pose-free same-scan distance residuals from 0.091 m to 0.035 m.
MRCLAM_RANGE_SCALE = 0.971


def _table(path: PathLike, columns: int) -> np.ndarray:
    """Rows of `columns` numbers from a text file; '#' lines are comments. Errors name the line."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"path: no such file: {path!r}")
    rows: List[List[float]] = []
    with open(path) as f:
        for number, line in enumerate(f, 1):
            text = line.split("#", 1)[0].strip()
            if not text:
                continue
            fields = text.split()
            if len(fields) != columns:
                raise ValueError(f"{path}:{number}: expected {columns} fields, got {len(fields)}")
            try:
                rows.append([float(x) for x in fields])
            except ValueError as exc:
                raise ValueError(f"{path}:{number}: {exc}") from None
    return np.array(rows, float).reshape(-1, columns)


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

    @property
    def landmark_positions(self) -> Dict[int, np.ndarray]:
        return {int(s): xy for s, xy in zip(self.landmarks[:, 0], self.landmarks[:, 1:3])}

    def with_survey_swapped(self, pairs) -> "Mrclam":
        """A copy whose surveyed positions of each subject pair ``(a, b)`` are exchanged, for data
        whose survey labels disagree with the barcodes (Dataset 1: subjects 11 and 17, see
        ``landmark_slam.survey_label_swaps``). Measurements are left as the robot saw them."""
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
        m[:, 2] *= scale / np.cos(m[:, 3])
        return dataclasses.replace(self, measurements=m)


def read_mrclam(folder: PathLike, robot: int = 1) -> Mrclam:
    folder = pathlib.Path(folder)
    barcodes = _table(folder / "Barcodes.dat", 2)
    subject_of = {int(b): int(s) for s, b in barcodes}
    odometry = _table(folder / f"Robot{robot}_Odometry.dat", 3)
    raw = _table(folder / f"Robot{robot}_Measurement.dat", 4)
    unknown = sorted({int(b) for b in raw[:, 1]} - set(subject_of))
    if unknown:
        raise ValueError(f"{folder / f'Robot{robot}_Measurement.dat'}: barcodes not in Barcodes.dat: {unknown}")
    subjects = np.array([subject_of[int(b)] for b in raw[:, 1]], float)
    is_landmark = np.isin(subjects, list(MRCLAM_LANDMARK_SUBJECTS))
    measurements = np.column_stack([raw[:, 0], subjects, raw[:, 2], raw[:, 3]])[is_landmark]
    gt_path = folder / f"Robot{robot}_Groundtruth.dat"
    groundtruth = _table(gt_path, 4) if gt_path.exists() else None
    landmarks = _table(folder / "Landmark_Groundtruth.dat", 5)[:, :3]
    order = np.argsort(odometry[:, 0], kind="stable")
    return Mrclam(odometry[order], measurements[np.argsort(measurements[:, 0], kind="stable")], groundtruth,
                  landmarks, int(np.count_nonzero(~is_landmark)))


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


def _upper(values: List[float], n: int) -> np.ndarray:
    m = np.zeros((n, n))
    m[np.triu_indices(n)] = values
    return m


def read_victoria_park(path: PathLike, noise: str = "auto") -> VictoriaPark:
    """``noise``: 'sqrt_information' (iSAM's file: upper-triangular R, covariance (R^T R)^-1),
    'covariance' (GTSAM's copy), or 'auto' (covariance if the file name contains 'gtsam')."""
    path = os.fspath(path)
    if noise == "auto":
        noise = "covariance" if "gtsam" in os.path.basename(path).lower() else "sqrt_information"
    if noise not in ("sqrt_information", "covariance"):
        raise ValueError(f"noise must be 'sqrt_information', 'covariance' or 'auto', got {noise!r}")

    def covariance(upper: np.ndarray) -> np.ndarray:
        if noise == "covariance":
            return upper + np.triu(upper, 1).T
        return np.linalg.inv(upper.T @ upper)

    odo: List[list] = []
    obs: List[list] = []
    if not os.path.isfile(path):
        raise FileNotFoundError(f"path: no such file: {path!r}")
    with open(path) as f:
        for number, line in enumerate(f, 1):
            fields = line.split()
            if not fields or fields[0].startswith("#"):
                continue
            kind, expected = fields[0], {"ODOMETRY": 12, "LANDMARK": 8}.get(fields[0])
            if expected is None:
                raise ValueError(f"{path}:{number}: unknown record {kind!r}")
            if len(fields) != expected:
                raise ValueError(f"{path}:{number}: {kind} needs {expected} fields, got {len(fields)}")
            try:
                values = [float(x) for x in fields[1:]]
            except ValueError as exc:
                raise ValueError(f"{path}:{number}: {exc}") from None
            if not np.all(np.isfinite(values)):
                raise ValueError(f"{path}:{number}: non-finite value")
            (odo if kind == "ODOMETRY" else obs).append(values + [number])
    o = np.array(odo).reshape(-1, 12)
    b = np.array(obs).reshape(-1, 8)
    delta_cov = np.array([covariance(_upper(r[5:11], 3)) for r in o]).reshape(-1, 3, 3)
    xy_cov = np.array([covariance(_upper(r[4:7], 2)) for r in b]).reshape(-1, 2, 2)
    return VictoriaPark(o[:, 0].astype(np.int64), o[:, 1].astype(np.int64), o[:, 2:5], delta_cov,
                        b[:, 0].astype(np.int64), b[:, 1].astype(np.int64), b[:, 2:4], xy_cov)
