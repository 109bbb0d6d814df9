"""Victoria Park (Guivant and Nebot's car in Sydney's park, as iSAM / GTSAM text): read
(``load``), and driven through EKF SLAM or FastSLAM along its chain of odometry edges
(``run_ekf``, ``run_fastslam``), the landmark points it records turned into range and bearing.

The file reader is ``probslam.io.read_victoria_park``. Units: metres, radians.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
from typing import List, Optional, Tuple, Union

import numpy as np

from .. import _core
from .._args import positive_real, require_fields, require_instance
from ..fastslam import dataset_options, fastslam_along_chain
from ..io._files import file_path
from ..io.landmark_datasets import VictoriaPark, read_victoria_park
from ..landmark_refine import RefinementInput, compose_increments, run_labels
from ..landmark_slam import LandmarkSlamResult, ekf_along_chain, polar_measurements
from .landmark_dataset import (LandmarkDataset, association_line, fastslam_lines, refuse_hypotheses,
                               skipped_rows_line)

PathLike = Union[str, "os.PathLike[str]"]

#: The largest distance (m) a record may hold: the filters refuse coordinates beyond it (C++
#: kMaxCoordinate), and the squares of larger ones overflow in the conversion to range and
#: bearing, which then fails with a message about an internal noise matrix.
MAX_COORDINATE = _core.MAX_COORDINATE

#: FastSLAM: the standard deviations of the file's odometry noise are multiplied by this.
#: The file gives every step the same noise (0.01 m, 0.002 m, 0.002 rad), but the odometry's
#: heading error is not white: at the GraphSLAM optimum (chi2 6184.12) the per-step heading
#: residuals have mean +0.54 sigma (7.5 rad accumulated over the run, more than a full turn), so
#: the error over n steps grows like n, not sqrt(n): its RMS is 0.79, 2.5, 4.3 and 7.2 times
#: sigma sqrt(n) for n = 1, 10, 30, 100. An EKF corrects such a drift through its pose-landmark
#: correlations; a particle filter can only select among the poses it sampled, so with the
#: file's noise the particles cannot follow it (one noise-free particle equals dead reckoning,
#: 156 m RMS from the optimum; the best of 100 particles ends 157 m from it). 7 is that ratio at
#: 100 steps: the particles then cover the heading error accumulated between loop closures,
#: which is what hidden associations need (a particle that drifted beyond the association gate
#: starts a duplicate instead of closing the loop). Measured on this file only, the one it is
#: for (studies/fastslam_victoria_park_study.py, 100 particles, seeds 0-3, hidden
#: associations, median path RMSE from the optimum): scale 3: 180 m (version 1) / 181 m
#: (version 2); 5: 45 / 13 m; 7: 10 / 8.8 m; 10: 24 / 24 m. Known associations: 3: 4.8-21 m;
#: 7: 8-14 m.
ODOMETRY_NOISE_SCALE = 7.0


def load(path: PathLike) -> VictoriaPark:
    """The file at ``path``, ready to run. Besides the reader's errors
    (``io.read_victoria_park``), a ValueError naming the file when it holds no ODOMETRY or no
    LANDMARK record, or distances beyond ``MAX_COORDINATE``."""
    path = pathlib.Path(file_path(path))
    data = read_victoria_park(path)
    if len(data.pose_from) == 0:
        raise ValueError(f"{path}: no ODOMETRY records")
    if len(data.xy) == 0:
        raise ValueError(f"{path}: no LANDMARK records")
    for records, values in (("ODOMETRY", data.delta[:, :2]), ("LANDMARK", data.xy)):
        if np.max(np.abs(values)) > MAX_COORDINATE:
            raise ValueError(f"{path}: {records} records with distances beyond {MAX_COORDINATE:g} m "
                             f"(MAX_COORDINATE)")
    return data


def chain(data: VictoriaPark) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The run as a chain of poses: (observed_from (L,), z (L, 2), z_cov (L, 2, 2)), the chain
    position each landmark point was recorded from and the point as range-bearing with its polar
    covariance; the odometry edges must link the poses one after the other."""
    require_instance(data, VictoriaPark, "data")
    if np.any(data.pose_from[1:] != data.pose_to[:-1]):
        raise ValueError("data: the odometry edges do not form one chain")
    poses = np.r_[data.pose_from[0], data.pose_to]
    z, z_cov = polar_measurements(data.xy, data.xy_cov)
    position = {int(p): k for k, p in enumerate(poses)}
    return np.array([position[int(p)] for p in data.pose], dtype=np.int64), z, z_cov


