"""Landmark SLAM runs against ground truth: the path and the map against the dataset's robot
truth and landmark survey (MRCLAM)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Optional

import numpy as np

from .._args import real_array, require_fields, require_instance
from ..io.landmark_datasets import Mrclam
from .alignment import align_rigid
from .statistics import rmse


def truth_positions(groundtruth: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(T, 2) ground-truth positions at `times` (linear interpolation of (t, x, y, ...) rows, held
    at the ends; ``interpolate_poses`` is the whole pose, within the span only)."""
    groundtruth = np.asarray(groundtruth)
    if groundtruth.ndim != 2 or groundtruth.shape[1] < 3 or len(groundtruth) == 0:
        raise ValueError(f"groundtruth: expected (T, 3 or more) rows (t, x, y, ...), got shape {groundtruth.shape}")
    times = real_array(times, "times", (None,))
    return np.column_stack([np.interp(times, groundtruth[:, 0], groundtruth[:, 1]),
                            np.interp(times, groundtruth[:, 0], groundtruth[:, 2])])


#: The fields a landmark SLAM result (``probslam.LandmarkSlamResult``) must have to be scored.
_RESULT_FIELDS = ("times", "poses", "landmarks", "associations")


@dataclass
class MrclamScore:
    """Accuracy of an MRCLAM run against ground truth: path and landmark RMSE (m)."""

    path_rmse: float  # m, raw
    path_rmse_aligned: float  # m, after the best rigid alignment of the path to ground truth
    landmark_rmse: float  # m, against the surveyed positions (same frame as the path)
    landmark_rmse_aligned: float  # m, after the path's alignment
    # The path's alignment onto the ground truth, R estimate + t (the "aligned" errors', e.g. to
    # draw the estimate where the scores put it).
    rotation: np.ndarray = field(default_factory=lambda: np.eye(2))  # (2, 2)
    translation: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (2,) m


def score_mrclam(result, data: Mrclam, landmark_map: Optional[Dict[int, int]] = None) -> MrclamScore:
    """``result``: a ``LandmarkSlamResult`` of an MRCLAM robot with ground truth (times (T,),
    poses (T, 3), landmarks {id: (2,)}); ``landmark_map``: filter id -> surveyed subject
    (identity when correspondences were known, e.g. ``majority_labels(result)`` when hidden)."""
    require_fields(result, _RESULT_FIELDS, "result", "a LandmarkSlamResult")
    require_instance(data, Mrclam, "data")
    truth = truth_positions(data.groundtruth, result.times)
    r, t = align_rigid(result.poses[:, :2], truth)
    aligned = result.poses[:, :2] @ r.T + t
    surveyed = data.landmark_positions
    pairs = [(xy, surveyed[(landmark_map or {}).get(i, i)]) for i, xy in result.landmarks.items()
             if (landmark_map or {}).get(i, i) in surveyed]
    est = np.array([p[0] for p in pairs]).reshape(-1, 2)
    sur = np.array([p[1] for p in pairs]).reshape(-1, 2)
    return MrclamScore(rmse(result.poses[:, :2], truth), rmse(aligned, truth),
                       rmse(est, sur) if len(est) else float("nan"),
                       rmse(est @ r.T + t, sur) if len(est) else float("nan"), r, t)


@dataclass
class LandmarkScore:
    """A landmark map against the survey: RMSE (m) as estimated and after rigid alignment."""

    rmse: float  # m, map against the survey as estimated (frames may differ)
    rmse_aligned: float  # m, after the best rigid alignment of the map onto the survey
    errors: Dict[int, float]  # surveyed subject -> aligned error, m
    rotation: np.ndarray = field(default_factory=lambda: np.eye(2))  # (2, 2) R of R m + t ~ survey
    translation: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (2,) t, m

    def survey_in_map_frame(self, data: Mrclam) -> Dict[int, np.ndarray]:
        """Every surveyed landmark of ``data`` brought into the map's frame by the inverse of the
        alignment (subject -> (2,) m), to draw the survey over the map it was compared with."""
        require_instance(data, Mrclam, "data")
        return {s: (np.asarray(p) - self.translation) @ self.rotation for s, p in data.landmark_positions.items()}


def score_landmarks(landmarks: Dict[int, np.ndarray], data: Mrclam,
                    landmark_map: Optional[Dict[int, int]] = None) -> LandmarkScore:
    """The map alone against the survey, for data without robot ground truth (MRCLAM Dataset 1):
    the filter starts at (0, 0, 0), so its frame is the start pose's, and the map is rigidly
    aligned onto the surveyed landmarks. ``landmark_map``: filter id -> subject (identity by
    default). Needs at least two landmarks."""
    require_instance(landmarks, dict, "landmarks")
    require_instance(data, Mrclam, "data")
    surveyed = data.landmark_positions
    pairs = [(i, (landmark_map or {}).get(i, i)) for i in landmarks]
    pairs = [(i, s) for i, s in pairs if s in surveyed]
    if len(pairs) < 2:
        raise ValueError(f"landmarks: need at least two surveyed landmarks to align, got {len(pairs)}")
    est = np.array([landmarks[i] for i, _ in pairs])
    sur = np.array([surveyed[s] for _, s in pairs])
    r, t = align_rigid(est, sur)
    errors = np.hypot(*(est @ r.T + t - sur).T)
    return LandmarkScore(rmse(est, sur), float(np.sqrt(np.mean(errors ** 2))),
                         {s: float(e) for (_, s), e in zip(pairs, errors)}, r, t)
