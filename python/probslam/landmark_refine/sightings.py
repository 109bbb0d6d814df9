"""Each sighting against its own landmark and against others, under the posterior of all the
other sightings: the leave-one-out statistic of step 2 and the innovation against a candidate
landmark that steps 2 and 3 choose by."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Tuple

import numpy as np

from .._core import joint_marginal_covariances, linearize_point_edges
from .problem import _Graph, _Problem


#: The residual covariance Q - H Sigma H^T of a sighting is singular when its landmark rests on
#: it alone (one sighting, or others that constrain the point in one direction only): it is not
#: tested when its smallest eigenvalue is below this fraction of Q's largest (rounding in the
#: difference of two nearly equal matrices is ~1e-16 relative; 1e-9 leaves a wide margin).
LEAVE_ONE_OUT_RANK_TOLERANCE = 1e-9


@dataclass
class _SightingTests:
    """What the sighting test computed for the labelled sightings of landmarks with two or more:
    rows (n,), residuals e (n, 2), Jacobians h (n, 2, 5) over (pose, landmark), residual
    covariances Q - h Sigma h^T (n, 2, 2), their inverses (NaN where not testable, ``ok``
    False), and the statistic e^T (Q - h Sigma h^T)^-1 e per sighting of the problem (K,)."""

    rows: np.ndarray
    e: np.ndarray
    h: np.ndarray
    residual_cov: np.ndarray
    inverse: np.ndarray
    ok: np.ndarray
    stats: np.ndarray
    joint: np.ndarray  # (n, 5, 5) of (pose, landmark)


def _sighting_statistics(g: _Graph, problem: _Problem, counts: Dict[int, int]) -> _SightingTests:
    """Each labelled sighting's leave-one-out statistic e^T (Q - H Sigma H^T)^-1 e against its
    landmark (NaN where not testable: a landmark of one sighting, or a residual covariance of
    less than full rank), and what the re-association and the noise estimate need of it."""
    k = len(problem.labels)
    stats = np.full(k, np.nan)
    rows = np.array([i for i in g.rows if counts[int(problem.labels[i])] >= 2], dtype=np.int64)
    if len(rows) == 0:
        empty = np.empty((0, 2, 2))
        return _SightingTests(rows, np.empty((0, 2)), np.empty((0, 2, 5)), empty, empty, np.zeros(0, bool), stats,
                              np.empty((0, 5, 5)))
    t = problem.pose_index[rows]
    groups = np.column_stack([t, g.point_ids(problem.labels[rows])]).tolist()
    joint = np.array(joint_marginal_covariances(g.graph, groups))
    marks = np.array([problem.landmarks[int(c)] for c in g.labels])
    m = marks[np.searchsorted(g.labels, problem.labels[rows])]
    e, j_pose, j_point = linearize_point_edges(problem.poses[t], m, problem.z[rows])
    h = np.concatenate([j_pose, j_point], axis=2)  # (n, 2, 5)
    residual_cov = problem.z_covariance[rows] - h @ joint @ h.transpose(0, 2, 1)
    residual_cov = 0.5 * (residual_cov + residual_cov.transpose(0, 2, 1))
    smallest = np.linalg.eigvalsh(residual_cov)[:, 0]
    scale = np.linalg.eigvalsh(problem.z_covariance[rows])[:, -1]
    ok = smallest > LEAVE_ONE_OUT_RANK_TOLERANCE * scale
    inv = np.full_like(residual_cov, np.nan)
    inv[ok] = np.linalg.inv(residual_cov[ok])
    stats[rows[ok]] = np.einsum("ni,nij,nj->n", e[ok], inv[ok], e[ok])
    return _SightingTests(rows, e, h, residual_cov, inv, ok, stats, joint)



def _reassociation_distances(g: _Graph, problem: _Problem, queries: List[Tuple[int, int]],
                             tests: _SightingTests) -> np.ndarray:
    """Squared Mahalanobis distance of sighting i to landmark c, for each query (i, c), under the
    posterior of all the sightings but i: with J the sighting's Jacobian over (pose, own landmark)
    and W = (Q - J Sigma J^T)^-1, removing it moves the mean by Sigma J^T W e and the covariance by
    + Sigma J^T W J Sigma (Woodbury); the innovation against c is then c's residual plus H (mean
    shift), with covariance Q + H Sigma' H^T. One factorisation for all the queries."""
    if not queries:
        return np.empty(0)
    rows = np.array([i for i, _ in queries], dtype=np.int64)
    t = problem.pose_index[rows]
    candidates = np.array([c for _, c in queries], dtype=np.int64)
    groups = np.column_stack([t, g.point_ids(problem.labels[rows]), g.point_ids(candidates)]).tolist()
    joint = np.array(joint_marginal_covariances(g.graph, groups))  # (n, 7, 7): candidate, pose, own
    n = len(queries)
    at = np.searchsorted(tests.rows, rows)
    e, h_own, w = tests.e[at], tests.h[at], tests.inverse[at]
    j_own = np.zeros((n, 2, 7))
    j_own[:, :, 0:5] = h_own
    a = joint @ j_own.transpose(0, 2, 1)  # Sigma J^T (n, 7, 2)
    shift = np.einsum("nij,nj->ni", a, np.einsum("nij,nj->ni", w, e))
    loo = joint + a @ w @ a.transpose(0, 2, 1)
    marks = np.array([problem.landmarks[int(c)] for c in g.labels])
    m = marks[np.searchsorted(g.labels, candidates)]
    e_c, j_pose, j_point = linearize_point_edges(problem.poses[t], m, problem.z[rows])
    h = np.zeros((n, 2, 7))
    h[:, :, 0:3] = j_pose
    h[:, :, 5:7] = j_point
    v = e_c + np.einsum("nij,nj->ni", h, shift)
    s = problem.z_covariance[rows] + h @ loo @ h.transpose(0, 2, 1)
    return np.einsum("ni,ni->n", v, np.linalg.solve(s, v[:, :, None])[:, :, 0]), np.linalg.slogdet(s)[1]