def _sensor_noise(z_cov: np.ndarray, measurement_noise) -> np.ndarray:
    """Q_t: the given (2, 2) covariance, or the points' polar covariance at the median range."""
    q = np.median(z_cov, axis=0) if measurement_noise is None else np.asarray(measurement_noise, float)
    return 0.5 * (q + q.T)


def run_ekf(data: VictoriaPark, measurement_noise=None, dead_reckoning: bool = False,
            progress: Optional[bool] = False) -> LandmarkSlamResult:
    """EKF SLAM with known correspondences (the file's landmark numbers) along the odometry
    edges, as relative poses with the file's covariances; the landmark points converted to
    range-bearing. The file's per-observation covariances are constant (0.4 m^2 per axis); their
    polar form at each range would change Q_t per measurement, so Q_t is the polar covariance at
    the median range unless given. ``dead_reckoning``: the odometry alone (method
    "dead-reckoning"). ``progress``: a bar over the poses (None: on a terminal only)."""
    observed_from, z, z_cov = chain(data)
    q = _sensor_noise(z_cov, measurement_noise)
    if dead_reckoning:
        observed_from = observed_from[:0]
    result = ekf_along_chain(data.delta, data.delta_cov, observed_from, z, z_cov, data.landmark, q,
                             progress=progress)
    return dataclasses.replace(result, method="dead-reckoning") if dead_reckoning else result


def run_fastslam(data: VictoriaPark, measurement_noise=None, *, known: bool = True,
                 options: Optional[_core.FastSlamOptions] = None, odometry_noise_scale: float = ODOMETRY_NOISE_SCALE,
                 progress: Optional[bool] = False, **fields) -> LandmarkSlamResult:
    """FastSLAM along the odometry edges, as relative poses with their covariances times
    ``odometry_noise_scale`` ** 2 (see ``ODOMETRY_NOISE_SCALE``), the landmark points as
    range-bearing (Q_t as ``run_ekf``). ``known=False`` hides the associations: each particle
    associates by maximum likelihood. ``options``: a FastSlamOptions, ``fields`` fields of it by
    keyword (num_particles, version, seed, threads, ...), p_new ``DEFAULT_P_NEW`` where left at
    FastSlamOptions' default (``fastslam.dataset_options``). ``progress``: a bar over the poses
    (None: on a terminal only)."""
    require_instance(data, VictoriaPark, "data")
    scale = positive_real(odometry_noise_scale, "odometry_noise_scale")
    o = dataset_options(options, fields)
    observed_from, z, z_cov = chain(data)
    f = _core.FastSlam(np.eye(3) * 0.0, _sensor_noise(z_cov, measurement_noise), options=o)
    return fastslam_along_chain(f, data.delta, scale ** 2 * data.delta_cov, observed_from, z, data.landmark, known,
                                progress=progress)


def refinement_input(run: LandmarkSlamResult, data: VictoriaPark) -> RefinementInput:
    """The arrays of ``landmark_refine.refine_landmarks`` from a filter run along the chain
    (``run_ekf`` / ``run_fastslam``): the file's odometry and observation covariances, poses the
    start and the chain poses with sightings, the sightings in the order the filters take them."""
    require_fields(run, ("times", "poses", "landmarks", "associations"), "run", "a LandmarkSlamResult")
    observed_from, z, z_cov = chain(data)
    order = np.argsort(observed_from, kind="stable")  # the order the filters take the sightings in
    truth = data.landmark[order].astype(np.int64)
    steps = observed_from[order]
    labels = run_labels(run, truth)
    recorded = np.asarray(run.poses, float)
    if len(recorded) != len(data.pose_to) + 1:
        raise ValueError(f"run: holds {len(recorded)} poses, the data's chain {len(data.pose_to) + 1}")
    nodes = np.unique(np.concatenate([[0], steps]))
    odometry, odometry_cov = compose_increments(data.delta, data.delta_cov, nodes)
    return RefinementInput(nodes.astype(float), recorded[nodes], odometry, odometry_cov,
                           np.searchsorted(nodes, steps).astype(np.int64), z[order], labels, z_cov[order],
                           {int(k): np.asarray(v, float) for k, v in run.landmarks.items()}, order, truth)


