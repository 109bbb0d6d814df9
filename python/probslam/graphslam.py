"""GraphSLAM in information form (ch. 11, Tables 11.1-11.5, 11.8 and 11.9), one function per table.

The state is ``y = (x_0 .. x_T, m_0 .. m_{N-1})``: poses ``(x, y, theta)`` then features
``(m_x, m_y)`` (or ``(m_x, m_y, s)`` when measurements carry a signature). ``Omega`` is a
``scipy.sparse.csc_matrix`` over y and ``xi`` a numpy vector. The anchor of x_0 is exact: its rows
and columns of Omega are cleared, ``Omega_00 = I`` and ``xi_0 = mu_0`` (the posterior conditioned
on x_0, the finite form of Table 11.2 line 3's infinite information), and x_0's covariance is 0.
"""

from __future__ import annotations

from typing import NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from . import _core


class Measurements(NamedTuple):
    """Feature measurements as flat arrays: ``time`` (M,) pose index t, ``z`` (M, 2) range [m]
    and bearing [rad] (or (M, 3) with a signature), ``correspondences`` (M,) feature index."""

    time: np.ndarray
    z: np.ndarray
    correspondences: np.ndarray


class GraphSlamResult(NamedTuple):
    """GraphSLAM's estimate: poses (T + 1, 3), features (N, d), pose covariances (T + 1, 3, 3),
    the iterations, convergence and objective; with unknown correspondences also the
    correspondences, merges and rounds of Table 11.9."""

    poses: np.ndarray  # (T + 1, 3)
    features: np.ndarray  # (N, d)
    pose_covariances: np.ndarray  # (T + 1, 3, 3), zeros for the anchored x_0
    iterations: int  # of the last solve
    converged: bool
    objective: float  # eq. 11.11 (the anchor term is zero)
    correspondences: Optional[np.ndarray] = None  # (M,) feature of each measurement (Table 11.9)
    merges: Optional["FeatureMerges"] = None  # the merges Table 11.9 made, in order
    rounds: int = 0  # Table 11.9's test-merge-solve rounds


class FeatureMerges(NamedTuple):
    """Merges made by Table 11.9, one entry each: features are named by their first measurement
    (an index into the measurement arrays); ``kept`` absorbed ``merged`` in ``round``."""

    round: np.ndarray  # (K,)
    kept: np.ndarray  # (K,)
    merged: np.ndarray  # (K,)
    probability: np.ndarray  # (K,) p(m_kept - m_merged = 0), Table 11.8
    distance2: np.ndarray  # (K,) squared Mahalanobis distance of the difference


class CorrespondenceTest(NamedTuple):
    """Table 11.8 for a pair (or arrays of pairs) of features: the difference m_j - m_k."""

    probability: Union[float, np.ndarray]  # density of m_j - m_k at 0, 1/m^2 (1/(m^2 s) with signatures)
    distance2: Union[float, np.ndarray]  # squared Mahalanobis distance of the difference
    mean: np.ndarray  # (d,) or (K, d)
    covariance: np.ndarray  # (d, d) or (K, d, d)


def _measurements(measurements) -> Measurements:
    if isinstance(measurements, Measurements):
        return measurements
    try:
        parts = tuple(measurements)
    except TypeError:
        parts = ()
    if len(parts) == 2:  # (time, z): correspondences unknown
        parts = parts + (None,)
    if len(parts) != 3:
        raise TypeError("measurements must be a (time, z, correspondences) or (time, z) tuple")
    return Measurements(*parts)


def _csc(matrix, name: str):
    import scipy.sparse as sp

    if not sp.issparse(matrix):
        raise TypeError(f"{name} must be a scipy.sparse matrix")
    m = sp.csc_matrix(matrix, dtype=np.float64)
    m.sum_duplicates()  # canonical form: sorted, unique row indices per column (the C++ side requires it)
    if m.shape[0] != m.shape[1]:
        raise ValueError(f"{name} must be square, got shape {m.shape}")
    return m


def _from_parts(parts):
    import scipy.sparse as sp

    data, indices, indptr, shape = parts
    return sp.csc_matrix((data, indices, indptr), shape=shape)


