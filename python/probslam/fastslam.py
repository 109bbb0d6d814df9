"""Landmark FastSLAM (C++ ``FastSlam``) driven over a run: along a chain of relative poses, and the
best particle's data associations carried along the resamplings (each particle's record follows
its ancestor's), so that a run with hidden correspondences can be scored sighting by sighting
against a dataset's own labels. The dataset drivers (UTIAS MRCLAM, Victoria Park) are in
``probslam.datasets``. Units: metres, radians, seconds.
"""

from __future__ import annotations

import time
from typing import Dict, List, Mapping, Optional, Tuple

import numpy as np

from ._args import options_over
from ._core import FastSlam, FastSlamOptions
from ._progress import progress_range
from .landmark_slam import Associations, LandmarkSlamResult

#: p_new of the dataset runs (``datasets.run_landmark_slam``, the datasets' ``run_fastslam``,
#: ``probslam fastslam``): the density (1 / (m rad)) a measurement of a new landmark is given; a
#: known landmark must explain the measurement better than this. It is 10 times below
#: FastSlamOptions' own default (1e-2, what ``FastSlam`` takes when built directly, as
#: bench_fastslam's figures are): the dataset runs' recorded results (benchmarks/RESULTS.md:
#: MRCLAM's, Victoria Park's and the original Victoria Park run's FastSLAM rows) ran with 1e-3,
#: and ``dataset_options`` keeps it, the one place that says so.
DEFAULT_P_NEW = 1e-3


def dataset_options(options: Optional[FastSlamOptions], fields: Mapping, **dataset) -> FastSlamOptions:
    """The FastSlamOptions of a FastSLAM run over a dataset: ``options`` (None: the defaults)
    with the dataset's own values ``dataset`` (its sensor's noise and field) and p_new
    ``DEFAULT_P_NEW`` where the options hold FastSlamOptions' default, then ``fields`` set by
    keyword (``_args.options_over``). Validated; errors name the field."""
    return options_over(FastSlamOptions, options, fields, {"p_new": DEFAULT_P_NEW, **dataset})


class AssociationHistories:
    """Every particle's association record, carried along resamplings: each scan's (ancestors,
    ids (M, k), true ids, stamp) are kept, and one particle's lineage is traced back at the end,
    so a run pays O(1) Python work per scan, not O(M)."""

    def __init__(self) -> None:
        self.scans: List[Tuple[np.ndarray, np.ndarray, np.ndarray, float]] = []

    def add(self, f: FastSlam, ids: np.ndarray, truth: np.ndarray, stamp: float = 0.0) -> None:
        """One scan just taken by ``f``: ``ids`` (M, k) from its ``update_unknown``, the sightings'
        true ids (k,), the scan's time stamp."""
        # Row j of this scan's ids belongs to particle j after the scan's resampling, whose
        # record before it is that of particle ancestors[j].
        self.scans.append((f.ancestors, ids, truth, stamp))

    def of(self, k: int) -> Associations:
        """Particle ``k``'s record: the sightings of its lineage's scans, oldest first."""
        out = []
        for ancestors, ids, truth, stamp in reversed(self.scans):
            out.append((np.full(len(truth), stamp, float), truth, ids[k]))
            if len(ancestors):
                k = int(ancestors[k])
        out.reverse()
        if not out:
            return Associations(np.empty(0), np.empty(0, np.int64), np.empty(0, np.int64))
        times, truth, ids = (np.concatenate(column) for column in zip(*out))
        return Associations(times, truth.astype(np.int64), ids.astype(np.int64))


def best_landmarks(f: FastSlam) -> Dict[int, np.ndarray]:
    """The best particle's map: landmark id -> (2,) position."""
    landmarks = f.landmarks()
    return {int(i): m for i, m in zip(landmarks.ids, landmarks.means)}


def result_of(f: FastSlam, times: np.ndarray, seconds: float, histories=None) -> LandmarkSlamResult:
    """The run's result at its end: the best particle's path at ``times`` and its map, with its
    association record when ``histories`` (an ``AssociationHistories``) were kept."""
    associations = None if histories is None else histories.of(f.best_index)
    return LandmarkSlamResult("fastslam", np.asarray(times, float), f.path(), best_landmarks(f), f, seconds,
                              associations)


def fastslam_along_chain(f: FastSlam, delta: np.ndarray, delta_cov: np.ndarray, observed_from: np.ndarray,
                         z: np.ndarray, landmark: np.ndarray, known: bool,
                         progress: Optional[bool] = False) -> LandmarkSlamResult:
    """FastSLAM ``f`` along a chain of P poses: ``delta`` (P-1, 3) relative poses with covariances
    (P-1, 3, 3); sighting k (robot-frame range-bearing ``z[k]``, dataset label ``landmark[k]``)
    is made from chain pose ``observed_from[k]``. ``known``: the labels are the correspondences;
    else each particle associates by maximum likelihood (``FastSlam.update_unknown``) and the best
    one's record is returned. ``times`` are the chain positions. ``progress``: a bar over the
    poses (None: on a terminal only)."""
    order = np.argsort(observed_from, kind="stable")
    bounds = np.searchsorted(observed_from[order], np.arange(len(delta) + 2))
    histories = None if known else AssociationHistories()
    t0 = time.perf_counter()
    for k in progress_range(len(delta) + 1, f"FastSLAM {f.version}.0", "pose", progress):
        if k > 0:
            f.predict_odometry(delta[k - 1], delta_cov[k - 1])
        rows = order[bounds[k]:bounds[k + 1]]
        if len(rows):
            truth = landmark[rows].astype(np.int64)
            if known:
                f.update(z[rows], truth)
            else:
                ids = f.update_unknown(z[rows]).ids
                histories.add(f, ids, truth, float(k))
    return result_of(f, np.arange(len(delta) + 1, dtype=float), time.perf_counter() - t0, histories)


__all__ = ["DEFAULT_P_NEW", "AssociationHistories", "best_landmarks", "dataset_options", "fastslam_along_chain",
           "result_of"]
