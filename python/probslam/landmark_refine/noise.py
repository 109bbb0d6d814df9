"""Variance component estimation (Foerstner): the odometry, range and bearing noise rescaled to
the residuals of the optimum before the first test."""

from __future__ import annotations

import numpy as np

from .._core import joint_marginal_covariances, linearize_pose_edges
from .problem import _Graph, _Problem
from .sightings import _SightingTests


#: The noise a filter is run with is set for the filter (MRCLAM's CLI default 0.15 m / 0.04 rad
#: is several times the camera's error: at the GraphSLAM optimum of robot 1 of Dataset 7 with
#: the barcodes as labels, chi2 is 722 for a redundancy of about 5000), and a test against a
#: noise several times too large cannot see a wrong sighting. With ``estimate_noise`` the
#: refinement rescales odometry, range and bearing noise by variance component estimation
#: (Foerstner) at each round before it tests, until every factor is within this of 1.
NOISE_TOLERANCE = 0.02

#: Variance component iterations per round at most (they converge linearly, within ~10 here).
NOISE_MAX_ITERATIONS = 20


def _variance_factors(g: _Graph, problem: _Problem, tests: _SightingTests, gate: float) -> np.ndarray:
    """Variance component estimation (Foerstner): for each noise group (odometry, range,
    bearing), sum of e^T Q^-1 e over its residuals divided by its redundancy, the sum of
    tr(Q^-1 (Q - J Sigma J^T)) (the residuals' share of the observations' freedom); 1 for a group
    whose noise is right. Sightings beyond the split gate are left out (they are about to leave:
    their residuals are errors of association, not noise). Range and bearing are the components
    of the sighting's residual mapped back to polar through the inverse of its Jacobian."""
    factors = np.ones(3)
    t = len(problem.poses)
    if t > 1:
        joint = np.array(joint_marginal_covariances(g.graph, [[k, k + 1] for k in range(t - 1)]))
        e, d_from, d_to = linearize_pose_edges(problem.poses[:-1], problem.poses[1:], problem.odometry)
        jac = np.concatenate([d_from, d_to], axis=2)
        info = problem.odometry_information
        residual = problem.odometry_covariances - jac @ joint @ jac.transpose(0, 2, 1)
        redundancy = np.einsum("nij,nji->", info, residual)
        if redundancy > 0:
            factors[0] = np.einsum("ni,nij,nj->", e, info, e) / redundancy
    keep = tests.ok & (tests.stats[tests.rows] <= gate)
    if keep.any():
        rows = tests.rows[keep]
        r, phi = problem.polar[rows, 0], problem.polar[rows, 1]
        c, s = np.cos(phi), np.sin(phi)
        to_polar = np.stack([np.column_stack([c, s]), np.column_stack([-s / r, c / r])], axis=1)
        e = np.einsum("nij,nj->ni", to_polar, tests.e[keep])
        residual = to_polar @ tests.residual_cov[keep] @ to_polar.transpose(0, 2, 1)
        q = problem.polar_noise[rows]
        for c_ in range(2):
            redundancy = np.sum(residual[:, c_, c_] / q[:, c_, c_])
            if redundancy > 0:
                factors[1 + c_] = np.sum(e[:, c_] ** 2 / q[:, c_, c_]) / redundancy
    return factors


def _scaled_polar(noise: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """Polar covariances (K, 2, 2) with range and bearing scaled by the factors ``variance``
    (2,): S Q S with S = diag(sqrt(variance))."""
    s = np.sqrt(variance)
    return noise * np.outer(s, s)[None]
