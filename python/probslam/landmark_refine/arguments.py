"""The checks of ``refine_landmarks``' arrays: shapes, integer indices and labels in range, and
covariances symmetric and invertible in double precision."""

from __future__ import annotations

from typing import Dict

import numpy as np

from .._args import real_array, require_instance, require_integer
from .problem import COVARIANCE_CONDITION_FLOOR, UNASSIGNED, _point_covariances


#: A covariance given whose transpose differs by more than this fraction of its largest entry
#: is refused as not symmetric (rounding in a computed covariance is ~1e-16 relative).
COVARIANCE_SYMMETRY = 1e-9


def _require_invertible(covs: np.ndarray, name: str, what: str = "matrix") -> None:
    """ValueError naming ``name`` and the first covariance of ``covs`` (N, n, n) that is not
    positive definite or not invertible within COVARIANCE_CONDITION_FLOOR."""
    if len(covs) == 0:
        return
    w = np.linalg.eigvalsh(covs)
    bad = np.flatnonzero(~(w[:, 0] > COVARIANCE_CONDITION_FLOOR * np.abs(w[:, -1])))
    if len(bad):
        i = int(bad[0])
        kind = "positive definite" if w[i, 0] <= 0 else f"invertible (eigenvalue ratio above {COVARIANCE_CONDITION_FLOOR:g})"
        raise ValueError(f"{name}: must be positive definite and invertible; {what} {i} is not {kind}: "
                         f"eigenvalues {w[i, 0]:.6g} .. {w[i, -1]:.6g}")



def _integer_vector(value, name: str, k: int) -> np.ndarray:
    """value as a (k,) integer array: TypeError naming it for other dtypes, ValueError for another shape."""
    a = np.asarray(value)
    if a.dtype.kind not in "iu":
        raise TypeError(f"{name}: expected integers, got dtype {a.dtype}")
    if a.shape != (k,):
        raise ValueError(f"{name}: expected shape ({k},), got {a.shape}")
    return a


def _check_input(poses, odometry, odometry_covariances, pose_index, measurements, labels, measurement_noise,
                 landmarks):
    poses = real_array(poses, "poses", (None, 3))
    t = len(poses)
    if t < 1:
        raise ValueError("poses: need at least one pose")
    odometry = real_array(odometry, "odometry", (t - 1, 3))
    odometry_covariances = real_array(odometry_covariances, "odometry_covariances", (t - 1, 3, 3))
    measurements = real_array(measurements, "measurements", (None, 2))
    k = len(measurements)
    if np.any(measurements[:, 0] <= 0):
        raise ValueError(f"measurements: ranges must be > 0 (row {int(np.argmax(measurements[:, 0] <= 0))})")
    index = _integer_vector(pose_index, "pose_index", k)
    if k and (index.min() < 0 or index.max() >= t):
        raise ValueError(f"pose_index: must lie in [0, {t - 1}] (the rows of poses)")
    lab = _integer_vector(labels, "labels", k)
    if k and lab.min() < UNASSIGNED:
        raise ValueError(f"labels: a landmark label is >= 0, {UNASSIGNED} marks a sighting of none; got {lab.min()}")
    q = real_array(measurement_noise, "measurement_noise", None)
    if q.shape == (2, 2):
        q = np.broadcast_to(q, (k, 2, 2))
    elif q.shape != (k, 2, 2):
        raise ValueError(f"measurement_noise: expected shape (2, 2) or ({k}, 2, 2), got {q.shape}")
    for name, covs in (("odometry_covariances", odometry_covariances), ("measurement_noise", q)):
        largest = np.abs(covs).max(axis=(1, 2))[:, None, None] if len(covs) else 0.0
        if len(covs) and np.any(np.abs(covs - covs.transpose(0, 2, 1)) > COVARIANCE_SYMMETRY * largest):
            raise ValueError(f"{name}: must be symmetric")
        _require_invertible(covs, name)
    # The point covariance a sighting gives (a range near 0 makes it singular).
    _require_invertible(_point_covariances(measurements, q), "measurements, measurement_noise", "sighting")
    values: Dict[int, np.ndarray] = {}
    if landmarks is not None:
        require_instance(landmarks, dict, "landmarks")
        for key, value in landmarks.items():
            label = require_integer(key, "landmarks", 0)
            values[label] = real_array(value, f"landmarks[{label}]", (2,))
    return poses, odometry, odometry_covariances, index.astype(np.int64), measurements, lab.astype(np.int64), q, values