class VictoriaParkChain(LandmarkDataset):
    """Victoria Park as iSAM / GTSAM text, as a landmark run sees it
    (``landmark_dataset.LandmarkDataset``): its odometry and sighting noise are the file's, its
    landmark numbers the labels; the EKF takes them (known correspondences, with or without
    ``unknown``), FastSLAM may hide them. Nothing to score against (the file has no ground truth)."""

    LABEL = "Victoria Park"
    DATA = VictoriaPark

    @classmethod
    def check(cls, options, path) -> None:
        """As ``LandmarkDataset.check``; and no options of the multiple-hypothesis EKF, refine only
        FastSLAM's hidden correspondences."""
        super().check(options, path)
        refuse_hypotheses(options)
        if options.refine != "none" and not options.unknown:
            raise ValueError("refine graphslam needs unknown correspondences (with known ones there is nothing to "
                             "refine)")
        if options.refine != "none" and options.method == "ekf":
            raise ValueError("refine graphslam applies to MRCLAM folders with method ekf (Victoria Park's EKF takes "
                             "the file's correspondences); use fastslam with unknown for Victoria Park")

    @classmethod
    def load(cls, path, options) -> "VictoriaParkChain":
        """The file at ``path`` (``load``)."""
        return cls(load(path), path)

    def read_lines(self) -> List[str]:
        """The records skipped and those whose noise was repaired."""
        from ..graph import INFORMATION_EIGENVALUE_FLOOR

        data = self.data
        lines = [skipped_rows_line({"unreadable records": data.skipped_rows} if data.skipped_rows else {})]
        if data.repaired_rows:
            lines.append(f"repaired rows: {data.repaired_rows} (noise not positive definite: eigenvalues raised to "
                         f"{INFORMATION_EIGENVALUE_FLOOR:g} of the largest)")
        return lines

    def run(self, options, progress: Optional[bool] = None) -> LandmarkSlamResult:
        """``run_fastslam``, or ``run_ekf`` (known correspondences, the file's)."""
        if options.method == "fastslam":
            return self.run_filter("fastslam", known=not options.unknown, options=options.fastslam,
                                   progress=progress)
        return self.run_filter("ekf", progress=progress)

    def _run_filter(self, method, known, motion_noise, measurement_noise, association, hypotheses, fastslam,
                    progress) -> LandmarkSlamResult:
        if motion_noise is not None:
            raise ValueError("motion_noise: Victoria Park's odometry noise is its file's")
        if method == "fastslam":
            return run_fastslam(self.data, measurement_noise, known=known, progress=progress, **fastslam)
        if method == "mht":
            raise ValueError("method 'mht' runs on MRCLAM only")
        if method == "ekf" and not known:
            raise ValueError("known: on Victoria Park the EKF runs with the file's correspondences only (known=True)")
        return run_ekf(self.data, measurement_noise, dead_reckoning=method == "dead-reckoning", progress=progress)

    def refinement_input(self, run: LandmarkSlamResult, motion_noise=None, measurement_noise=None,
                         command_period: Optional[float] = None) -> RefinementInput:
        """``refinement_input`` of the run (the file's noise: the noise arguments are not used)."""
        return refinement_input(run, self.data)

    def summary(self, result: LandmarkSlamResult, options, seconds: float) -> List[str]:
        """The file, its poses and observations, what the filter mapped."""
        source = f"Victoria Park {self.path}: {len(result.poses)} poses, {len(self.data.xy)} observations"
        if options.method == "fastslam":
            return ([f"dataset:       {source}, {'unknown' if options.unknown else 'known'} correspondences"]
                    + fastslam_lines(result, options) + association_line(result))
        return [f"dataset:       {source}",
                f"landmarks:     {len(result.landmarks)}; filter time {result.seconds:.3f} s"]


__all__ = ["MAX_COORDINATE", "ODOMETRY_NOISE_SCALE", "VictoriaParkChain", "chain", "load", "refinement_input", "run_ekf", "run_fastslam"]
