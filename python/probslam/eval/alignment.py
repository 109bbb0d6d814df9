"""The rigid alignment of one set of planar points onto another (Kabsch / Umeyama without scale,
evo's ``--align``): the estimate's frame is arbitrary, so scores are given after it too."""

from __future__ import annotations

from typing import Tuple

import numpy as np

from .._args import real_array
from ._checks import _require_finite


def align_rigid(estimate: np.ndarray, truth: np.ndarray):
    """Best-fit rotation R (2, 2) and translation t (2,) with R @ estimate + t ~ truth (Kabsch)."""
    estimate = real_array(estimate, "estimate", (None, 2))
    truth = real_array(truth, "truth", (len(estimate), 2))
    if len(estimate) == 0:
        raise ValueError("estimate: no points to align")
    with np.errstate(over="ignore", invalid="ignore"):
        mu_e, mu_t = estimate.mean(0), truth.mean(0)
        cross = (estimate - mu_e).T @ (truth - mu_t)
    _require_finite(cross, "estimate and truth: the cross-covariance")  # an SVD of inf or NaN fails
    u, _, vt = np.linalg.svd(cross)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, d]) @ u.T
    return r, mu_t - r @ mu_e


def _se2_alignment(est: np.ndarray, ref: np.ndarray, what: str) -> Tuple[np.ndarray, np.ndarray]:
    """``align_rigid`` of (K, 2) positions onto (K, 2), an overflow named by ``what`` (the
    kernel would name its own arguments)."""
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            rotation, translation = align_rigid(est, ref)
    except ValueError:  # the cross-covariance overflows
        raise ValueError(f"{what} overflows a double (inputs too large)") from None
    _require_finite(np.concatenate([rotation.ravel(), translation]), what)
    return rotation, translation