def eif_initialize(controls, dt, initial_pose=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Table 11.1: the dead-reckoned path ``(T + 1, 3)`` from controls ``(T, 2)`` rows
    ``(v [m/s], w [rad/s])`` and ``dt`` (seconds, a number or ``(T,)``)."""
    return _core._eif_initialize(controls, dt, initial_pose)


def _split_mu(mu, controls, meas: Measurements):
    num_poses = np.asarray(controls).shape[0] + 1
    mu = np.asarray(mu, dtype=np.float64)
    z = np.asarray(meas.z)
    d = z.shape[1] if z.ndim == 2 else 2
    corr = np.asarray(meas.correspondences)
    n = int(corr.max()) + 1 if corr.size else 0
    if mu.shape == (num_poses, 3) or mu.size == 3 * num_poses:
        poses = mu.reshape(num_poses, 3)
        return poses, _core._eif_initial_features(poses, meas.time, meas.z, meas.correspondences, n)
    if mu.ndim != 1 or mu.size != 3 * num_poses + d * n:
        raise ValueError(
            f"mu must be the path ({num_poses}, 3) or the full state of {3 * num_poses + d * n} entries"
        )
    return mu[: 3 * num_poses].reshape(num_poses, 3), mu[3 * num_poses :].reshape(n, d)


def eif_construct(controls, dt, measurements, mu, R, Q):
    """Table 11.2 (with the errata): ``(Omega, xi)`` linearised at ``mu``.

    ``mu`` is the full state vector, or the path ``(T + 1, 3)`` alone, in which case each feature
    is placed by its first measurement. ``R`` is the 3x3 pose-space motion noise covariance and
    ``Q`` the d x d measurement noise covariance (variances, m^2 and rad^2).
    """
    meas = _measurements(measurements)
    poses, features = _split_mu(mu, controls, meas)
    parts, xi = _core._eif_construct(
        controls, dt, meas.time, meas.z, meas.correspondences, poses, features, R, Q
    )
    return _from_parts(parts), xi


def _feature_dim(omega, num_poses: int, feature_dim: Optional[int]) -> int:
    if feature_dim is not None:
        return feature_dim
    rest = omega.shape[0] - 3 * num_poses
    return 2 if rest % 2 == 0 else 3


def eif_reduce(omega, xi, num_poses: int, feature_dim: Optional[int] = None):
    """Table 11.3: ``(Omega~, xi~)`` over the path, features eliminated by their d x d block
    Schur complements (Omega_mm is never inverted as a whole). ``num_poses`` is T + 1;
    ``feature_dim`` is 2 or 3 (guessed from the size when omitted: give it when it is ambiguous)."""
    omega = _csc(omega, "omega")
    d = _feature_dim(omega, num_poses, feature_dim)
    parts, xi_r = _core._eif_reduce(omega.indptr, omega.indices, omega.data, omega.shape[0], xi, num_poses, d)
    return _from_parts(parts), xi_r


def eif_solve(
    reduced_omega,
    reduced_xi,
    omega,
    xi,
    num_poses: int,
    feature_dim: Optional[int] = None,
    covariance_blocks: Sequence[Tuple[int, int]] = (),
):
    """Table 11.4 (with the erratum of line 6): ``(poses (T + 1, 3), features (N, d), blocks)``.

    The path comes from a sparse Cholesky factorisation of Omega~; ``covariance_blocks`` lists
    pose index pairs ``(s, t)`` whose 3x3 block of the path covariance is returned in ``blocks``
    ``(K, 3, 3)``, computed from the factor (never a dense inverse)."""
    r = _csc(reduced_omega, "reduced_omega")
    f = _csc(omega, "omega")
    d = _feature_dim(f, num_poses, feature_dim)
    blocks = [(int(s), int(t)) for s, t in covariance_blocks]
    return _core._eif_solve(
        r.indptr, r.indices, r.data, reduced_xi, f.indptr, f.indices, f.data, f.shape[0], xi, num_poses, d, blocks
    )


def eif_correspondence_test(omega, reduced_omega, features, num_poses: int, j, k) -> CorrespondenceTest:
    """Table 11.8 (with the errata): the posterior of ``m_j - m_k`` and its density at 0.

    ``omega`` is the information of Table 11.2, ``reduced_omega`` the path information of
    Table 11.3 (standing for the path covariance Sigma_{0:t}, never inverted densely) and
    ``features`` ``(N, d)`` the means of Table 11.4. The marginal of the pair is
    ``Sigma_[jk] = A^-1 + A^-1 B Sigma_tt B^T A^-1`` with ``A = Omega_{jk,jk}`` and
    ``B = Omega_{jk,tau(j,k)}``; the book's line 2 and eq. 11.46 are wrong. ``j`` and ``k`` are
    feature indices, or equal-length integer arrays of pairs (the factor is then shared).
    """
    f = _csc(omega, "omega")
    r = _csc(reduced_omega, "reduced_omega")
    scalar = np.ndim(j) == 0 and np.ndim(k) == 0
    js, ks = np.atleast_1d(j), np.atleast_1d(k)
    for name, a in (("j", js), ("k", ks)):
        if a.ndim != 1 or not np.issubdtype(a.dtype, np.integer):
            raise TypeError(f"{name} must be an integer or a 1-D integer array")
    if js.shape != ks.shape:
        raise ValueError(f"j and k must have the same length, got {js.shape} and {ks.shape}")
    pairs = [(int(a), int(b)) for a, b in zip(js, ks)]
    probability, distance2, mean, cov = _core._eif_correspondence_test(
        f.indptr, f.indices, f.data, f.shape[0], r.indptr, r.indices, r.data, features, num_poses, pairs
    )
    if scalar:
        return CorrespondenceTest(float(probability[0]), float(distance2[0]), mean[0], cov[0])
    return CorrespondenceTest(probability, distance2, mean, cov)


def graph_slam(
    controls,
    dt,
    measurements,
    R,
    Q,
    correspondences=None,
    *,
    max_iterations: int = 50,
    tolerance: float = 1e-9,
    initial_pose=(0.0, 0.0, 0.0),
    path_covariances: bool = True,
    chi: float = 1e-4,
    search_radius: float = 3.0,
    max_rounds: int = 100,
) -> GraphSlamResult:
    """Table 11.5: construct, reduce and solve from the dead-reckoned path until no coordinate
    moves more than ``tolerance`` (m / rad).

    ``measurements`` is ``(time, z, correspondences)``; a separate ``correspondences`` argument
    replaces the third entry. Returns poses, features, the 3x3 marginal of every pose, the
    iteration count and the objective of eq. 11.11.

    With no correspondences (``measurements`` ``(time, z)`` or a third entry of ``None``) this is
    Table 11.9: a feature per measurement, then rounds that test every pair of features whose
    means lie within ``search_radius`` metres and not observed at a common time step
    (Table 11.8), merge those with ``p(m_j - m_k = 0) > chi`` (the most probable first, a
    feature may absorb several in one round, never two sharing a time step) and re-solve, until
    no pair exceeds ``chi`` or
    ``max_rounds``. ``chi`` is a density (1/m^2; 1/(m^2 s) with signatures): a pair is merged
    when its difference is both near zero and certain. The result carries ``correspondences``,
    ``merges`` and ``rounds``; ``converged`` then also says no pair above ``chi`` was left.
    """
    meas = _measurements(measurements)
    if correspondences is not None:
        meas = meas._replace(correspondences=correspondences)
    options = (max_iterations, tolerance, initial_pose, path_covariances)
    if meas.correspondences is None:
        out = _core._graph_slam_unknown(
            controls, dt, meas.time, meas.z, R, Q, *options, chi, search_radius, max_rounds
        )
        out["merges"] = FeatureMerges(**out["merges"])
        search_converged = out.pop("search_converged")
        out["converged"] = out["converged"] and search_converged
        return GraphSlamResult(**out)
    out = _core._graph_slam(controls, dt, meas.time, meas.z, meas.correspondences, R, Q, *options)
    return GraphSlamResult(**out)


def eif_objective(controls, dt, measurements, poses, features, R, Q) -> float:
    """Eq. 11.11 without the anchor: the motion and measurement squared Mahalanobis residuals."""
    meas = _measurements(measurements)
    return _core._eif_objective(controls, dt, meas.time, meas.z, meas.correspondences, poses, features, R, Q)
