"""The refinement's problem: the linearised measurement (a range-bearing sighting as the point in
the pose's frame with the information of its noise), the state of labels and values, and the
GraphSLAM of the current labels that is optimised and queried for marginals."""

from __future__ import annotations

import collections
from typing import Dict, Tuple

import numpy as np

from .. import geometry
from .._core import PoseGraph2D, marginal_covariances, optimize


#: A given covariance (odometry, measurement noise, and the sighting's point covariance it gives)
#: must be invertible in double precision: its smallest eigenvalue above this fraction of its
#: largest. Below it the inverse is dominated by rounding (an eigenvalue of 1e-16 relative is at
#: the level of one ulp of the entries) and numpy answers "Singular matrix" naming nothing.
COVARIANCE_CONDITION_FLOOR = 1e-13


#: The tests are made at a minimum: the leave-one-out statistic e^T (Q - H Sigma H^T)^-1 e
#: equals the innovation against the other sightings' posterior only where the gradient is zero.
#: Each optimisation runs until its largest step is below this (m, rad); a relative decrease of
#: 1e-10 stopped one 3.6e-5 m short of the minimum on a graph with chi2 5e4, off by 3e-5 in a
#: statistic of 39.
MINIMUM_STEP = 1e-9

#: ... or until an iteration lowers chi2 by less than this fraction, two decades above chi2's
#: rounding: near a minimum of a graph of thousands of poses the steps of its weakest directions
#: stay at rounding level (~1e-8) while chi2 no longer changes (1e-12 stopped 3e-6 m short on a
#: simulated graph of chi2 5e4, off by 2e-7 in a statistic of 0.009). On MRCLAM Dataset 1 robot 5 after a
#: joint-compatibility EKF, Gauss-Newton went from a minimum of chi2 16100 to 9.6e6 when the
#: noise was rescaled by 4%: these optimisations are damped.
MINIMUM_DECREASE = 1e-14

#: The optimisations between two noise estimates stop at this relative decrease of chi2: the
#: factors they feed change by far less than NOISE_TOLERANCE; the optimum the tests are made at
#: is then reached to MINIMUM_STEP.
NOISE_OPTIMIZE_TOLERANCE = 1e-6

UNASSIGNED = -1  # label of a sighting that belongs to no landmark


# ---------------------------------------------------------------------------------------------
# The linearised measurement: a sighting as the point in the pose's frame.


def _point_covariances(measurements: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """The robot-frame point covariances (K, 2, 2) of range-bearing sightings, through the
    Jacobian of (r cos phi, r sin phi)."""
    r, phi = measurements[:, 0], measurements[:, 1]
    c, s = np.cos(phi), np.sin(phi)
    jac = np.stack([np.column_stack([c, -r * s]), np.column_stack([s, r * c])], axis=1)
    cov = jac @ noise @ jac.transpose(0, 2, 1)
    return 0.5 * (cov + cov.transpose(0, 2, 1))


def polar_to_point(measurements: np.ndarray, noise: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Range-bearing (K, 2) with covariances (K, 2, 2) as robot-frame points (K, 2) with their
    information (K, 2, 2)."""
    r, phi = measurements[:, 0], measurements[:, 1]
    return np.column_stack([r * np.cos(phi), r * np.sin(phi)]), np.linalg.inv(_point_covariances(measurements, noise))




# ---------------------------------------------------------------------------------------------
# The refinement.


class _Problem:
    """The refinement's state: the data, the current noise (polar (K, 2, 2) and odometry
    (T - 1, 3, 3) covariances, and what the graph needs of them), labels and values."""

    def __init__(self, poses, odometry, odometry_covariances, pose_index, polar, polar_noise, labels):
        self.poses = poses  # (T, 3) current values
        self.odometry = odometry  # (T - 1, 3)
        self.pose_index = pose_index  # (K,)
        self.polar = polar  # (K, 2) range, bearing
        self.labels = labels  # (K,) current labels
        self.landmarks: Dict[int, np.ndarray] = {}
        # Sighting -> the landmarks it has left: it never goes back to one (see _split_moves).
        self.left: Dict[int, set] = collections.defaultdict(set)
        self.set_noise(odometry_covariances, polar_noise)

    def set_noise(self, odometry_covariances: np.ndarray, polar_noise: np.ndarray) -> None:
        self.odometry_covariances = odometry_covariances
        self.odometry_information = np.linalg.inv(odometry_covariances)
        self.polar_noise = polar_noise
        self.z, self.z_information = polar_to_point(self.polar, polar_noise)
        self.z_covariance = np.linalg.inv(self.z_information)


def _placed(problem: _Problem, rows: np.ndarray) -> np.ndarray:
    """World positions (n, 2) of sightings ``rows`` placed from their poses' current values."""
    return geometry.transform_points(problem.poses[problem.pose_index[rows]], problem.z[rows])


class _Graph:
    """The GraphSLAM of the current labels: pose vertex k has id k, landmark `label` the id
    T + its slot in ``labels`` (sorted)."""

    def __init__(self, problem: _Problem):
        p = problem
        t = len(p.poses)
        self.labels = np.array(sorted({int(x) for x in p.labels[p.labels != UNASSIGNED]}), dtype=np.int64)
        self.slot = {int(label): k for k, label in enumerate(self.labels)}
        self.num_poses = t
        g = PoseGraph2D()
        for k in range(t):
            g.add_pose(k, p.poses[k])
        g.set_fixed(0)  # the filters' start pose is known exactly: the gauge
        for k in range(t - 1):
            g.add_pose_edge(k, k + 1, p.odometry[k], p.odometry_information[k])
        for label in self.labels:
            g.add_point(t + self.slot[int(label)], p.landmarks[int(label)])
        self.rows = np.flatnonzero(p.labels != UNASSIGNED)
        for i in self.rows:
            g.add_point_edge(int(p.pose_index[i]), t + self.slot[int(p.labels[i])], p.z[i], p.z_information[i])
        self.graph = g

    def point_id(self, label) -> int:
        return self.num_poses + self.slot[int(label)]

    def point_ids(self, labels: np.ndarray) -> np.ndarray:
        """``point_id`` of each of an array of held labels."""
        return self.num_poses + np.searchsorted(self.labels, labels)

    def landmark_marginals(self) -> np.ndarray:
        """(L, 2, 2) marginal covariances of the landmarks in ``labels`` order, computed once."""
        if getattr(self, "_marginals", None) is None:
            ids = [self.point_id(x) for x in self.labels]
            self._marginals = np.array(marginal_covariances(self.graph, ids)).reshape(-1, 2, 2)
        return self._marginals

    def optimize(self, problem: _Problem, precise: bool = True) -> float:
        """Minimise from the current values (Levenberg-Marquardt: its first damping is tiny, so
        where Gauss-Newton's steps are good they are taken as they are, and a start far off, a
        filter that went astray or a rescaled noise, is still safe). ``precise``: to
        MINIMUM_STEP / MINIMUM_DECREASE, the tests' requirement; else to
        NOISE_OPTIMIZE_TOLERANCE (between two noise estimates)."""
        tolerance = dict(relative_tolerance=MINIMUM_DECREASE, step_tolerance=MINIMUM_STEP) if precise else \
            dict(relative_tolerance=NOISE_OPTIMIZE_TOLERANCE)
        report = optimize(self.graph, algorithm="levenberg-marquardt", **tolerance)
        self._marginals = None
        problem.poses = self.graph.poses
        points = self.graph.points
        problem.landmarks = {int(label): points[k].copy() for k, label in enumerate(self.labels)}
        return float(report.chi2)
