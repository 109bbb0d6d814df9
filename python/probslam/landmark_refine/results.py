"""What the refinement reports: each merge and split, each round, and the refined solution."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Tuple

import numpy as np


@dataclass(frozen=True)
class Merge:
    """Landmark ``merged`` joined landmark ``kept`` in round ``iteration`` (0-based);
    ``distance2``: the pair's squared Mahalanobis distance, ``probability`` = P(chi2_2 >= it)."""

    iteration: int
    kept: int
    merged: int
    distance2: float
    probability: float


@dataclass(frozen=True)
class Split:
    """Sighting ``sighting`` left landmark ``old`` for ``new`` in round ``iteration``:
    ``distance2`` its leave-one-out statistic against ``old`` when it left (the sightings that
    left before it in the round excluded too), ``new_distance2`` against ``new`` under the
    posterior without any of the round's leavers (NaN when ``new`` is a landmark created for it,
    ``created`` True; UNASSIGNED when it went to none). ``reason``: "gate" (its statistic
    exceeded the split gate) or "likelihood" (``new`` explains it better by more than
    REASSOCIATION_MARGIN)."""

    iteration: int
    sighting: int
    old: int
    new: int
    distance2: float
    new_distance2: float
    created: bool
    reason: str


@dataclass(frozen=True)
class RefinementRound:
    """One round: the labels it started from and the optimum it tested at (poses (T, 3),
    landmarks {label: (2,)}), the pairs it tested (P, 3) rows (label a, label b, distance2), each
    sighting's leave-one-out statistic against its landmark (K,) (NaN: not tested, or the round
    merged and skipped the sighting test), what it changed, and the noise it tested with
    (``noise_scale`` (3,): standard deviations of odometry, range and bearing over the given)."""

    iteration: int
    labels: np.ndarray
    poses: np.ndarray
    landmarks: Dict[int, np.ndarray]
    pair_tests: np.ndarray
    sighting_tests: np.ndarray
    merges: Tuple[Merge, ...]
    splits: Tuple[Split, ...]
    noise_scale: np.ndarray


@dataclass(frozen=True)
class LandmarkRefinement:
    """The refined solution: poses (T, 3), landmarks {label: (2,)} (those holding a sighting),
    labels (K,) per sighting (UNASSIGNED for those left out), every merge and split, the rounds
    run (``iterations``; ``converged``: the last one changed nothing), the gates used
    (``merge_gate``, ``split_gate``: squared Mahalanobis distances), the final chi2, seconds, and
    the noise of the final solution (``noise_scale`` (3,): standard deviations of odometry,
    range and bearing over the given ones; ones without ``estimate_noise``) and each landmark's
    marginal covariance there (``landmark_covariances``)."""

    poses: np.ndarray
    landmarks: Dict[int, np.ndarray]
    labels: np.ndarray
    merges: Tuple[Merge, ...]
    splits: Tuple[Split, ...]
    iterations: int
    converged: bool
    merge_gate: float
    split_gate: float
    chi2: float
    seconds: float
    rounds: Tuple[RefinementRound, ...]
    noise_scale: np.ndarray
    #: {label: (2, 2)} each landmark's marginal covariance at the final optimum (m^2).
    landmark_covariances: Dict[int, np.ndarray]
