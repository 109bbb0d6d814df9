"""Filter consistency: the normalised estimation error squared (NEES) of an estimate against the
covariance the filter claims for it."""

from __future__ import annotations

import numpy as np

from .._args import real_array
from ._checks import _require_finite


#: ``nees`` treats a covariance as singular when its smallest eigenvalue is at most this times its
#: largest. Rounding alone leaves the smallest eigenvalue of an exactly rank-deficient symmetric
#: matrix near 1e-16 times the largest; 1e-12 keeps a margin of 1e4 above that while a real pose
#: covariance (e.g. 1 m^2 in position, 1e-8 rad^2 in heading) stays far above it.
NEES_SINGULAR_RTOL = 1e-12

#: ``nees`` rejects a covariance whose transpose differs by more than this times its largest
#: entry: filters symmetrise their covariances, so anything larger is a wrong argument (e.g. a
#: square root factor or an information matrix in the wrong layout), not rounding.
_SYMMETRY_RTOL = 1e-9


class SingularCovarianceError(ValueError):
    """``nees`` was given a singular covariance: the filter claims certainty in some direction."""


def nees(error: object, covariance: object) -> np.ndarray:
    """Normalised estimation error squared, e^T P^-1 e, for one or many estimates.

    Args:
        error: (..., n) estimate minus truth, in the state's units (metres, radians; wrap angle
            differences first, e.g. with ``probslam.sim.pose_error``).
        covariance: (..., n, n) the covariance the filter claims for that estimate, symmetric
            positive semi-definite, in the squared units of ``error``.

    Returns:
        (...) dimensionless NEES, finite; chi2(n)-distributed when the filter is consistent (mean n).

    Raises:
        SingularCovarianceError (a ValueError) when a covariance is singular: its smallest
        eigenvalue is at most ``NEES_SINGULAR_RTOL`` times its largest, or it is zero. The NEES is
        then unbounded; no pseudo-inverse is taken, as it would drop exactly the error the filter
        says is impossible and make an overconfident filter look consistent. A caller studying
        consistency counts these cases itself (e.g. as infinite NEES).
        ValueError naming the argument for non-finite input, an empty state (n = 0),
        mismatched shapes, an asymmetric covariance, or a NEES too large for a double;
        TypeError for anything but real numbers.
    """
    e = real_array(error, "error", None)
    p = real_array(covariance, "covariance", None)
    if e.ndim < 1 or e.shape[-1] == 0:
        raise ValueError(f"error: expected shape (..., n) with n >= 1, got {e.shape}")
    if p.shape != e.shape + e.shape[-1:]:
        raise ValueError(f"covariance must have shape error.shape + (n,) = {e.shape + e.shape[-1:]}, "
                         f"got error {e.shape} and covariance {p.shape}")
    scale = np.max(np.abs(p), axis=(-2, -1), keepdims=True)
    if np.any(np.abs(p - np.swapaxes(p, -1, -2)) > _SYMMETRY_RTOL * scale):
        raise ValueError("covariance must be symmetric")
    values, vectors = np.linalg.eigh(p)
    largest = values[..., -1:]
    singular = np.any(values <= NEES_SINGULAR_RTOL * largest, axis=-1) | (largest[..., 0] <= 0.0)
    if np.any(singular):
        where = tuple(int(i) for i in np.argwhere(singular)[0])
        raise SingularCovarianceError(f"covariance{list(where) if where else ''} is singular (eigenvalues "
                                      f"{values[where].tolist()}): the NEES is unbounded")
    projected = np.einsum("...ji,...j->...i", vectors, e)  # V^T e
    with np.errstate(over="ignore", invalid="ignore"):
        result = np.sum(projected ** 2 / values, axis=-1)
    _require_finite(result, "error and covariance: the NEES")
    return result
