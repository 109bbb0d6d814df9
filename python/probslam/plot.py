"""Plotting helpers; each draws on a matplotlib ``ax`` (matplotlib is imported lazily)."""

from __future__ import annotations

from typing import Dict, Optional

import numpy as np


def require_matplotlib():
    """matplotlib.pyplot (the Agg backend unless one is already chosen); ImportError with an
    install hint when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("plotting needs matplotlib: pip install 'probslam[plot]'") from exc
    return plt


def covariance_ellipse(ax, mean, cov, n_sigma: float = 2.0, **style):
    """Draw the n-sigma ellipse of a 2-D Gaussian (mean (2,), cov (2, 2), metres)."""
    from matplotlib.patches import Ellipse

    values, vectors = np.linalg.eigh(np.asarray(cov)[:2, :2])
    values = np.clip(values, 0.0, None)
    angle = np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1]))
    ellipse = Ellipse(mean[:2], 2 * n_sigma * np.sqrt(values[1]), 2 * n_sigma * np.sqrt(values[0]), angle=angle,
                      fill=False, **style)
    ax.add_patch(ellipse)
    return ellipse


def landmark_map(ax, poses: np.ndarray, ekf=None, truth_path: Optional[np.ndarray] = None,
                 truth_landmarks: Optional[Dict[int, np.ndarray]] = None, dead_reckoning: Optional[np.ndarray] = None,
                 n_sigma: float = 2.0, truth_landmarks_label: str = "surveyed landmarks") -> None:
    """Estimated path (T, 3+), landmarks with their n-sigma ellipses from an EkfSlam, and the
    ground truth and dead reckoning where given."""
    if dead_reckoning is not None:
        ax.plot(dead_reckoning[:, 0], dead_reckoning[:, 1], color="0.6", lw=0.8, label="dead reckoning")
    if truth_path is not None:
        ax.plot(truth_path[:, 0], truth_path[:, 1], color="tab:green", lw=0.8, label="ground truth")
    ax.plot(poses[:, 0], poses[:, 1], color="tab:blue", lw=0.8, label="EKF SLAM")
    if truth_landmarks:
        xy = np.array(list(truth_landmarks.values()))
        ax.plot(xy[:, 0], xy[:, 1], "g+", ms=9, label=truth_landmarks_label)
    if ekf is not None and ekf.num_landmarks:
        landmarks = ekf.landmarks()
        xy = landmarks.means
        ax.plot(xy[:, 0], xy[:, 1], "r.", ms=4, label="estimated landmarks")
        for m, cov in zip(xy, landmarks.covariances):
            covariance_ellipse(ax, m, cov, n_sigma, color="tab:red", lw=0.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize="small")


def fastslam_map(ax, fastslam, truth_path: Optional[np.ndarray] = None,
                 truth_landmarks: Optional[Dict[int, np.ndarray]] = None, dead_reckoning: Optional[np.ndarray] = None,
                 n_sigma: float = 2.0, truth_landmarks_label: str = "surveyed landmarks") -> None:
    """A FastSlam's particle cloud (its M poses), the best particle's path and landmarks with
    their n-sigma ellipses, and the ground truth and dead reckoning (T, 2+) where given (metres)."""
    best = fastslam.best_index
    if dead_reckoning is not None:
        ax.plot(dead_reckoning[:, 0], dead_reckoning[:, 1], color="0.6", lw=0.8, label="dead reckoning")
    if truth_path is not None:
        ax.plot(truth_path[:, 0], truth_path[:, 1], color="tab:green", lw=0.8, label="ground truth")
    path = fastslam.path(best)
    ax.plot(path[:, 0], path[:, 1], color="tab:blue", lw=0.8, label="best particle's path")
    cloud = fastslam.poses
    ax.plot(cloud[:, 0], cloud[:, 1], ".", color="tab:purple", ms=2, label=f"particles ({len(cloud)})")
    if truth_landmarks:
        xy = np.array(list(truth_landmarks.values()))
        ax.plot(xy[:, 0], xy[:, 1], "g+", ms=9, label=truth_landmarks_label)
    landmarks = fastslam.landmarks(best)
    means, covs = landmarks.means, landmarks.covariances
    if len(means):
        ax.plot(means[:, 0], means[:, 1], "r.", ms=4, label="best particle's landmarks")
        for m, c in zip(means, covs):
            covariance_ellipse(ax, m, c, n_sigma, color="tab:red", lw=0.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize="small")


def pose_graph(ax, graph, initial=None, edges: bool = True) -> None:
    """A PoseGraph2D: its poses as a path, points as dots, and (if ``edges``) every edge as a thin
    line; ``initial`` (P, 3+) draws the starting guess in grey beneath."""
    from matplotlib.collections import LineCollection

    if initial is not None:
        ax.plot(initial[:, 0], initial[:, 1], color="0.7", lw=0.5, label="initial guess")
    xy = {int(i): p[:2] for i, p in zip(graph.pose_ids, graph.poses)}
    xy.update({int(i): p for i, p in zip(graph.point_ids, graph.points)})
    if edges:
        segments = [(xy[int(a)], xy[int(b)]) for a, b in graph.edge_ids()]
        ax.add_collection(LineCollection(segments, colors="tab:orange", linewidths=0.3, alpha=0.5, label="edges"))
    ax.plot(graph.poses[:, 0], graph.poses[:, 1], color="tab:blue", lw=0.7, label="optimised poses")
    if len(graph.point_ids):
        ax.plot(graph.points[:, 0], graph.points[:, 1], "r.", ms=3, label="points")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize="small")
