"""What a landmark SLAM run returns (``LandmarkSlamResult``, for every filter and dataset), and EKF
SLAM along a chain of relative poses: over a pose/landmark graph (``run_ekf_on_graph``, the
``"ekf"`` start of ``graph.initialize``) or a dataset given as such a chain (Victoria Park).

The drivers of the datasets are in ``probslam.datasets``, their scores in ``probslam.eval``.
Units: metres, radians, seconds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Dict, Optional

import numpy as np

from ._args import real_array, require_instance
from ._progress import progress_range
from ._core import PoseGraph2D
from .ekf import EkfSlam


@dataclass(frozen=True)
class Associations:
    """The data association of a run with hidden correspondences, one entry per sighting in the
    order the filter took them (for a particle filter: the best particle's, along its lineage).

    times: (K,) the stamp of the sighting's scan (s; for a chain of poses, the pose's index);
    truth: (K,) int64, the dataset's own label of the sighting (its barcode's subject, its
    landmark number); ids: (K,) int64, the filter landmark it was applied to, -1 when it was not
    put in the map (discarded as clutter, kept provisional or left unassociated).
    """

    times: np.ndarray
    truth: np.ndarray
    ids: np.ndarray

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    @property
    def applied(self) -> int:
        """How many sightings were put in the map (associated or starting a landmark)."""
        return int(np.count_nonzero(self.ids >= 0))


#: The methods a ``LandmarkSlamResult`` comes from.
METHODS = ("ekf", "mht", "fastslam", "dead-reckoning")


@dataclass(frozen=True)
class LandmarkSlamResult:
    """A landmark SLAM run over a dataset, whatever the filter (``probslam.run_landmark_slam``).

    method: "ekf" (EKF SLAM, Tables 10.1 / 10.2), "mht" (the multiple-hypothesis EKF; its best
    hypothesis), "fastslam" (its best particle) or "dead-reckoning" (predictions only);
    times (T,) s and poses (T, 3): the filtered poses (FastSLAM: the best particle's path);
    landmarks: the map, filter id -> (2,) position in metres; filter: the filter at the end
    (an ``EkfSlam``, for "mht" the best hypothesis's, or a ``FastSlam``); seconds: filter time;
    associations: per sighting, what the filter did with it (hidden correspondences only, else
    None). EKF with known correspondences only: rejected, the sightings the outlier gate
    skipped, and innovations (K, 4), rows ``(t, subject, NIS, used)`` per sighting (NIS NaN at a
    first sighting; used 0 where the gate rejected it).
    """

    method: str
    times: np.ndarray
    poses: np.ndarray
    landmarks: Dict[int, np.ndarray]
    filter: Any
    seconds: float = 0.0
    associations: Optional[Associations] = None
    rejected: int = 0
    innovations: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))


def ekf_landmarks(ekf: EkfSlam) -> Dict[int, np.ndarray]:
    """An EkfSlam's map: landmark id -> (2,) position."""
    return {int(i): ekf.landmark(i)[:2] for i in ekf.landmarks().ids}


def polar_measurements(xy: np.ndarray, xy_cov: np.ndarray):
    """Robot-frame points (L, 2) with covariances (L, 2, 2) as range-bearing (L, 2) with
    covariances (L, 2, 2), through the Jacobian of (r, phi) = (|p|, atan2(p_y, p_x))."""
    xy = real_array(xy, "xy", (None, 2))
    xy_cov = real_array(xy_cov, "xy_cov", (len(xy), 2, 2))
    r = np.hypot(xy[:, 0], xy[:, 1])
    if np.any(r == 0.0):
        raise ValueError("xy: a point at the origin has no bearing")
    z = np.column_stack([r, np.arctan2(xy[:, 1], xy[:, 0])])
    j = np.stack([np.column_stack([xy[:, 0] / r, xy[:, 1] / r]),
                  np.column_stack([-xy[:, 1] / r ** 2, xy[:, 0] / r ** 2])], axis=1)
    return z, j @ xy_cov @ j.transpose(0, 2, 1)


def ekf_along_chain(delta: np.ndarray, delta_cov: np.ndarray, observed_from: np.ndarray, z: np.ndarray,
                    z_cov: np.ndarray, landmark: np.ndarray, measurement_noise=None,
                    initial_pose=(0.0, 0.0, 0.0), progress: Optional[bool] = False) -> LandmarkSlamResult:
    """EKF SLAM with known correspondences along a chain of P poses: ``delta`` (P-1, 3) relative
    poses with covariances (P-1, 3, 3); observation k (robot-frame range-bearing ``z[k]``, polar
    covariance ``z_cov[k]``) of landmark ``landmark[k]`` is made from chain pose
    ``observed_from[k]``. The filter takes one Q_t: the median of ``z_cov`` unless given; the
    chain starts at ``initial_pose``, known exactly. ``times`` are the chain positions.
    ``progress``: a bar over the poses (None: on a terminal only)."""
    t0 = time.perf_counter()
    q = np.median(z_cov, axis=0) if measurement_noise is None else np.asarray(measurement_noise, float)
    ekf = EkfSlam(np.eye(3) * 1e-6, 0.5 * (q + q.T), use_signatures=False, initial_pose=initial_pose)
    order = np.argsort(observed_from, kind="stable")
    bounds = np.searchsorted(observed_from[order], np.arange(len(delta) + 2))
    poses = np.empty((len(delta) + 1, 3))
    for k in progress_range(len(delta) + 1, "EKF SLAM", "pose", progress):
        if k > 0:
            ekf.predict_odometry(delta[k - 1], delta_cov[k - 1])
        rows = order[bounds[k]:bounds[k + 1]]
        if len(rows):
            ekf.update(z[rows], landmark[rows])
        poses[k] = ekf.pose
    return LandmarkSlamResult("ekf", np.arange(len(poses), dtype=float), poses, ekf_landmarks(ekf), ekf,
                              time.perf_counter() - t0)


def run_ekf_on_graph(graph, measurement_noise=None) -> LandmarkSlamResult:
    """EKF SLAM over a pose/landmark graph (``probslam.graph.PoseGraph2D``): the poses in the
    order they were added form the chain, each consecutive pair linked by a pose edge (the
    odometry, its covariance the inverse information); the point edges are the landmark
    observations, converted to range-bearing. Other pose edges (loop closures) are ignored.
    The filter starts, certain, at the first pose's current value.
    ``poses`` follow ``graph.pose_ids``; ``landmarks`` maps point ids to positions."""
    require_instance(graph, PoseGraph2D, "graph")
    chain = np.asarray(graph.pose_ids)
    if len(chain) < 2 or graph.num_point_edges == 0:
        raise ValueError("graph: the EKF needs at least two poses and one point edge")
    ends, delta, info = graph.pose_edges()
    edge_of = {(int(a), int(b)): k for k, (a, b) in enumerate(ends)}
    links = [edge_of.get((int(a), int(b)), -1) for a, b in zip(chain[:-1], chain[1:])]
    if min(links) < 0:
        k = links.index(-1)
        raise ValueError(f"graph: no pose edge from pose {chain[k]} to the next pose {chain[k + 1]}; "
                         "the EKF follows a chain of odometry edges in the order the poses were added")
    point_ends, xy, xy_info = graph.point_edges()
    by_id = np.argsort(chain)
    observed_from = by_id[np.searchsorted(chain[by_id], point_ends[:, 0])]
    z, z_cov = polar_measurements(xy, np.linalg.inv(xy_info))
    return ekf_along_chain(delta[links], np.linalg.inv(info[links]), observed_from, z, z_cov,
                           point_ends[:, 1].astype(np.int64), measurement_noise, graph.poses[0])


__all__ = ["Associations", "LandmarkSlamResult", "METHODS", "ekf_along_chain", "ekf_landmarks", "polar_measurements",
           "run_ekf_on_graph"]
