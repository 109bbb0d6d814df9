"""The two chi-square gates of the refinement: a landmark pair merges within the merge gate, a
sighting leaves its landmark beyond the split gate (squared Mahalanobis distances, 2 dof)."""

from __future__ import annotations

from .._args import require_integer
from .._core import chi_square_quantile

#: A landmark pair merges when the Mahalanobis distance of their difference from 0 is within the
#: chi-square quantile at this probability (2 dof): a true duplicate pair passes with this
#: probability (Delta ~ N(0, Sigma_Delta) when both labels name one landmark), so 1% of the
#: duplicates are missed; a distinct pair merges only when their distance is below ~3 standard
#: deviations of Delta (9.21 = 3.03^2), i.e. when the data cannot tell them apart.
MERGE_PROBABILITY = 0.99

#: The split gate is chosen for the whole run, not per sighting: a run of K sightings tests K
#: residuals, so with a per-sighting quantile p about K (1 - p) correct sightings would leave
#: their landmark (50 at p = 0.99 for MRCLAM's 5000), each becoming a one-sighting landmark that
#: can never merge back (its merge test is its own failed residual test). The gate is the
#: chi-square quantile at p = SPLIT_RUN_PROBABILITY ** (1 / K) (Sidak), so that with this
#: probability no correct sighting of the whole run is split off: for K = 5000, p = 1 - 2.0e-6
#: and the gate is 26.2 (5.1 sigma). A sighting on a wrong landmark metres away scores in the
#: thousands. It is >= the merge gate, so a sighting that left never merges back.
SPLIT_RUN_PROBABILITY = 0.99


def merge_gate(probability: float = MERGE_PROBABILITY) -> float:
    """The squared Mahalanobis distance within which a pair merges (chi-square, 2 dof)."""
    return float(chi_square_quantile(probability, 2))


def split_gate(num_sightings: int, probability: float = SPLIT_RUN_PROBABILITY) -> float:
    """The squared leave-one-out distance beyond which a sighting leaves its landmark, for a run
    of ``num_sightings`` tested sightings (see SPLIT_RUN_PROBABILITY)."""
    num_sightings = require_integer(num_sightings, "num_sightings", 1)
    return float(chi_square_quantile(probability ** (1.0 / num_sightings), 2))
