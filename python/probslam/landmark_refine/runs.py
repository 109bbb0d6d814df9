"""From a filter run over a dataset to the refinement's arrays: odometry composed between the
poses where sightings were taken, the run's labels, its poses at those nodes; and the result of
refining a run."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict

import numpy as np

from .. import geometry
from .problem import UNASSIGNED
from .results import LandmarkRefinement

#: MRCLAM odometry between two scans comes from the velocity motion model with two noise terms
#: (v, w): over one command its covariance has rank 2 (Thrun's eq. 5.9 adds a third term for this
#: reason), so two scans within one command would have no information matrix. Each composed
#: covariance's eigenvalues are raised to at least this fraction of its largest: the directions
#: the model says cannot err get a standard deviation 1e-3 of the largest one's, and information
#: entries stay within a factor 1e6 of each other in a pose, well inside what the factorisation
#: resolves.
ODOMETRY_COVARIANCE_FLOOR = 1e-6


def compose_increments(deltas: np.ndarray, covariances: np.ndarray, nodes: np.ndarray):
    """Relative motions between chain nodes: ``deltas`` (n, 3) move node i to node i + 1 in node
    i's frame, with ``covariances`` (n, 3, 3), independent. For consecutive entries a <= b of
    ``nodes`` (m,), returns node b in node a's frame (m - 1, 3) and its covariance (m - 1, 3, 3)
    (first order: each increment's Jacobian rotates it into a's frame and, for its heading,
    swings the rest of the segment about its end point; a segment a == b is no motion, zero
    covariance). Vectorised over all increments at once: the chain is laid out in node 0's
    frame, each increment's share of its segment's covariance summed per segment."""
    deltas = np.asarray(deltas, float)
    covariances = np.asarray(covariances, float)
    nodes = np.asarray(nodes, np.int64)
    # Unwrapped headings: a segment's turn is the difference of its ends' however many laps.
    heading = np.concatenate([[0.0], np.cumsum(deltas[:, 2])])  # node 0's frame
    position = geometry.accumulate(np.zeros(3), deltas)[:, :2]
    a, b = nodes[:-1], nodes[1:]
    frame = np.zeros((len(a), 3, 3))  # blockdiag(R(heading_a), 1): a's frame in node 0's
    frame[:, :2, :2] = geometry.rotations(heading[a])
    frame[:, 2, 2] = 1.0
    rel = np.empty((len(a), 3))
    rel[:, :2] = np.einsum("nji,nj->ni", frame[:, :2, :2], position[b] - position[a])
    rel[:, 2] = np.arctan2(np.sin(heading[b] - heading[a]), np.cos(heading[b] - heading[a]))
    world = np.zeros((len(a), 3, 3))
    moving = np.flatnonzero(b > a)
    if len(moving):
        i = np.arange(a[moving[0]], b[moving[-1]])
        segment = np.searchsorted(b, i, side="right")  # a[segment] <= i < b[segment]
        g = np.zeros((len(i), 3, 3))
        g[:, :2, :2] = geometry.rotations(heading[i])
        arm = position[b[segment]] - position[i + 1]  # the heading of increment i swings the rest about its end
        g[:, 0, 2], g[:, 1, 2], g[:, 2, 2] = -arm[:, 1], arm[:, 0], 1.0
        world[moving] = np.add.reduceat(g @ covariances[i] @ g.transpose(0, 2, 1), a[moving] - i[0], axis=0)
    cov = frame.transpose(0, 2, 1) @ world @ frame
    return rel, 0.5 * (cov + cov.transpose(0, 2, 1))


def floor_covariances(covariances: np.ndarray) -> np.ndarray:
    """Covariances with eigenvalues raised to ODOMETRY_COVARIANCE_FLOOR of their largest."""
    values, vectors = np.linalg.eigh(covariances)
    values = np.maximum(values, ODOMETRY_COVARIANCE_FLOOR * values[:, -1:])
    return np.einsum("nij,nj,nkj->nik", vectors, values, vectors)


@dataclass(frozen=True)
class RefinementInput:
    """The arrays ``refine_landmarks`` takes, built from a run over a dataset, and what scoring
    needs: ``times`` (T,) of the poses (s; chain positions for Victoria Park), ``rows`` (K,) each
    sighting's row in the dataset's measurements, ``truth`` (K,) its true landmark (the barcode's
    subject, Victoria Park's landmark id)."""

    times: np.ndarray
    poses: np.ndarray
    odometry: np.ndarray
    odometry_covariances: np.ndarray
    pose_index: np.ndarray
    measurements: np.ndarray
    labels: np.ndarray
    measurement_noise: np.ndarray
    landmarks: Dict[int, np.ndarray]
    rows: np.ndarray
    truth: np.ndarray

    def arguments(self) -> dict:
        """Keyword arguments of ``refine_landmarks``."""
        return dict(poses=self.poses, odometry=self.odometry, odometry_covariances=self.odometry_covariances,
                    pose_index=self.pose_index, measurements=self.measurements, labels=self.labels,
                    measurement_noise=self.measurement_noise, landmarks=self.landmarks)


def run_labels(run, truth: np.ndarray) -> np.ndarray:
    """Per sighting, the run's landmark (UNASSIGNED where it put the sighting on none): from its
    association record (hidden correspondences), else the true ids (known), less the sightings
    an EKF's outlier gate rejected."""
    if run.associations is None:
        labels = truth.astype(np.int64).copy()
        innovations = getattr(run, "innovations", None)
        if innovations is not None and len(innovations) == len(truth):
            labels[innovations[:, 3] == 0] = UNASSIGNED
        return labels
    record = run.associations
    if len(record.ids) != len(truth) or np.any(np.asarray(record.truth) != truth):
        raise ValueError("run: its associations do not follow the data's sightings (was it run on this data?)")
    return np.where(np.asarray(record.ids) >= 0, record.ids, UNASSIGNED).astype(np.int64)


def poses_at_nodes(times: np.ndarray, poses: np.ndarray, chain_times: np.ndarray, chain: np.ndarray) -> np.ndarray:
    """The run's pose at each chain node time: its latest recorded pose at or before it, moved
    on by the dead-reckoned motion since (the run's poses may be recorded at other times than
    the sightings', e.g. the EKF's at the odometry stamps)."""
    # A recorded time matches a node up to rounding (FastSLAM adds dt to the previous stamp).
    k = np.searchsorted(times, chain_times + 1e-9, side="right") - 1
    k = np.clip(k, 0, len(times) - 1)
    node = np.clip(np.searchsorted(chain_times, times[k] + 1e-9, side="right") - 1, 0, len(chain_times) - 1)
    return geometry.compose(poses[k], geometry.between(chain[node], chain))


@dataclass(frozen=True)
class RunRefinement:
    """``refine_run``'s result: the input built from the run, and the refinement."""

    input: RefinementInput
    result: LandmarkRefinement

    def as_landmark_slam_result(self, run):
        """The refinement as a ``LandmarkSlamResult`` of ``run``'s method (poses at the sightings'
        times, the refined map, every sighting's refined label in ``associations``), so the run's
        scores (``probslam.eval``) and writers apply to it; ``filter`` stays the run's."""
        from ..landmark_slam import Associations, LandmarkSlamResult

        sighted = self.input.times[self.input.pose_index]
        record = Associations(sighted, self.input.truth.astype(np.int64), self.result.labels.astype(np.int64))
        return LandmarkSlamResult(run.method, self.input.times, self.result.poses, dict(self.result.landmarks),
                                  run.filter, run.seconds + self.result.seconds, record)
