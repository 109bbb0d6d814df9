"""A trajectory against a corrected CARMEN log, scan for scan: Radish's ``intel-corrected.log.gz``
and ``freiburg-079-corrected.log.gz`` hold another SLAM system's laser poses (GMapping-style; a
reference, not ground truth) for scans of their raw logs.

A corrected scan is paired with the raw scan of identical range vector whose logger time (the last
field of a CARMEN line) is within ``tolerance`` of its own (``pair_corrected_scans``): the time
alone may name a neighbour (the corrected logs print 6 significant digits, the raw Intel log holds
bursts of up to 14 scans within 0.01 s and its logger times are not monotonic), the ranges alone
may repeat (a robot standing still). ``corrected_log_error``: the position and heading errors at
the pairs after the best rigid alignment (Kabsch / Umeyama without scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List

import numpy as np

from .._args import positive_real, real_array, require_instance
from ..io.carmen import LaserScans
from ._checks import _require_finite, _wrap
from .alignment import _se2_alignment
from .statistics import error_statistics, statistics_table

#: Largest |logger time difference| (s) of a corrected scan and its raw twin: the corrected logs
#: print their times to 6 significant digits (Intel's 0.01 s past 1000 s), the raw logs to 1 us.
PAIR_TOLERANCE = 0.01
#: Fewest pairs a score is given from: two positions are fitted by the alignment at any distance
#: error-free but for their spacing, so the errors would say nothing of the trajectory.
MIN_PAIRS = 3


@dataclass(frozen=True)
class ScanPairs:
    """Corrected scans paired with raw ones: raw_indices (P,) and corrected_indices (P,) int64, in
    the corrected log's order; corrected: the corrected log's scans; ambiguous: corrected scans
    left out because several raw scans have their ranges and a time within ``tolerance`` (s)."""

    raw_indices: np.ndarray
    corrected_indices: np.ndarray
    corrected: int
    ambiguous: int
    tolerance: float

    def __len__(self) -> int:
        return len(self.raw_indices)

    def __str__(self) -> str:
        text = f"{len(self)}/{self.corrected} corrected scans paired"
        return text + (f", {self.ambiguous} ambiguous left out" if self.ambiguous else "")


def pair_corrected_scans(raw: LaserScans, corrected: LaserScans, tolerance: float = PAIR_TOLERANCE) -> ScanPairs:
    """The corrected scans that have exactly one raw scan with identical ranges (every beam, the
    NaN padding included) and logger time within ``tolerance`` s of their own, with it. raw,
    corrected: ``io.LaserScans`` (``io.read_carmen_log(path).scans``). Scans of different widths
    never pair. TypeError / ValueError naming the argument."""
    require_instance(raw, LaserScans, "raw")
    require_instance(corrected, LaserScans, "corrected")
    tolerance = positive_real(tolerance, "tolerance")
    t_raw = real_array(raw.timestamps, "raw", (len(raw),))
    t_cor = real_array(corrected.timestamps, "corrected", (len(corrected),))
    by_ranges: Dict[bytes, List[int]] = {}
    for i, ranges in enumerate(np.ascontiguousarray(raw.ranges, dtype=float)):
        by_ranges.setdefault(ranges.tobytes(), []).append(i)
    raw_index, cor_index, ambiguous = [], [], 0
    for k, ranges in enumerate(np.ascontiguousarray(corrected.ranges, dtype=float)):
        near = [i for i in by_ranges.get(ranges.tobytes(), ()) if abs(t_raw[i] - t_cor[k]) <= tolerance]
        if len(near) == 1:
            raw_index.append(near[0])
            cor_index.append(k)
        ambiguous += len(near) > 1
    return ScanPairs(np.array(raw_index, np.int64), np.array(cor_index, np.int64), len(corrected), ambiguous,
                     tolerance)


@dataclass(frozen=True)
class CorrectedLogError:
    """Poses against a corrected log at its scans paired with the raw log's.

    errors (K,) m: the distance of each position, after the alignment, from the corrected one;
    heading_errors (K,) rad: the absolute heading difference after it; rotation (2, 2),
    translation (2,): the alignment applied to the estimate; pairs: the pairing
    (``pair_corrected_scans``); outside: pairs whose raw scan is past the estimate's last (K =
    len(pairs) - outside)."""

    errors: np.ndarray
    heading_errors: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    pairs: ScanPairs
    outside: int

    @property
    def matched(self) -> int:
        """How many pairs were compared."""
        return len(self.errors)

    @property
    def statistics(self) -> Dict[str, float]:
        """evo's statistics of the position errors (m)."""
        return error_statistics(self.errors)

    @property
    def heading_statistics_deg(self) -> Dict[str, float]:
        """evo's statistics of the heading errors, in degrees."""
        return error_statistics(np.degrees(self.heading_errors))

    def __str__(self) -> str:
        return (statistics_table("position error after the rigid alignment (m)", self.statistics) + "\n"
                + statistics_table("heading error after the rigid alignment (deg)", self.heading_statistics_deg))


def corrected_log_error(poses: object, raw: LaserScans, corrected: LaserScans,
                        tolerance: float = PAIR_TOLERANCE) -> CorrectedLogError:
    """``poses`` (N, 3) ``(x, y, theta)``: an estimate of the laser poses of the raw log's first N
    scans (``raw``), row for row (a SLAM run's on that log), against the ``corrected`` log's laser
    poses at the pairs of ``pair_corrected_scans(raw, corrected, tolerance)`` within those N
    scans, after the rigid alignment that fits the positions best. ValueError naming the argument
    for more poses than raw scans, or fewer than MIN_PAIRS pairs among them."""
    pairs = pair_corrected_scans(raw, corrected, tolerance)
    p = real_array(poses, "poses", (None, 3))
    if len(p) > len(raw):
        raise ValueError(f"poses: {len(p)} rows, but the raw log has {len(raw)} scans (the rows are its scans)")
    inside = pairs.raw_indices < len(p)
    if np.count_nonzero(inside) < MIN_PAIRS:
        raise ValueError(f"corrected: {pairs}, {np.count_nonzero(inside)} of them within the {len(p)} scans "
                         f"estimated: fewer than {MIN_PAIRS} (identical ranges, logger times within {tolerance:g} s)")
    est = p[pairs.raw_indices[inside]]
    ref = corrected.laser_poses[pairs.corrected_indices[inside]]
    rotation, translation = _se2_alignment(est[:, :2], ref[:, :2], "poses and corrected: the alignment")
    errors = np.linalg.norm(est[:, :2] @ rotation.T + translation - ref[:, :2], axis=1)
    _require_finite(errors, "poses and corrected: the errors")
    turn = math.atan2(rotation[1, 0], rotation[0, 0])
    headings = np.abs(_wrap(est[:, 2] + turn - ref[:, 2], "poses and corrected: the heading errors"))
    return CorrectedLogError(errors, headings, rotation, translation, pairs, int(np.count_nonzero(~inside)))


__all__ = ["CorrectedLogError", "MIN_PAIRS", "PAIR_TOLERANCE", "ScanPairs", "corrected_log_error",
           "pair_corrected_scans"]
