"""Plotting helpers; each draws on a matplotlib ``ax`` (matplotlib is imported lazily)."""

from __future__ import annotations

import math
from typing import Dict, Optional, Tuple

import numpy as np

#: The confidence of the covariance ellipses the figures draw: the ellipse holds this much of
#: the 2-D Gaussian's probability, its radii sqrt(chi2(2).ppf(0.95)) = 2.45 standard deviations
#: (a "2 sigma" ellipse holds 1 - exp(-2) = 86.5% in 2-D, not 95%).
ELLIPSE_CONFIDENCE = 0.95

#: What ``occupancy_map`` keeps around the cells it crops to, metres: room for the walls'
#: outer faces and the legend without the empty margin of a grid grown for stray rays.
MAP_MARGIN = 1.0

#: ``occupancy_map``'s crop="occupied" keeps the cells whose occupancy probability is above this:
#: map_saver's occupied threshold, what a ROS user's map shows as a wall.
OCCUPIED_PROBABILITY = 0.65


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


def ellipse_scale(confidence: float = ELLIPSE_CONFIDENCE) -> float:
    """How many standard deviations the ellipse holding ``confidence`` of a 2-D Gaussian
    reaches: sqrt of the chi-square quantile with 2 degrees of freedom, which has the closed form
    -2 ln(1 - confidence) (0.95: 2.448)."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    return math.sqrt(-2.0 * math.log1p(-confidence))


def ellipse_label(confidence: float = ELLIPSE_CONFIDENCE) -> str:
    """The legend text of covariance ellipses: their confidence and how it is computed."""
    return f"{confidence:.0%} confidence ellipses (chi2, 2 dof: {ellipse_scale(confidence):.2f} sigma)"


def covariance_ellipse(ax, mean, cov, n_sigma: Optional[float] = None, *, confidence: float = ELLIPSE_CONFIDENCE,
                       **style):
    """Draw the ellipse of a 2-D Gaussian (mean (2,), cov (2, 2), metres) that holds
    ``confidence`` of its probability (``ellipse_scale``), or, given ``n_sigma``, the n-sigma
    ellipse (which holds 1 - exp(-n_sigma^2 / 2): 86.5% for 2)."""
    from matplotlib.patches import Ellipse

    scale = ellipse_scale(confidence) if n_sigma is None else n_sigma
    values, vectors = np.linalg.eigh(np.asarray(cov)[:2, :2])
    values = np.clip(values, 0.0, None)
    angle = np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1]))
    ellipse = Ellipse(mean[:2], 2 * scale * np.sqrt(values[1]), 2 * scale * np.sqrt(values[0]), angle=angle,
                      fill=False, **style)
    ax.add_patch(ellipse)
    return ellipse


def _ellipses(ax, means, covariances, n_sigma: Optional[float], confidence: float) -> None:
    """Red covariance ellipses, and one legend entry saying their confidence."""
    from matplotlib.lines import Line2D

    for m, c in zip(means, covariances):
        covariance_ellipse(ax, m, c, n_sigma, confidence=confidence, color="tab:red", lw=0.6)
    if len(means):
        label = (ellipse_label(confidence) if n_sigma is None else
                 f"{n_sigma:g}-sigma ellipses ({1 - math.exp(-0.5 * n_sigma ** 2):.1%} confidence)")
        # A proxy: patches do not enter a legend one by one.
        ax.add_line(Line2D([], [], color="tab:red", lw=0.6, label=label))


def _metre_axes(ax) -> None:
    """Equal metre axes and the legend beside them (a landmark map has no empty corner)."""
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")


#: A rigid motion (R (2, 2), t (2,)): x -> R x + t, e.g. an estimate's alignment onto the ground
#: truth (``probslam.eval.MrclamScore.rotation`` / ``translation``).
Alignment = Tuple[np.ndarray, np.ndarray]
#: What the labels of an estimate drawn through its alignment end with.
ALIGNED_SUFFIX = " (aligned)"


def _moved(xy: np.ndarray, align: Optional[Alignment]) -> np.ndarray:
    """The first two columns of ``xy`` (N, 2+), moved by ``align`` (as they are without one)."""
    xy = np.asarray(xy, dtype=float).reshape(len(xy), -1)[:, :2]
    return xy if align is None else xy @ np.asarray(align[0]).T + np.asarray(align[1])


def _moved_covariances(covariances: np.ndarray, align: Optional[Alignment]) -> np.ndarray:
    """Covariances (N, 2, 2) rotated by ``align``: R C R^T."""
    c = np.asarray(covariances, dtype=float)
    return c if align is None else np.einsum("ij,njk,lk->nil", align[0], c, align[0])


def _label(label: str, align: Optional[Alignment]) -> str:
    return label if align is None else label + ALIGNED_SUFFIX


def _reference(ax, truth_path: Optional[np.ndarray], dead_reckoning: Optional[np.ndarray],
               dead_reckoning_label: str) -> None:
    """The dead reckoning and ground truth paths (T, 2+), where given."""
    if dead_reckoning is not None:
        ax.plot(dead_reckoning[:, 0], dead_reckoning[:, 1], color="0.6", lw=0.8, label=dead_reckoning_label)
    if truth_path is not None:
        ax.plot(truth_path[:, 0], truth_path[:, 1], color="tab:green", lw=0.8, label="ground truth")


def landmark_map(ax, poses: np.ndarray, ekf=None, truth_path: Optional[np.ndarray] = None,
                 truth_landmarks: Optional[Dict[int, np.ndarray]] = None, dead_reckoning: Optional[np.ndarray] = None,
                 n_sigma: Optional[float] = None, truth_landmarks_label: str = "surveyed landmarks", *,
                 confidence: float = ELLIPSE_CONFIDENCE, path_label: str = "EKF SLAM",
                 landmarks: Optional[Tuple[np.ndarray, np.ndarray]] = None, align: Optional[Alignment] = None,
                 dead_reckoning_label: str = "dead reckoning") -> None:
    """Estimated path (T, 3+) named ``path_label``, landmarks with their ``confidence`` ellipses
    (or n-sigma ones, given ``n_sigma``) from an EkfSlam, or ``landmarks`` = (means (N, 2),
    covariances (N, 2, 2)) given instead (a GraphSLAM refinement's), and the ground truth and
    dead reckoning where given; metre axes and a legend naming each line, marker and the
    ellipses' confidence. With ``align`` (R, t) the estimate (path, landmarks, ellipses) is drawn
    moved by it, onto the ground truth it was scored against, and its labels say so."""
    _reference(ax, truth_path, dead_reckoning, dead_reckoning_label)
    xy = _moved(poses, align)
    ax.plot(xy[:, 0], xy[:, 1], color="tab:blue", lw=0.8, label=_label(path_label, align))
    if truth_landmarks:
        xy = np.array(list(truth_landmarks.values()))
        ax.plot(xy[:, 0], xy[:, 1], "g+", ms=9, label=truth_landmarks_label)
    if landmarks is None and ekf is not None and ekf.num_landmarks:
        found = ekf.landmarks()
        landmarks = (found.means, found.covariances)
    if landmarks is not None and len(landmarks[0]):
        xy = _moved(landmarks[0], align)
        ax.plot(xy[:, 0], xy[:, 1], "r.", ms=4, label=_label("estimated landmarks", align))
        _ellipses(ax, xy, _moved_covariances(landmarks[1], align), n_sigma, confidence)
    _metre_axes(ax)


def fastslam_map(ax, fastslam, truth_path: Optional[np.ndarray] = None,
                 truth_landmarks: Optional[Dict[int, np.ndarray]] = None, dead_reckoning: Optional[np.ndarray] = None,
                 n_sigma: Optional[float] = None, truth_landmarks_label: str = "surveyed landmarks", *,
                 confidence: float = ELLIPSE_CONFIDENCE, align: Optional[Alignment] = None,
                 dead_reckoning_label: str = "dead reckoning") -> None:
    """A FastSlam's particle cloud (its M poses), the best particle's path and landmarks with
    their ``confidence`` ellipses (or n-sigma ones, given ``n_sigma``), and the ground truth and
    dead reckoning (T, 2+) where given (metres), with a legend as ``landmark_map``'s; ``align``
    as there (the particles, path and landmarks moved by it)."""
    best = fastslam.best_index
    _reference(ax, truth_path, dead_reckoning, dead_reckoning_label)
    path = _moved(fastslam.path(best), align)
    ax.plot(path[:, 0], path[:, 1], color="tab:blue", lw=0.8, label=_label("best particle's path", align))
    cloud = _moved(fastslam.poses, align)
    ax.plot(cloud[:, 0], cloud[:, 1], ".", color="tab:purple", ms=2, label=_label(f"particles ({len(cloud)})", align))
    if truth_landmarks:
        xy = np.array(list(truth_landmarks.values()))
        ax.plot(xy[:, 0], xy[:, 1], "g+", ms=9, label=truth_landmarks_label)
    landmarks = fastslam.landmarks(best)
    means, covs = landmarks.means, landmarks.covariances
    if len(means):
        means = _moved(means, align)
        ax.plot(means[:, 0], means[:, 1], "r.", ms=4, label=_label("best particle's landmarks", align))
        _ellipses(ax, means, _moved_covariances(covs, align), n_sigma, confidence)
    _metre_axes(ax)


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


#: The side view of a flat 3-D graph (a garage's levels, metres apart over hundreds of metres)
#: stretches z until its extent is at least this fraction of x's, by a round factor it names.
SIDE_VIEW_MIN_HEIGHT = 0.25
_ROUND_FACTORS = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000)


def side_view_exaggeration(x: np.ndarray, z: np.ndarray) -> int:
    """The factor ``pose_graph_3d`` stretches z by in the side view: 1 unless z's extent is below
    ``SIDE_VIEW_MIN_HEIGHT`` of x's (and not zero), then the smallest round factor that lifts it
    there (at most 1000)."""
    x_span, z_span = float(np.ptp(x)) if len(x) else 0.0, float(np.ptp(z)) if len(z) else 0.0
    if x_span == 0.0 or z_span == 0.0 or z_span >= SIDE_VIEW_MIN_HEIGHT * x_span:
        return 1  # drawn to scale (a planar graph too: a line stretched is still a line)
    needed = SIDE_VIEW_MIN_HEIGHT * x_span / z_span
    return next((k for k in _ROUND_FACTORS if k >= needed), _ROUND_FACTORS[-1])


def pose_graph_3d(top, side, graph, initial=None, edges: bool = False) -> None:
    """A PoseGraph3D as two projections on metre axes: ``top`` the view from above (x-y, equal
    scales) and ``side`` the view from the side (x-z, equal scales, or z stretched by the round
    factor of ``side_view_exaggeration`` when the graph is flat, said in the title); the poses as
    a path in id order, its points (landmarks) as small dots, ``initial`` (P, 3+) the starting
    guess of the poses in grey beneath, and (if ``edges``) every pose edge as a thin line (loop
    closures show the graph's structure)."""
    from matplotlib.collections import LineCollection

    order = np.argsort(graph.pose_ids, kind="stable")
    poses = graph.poses[order]
    index = {int(i): k for k, i in enumerate(graph.pose_ids)}
    stretch = side_view_exaggeration(poses[:, 0], poses[:, 2])
    side_title = "side view (x-z)" + (f", z stretched {stretch}x" if stretch > 1 else "")
    for ax, (a, b), view in ((top, (0, 1), "top view (x-y)"), (side, (0, 2), side_title)):
        if initial is not None:
            start = np.asarray(initial)[order]
            ax.plot(start[:, a], start[:, b], color="0.7", lw=0.5, label="initial guess")
        if edges:
            ends = np.array([(index[int(i)], index[int(j)]) for i, j in graph.pose_edges()[0]],
                            dtype=int).reshape(-1, 2)
            p = graph.poses[:, (a, b)]
            ax.add_collection(LineCollection(np.stack([p[ends[:, 0]], p[ends[:, 1]]], axis=1), colors="tab:orange",
                                             linewidths=0.3, alpha=0.5, label="edges"))
        ax.plot(poses[:, a], poses[:, b], color="tab:blue", lw=0.7, label="optimised poses")
        points = graph.points
        if len(points):
            ax.scatter(points[:, a], points[:, b], s=3, color="tab:red", linewidths=0, label="points")
        ax.set_aspect(stretch if ax is side else 1.0, adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("yz"[b - 1] + " [m]")
        ax.set_title(view, fontsize="medium")
    top.legend(loc="best", fontsize="small")


#: The crops of ``occupancy_map``.
CROPS = ("occupied", "known", "none")


def crop_bounds(grid, crop: str = "occupied", margin: float = MAP_MARGIN) -> Tuple[int, int, int, int]:
    """(row0, row1, col0, col1), the half-open cell block ``occupancy_map`` shows: the cells that
    are occupied (probability above ``OCCUPIED_PROBABILITY``; rays that leave a building through
    a window or door clear cells far outside it) or known (log-odds other than the prior's), and
    ``margin`` metres around them, within the grid; the whole grid for "none" or a grid with no
    such cell."""
    if crop not in CROPS:
        raise ValueError(f"crop must be one of {', '.join(map(repr, CROPS))}, got {crop!r}")
    if crop == "occupied":
        keep = grid.probability() > OCCUPIED_PROBABILITY
    else:
        keep = grid.log_odds != grid.l0
    if crop == "none" or not keep.any():
        return 0, grid.height, 0, grid.width
    rows, cols = np.flatnonzero(keep.any(axis=1)), np.flatnonzero(keep.any(axis=0))
    pad = int(math.ceil(margin / grid.resolution))
    return (max(int(rows[0]) - pad, 0), min(int(rows[-1]) + 1 + pad, grid.height),
            max(int(cols[0]) - pad, 0), min(int(cols[-1]) + 1 + pad, grid.width))


#: How dark ``occupancy_map`` draws a cell at the map's prior (unknown): mid grey, whatever the
#: prior, so that free space (white) and unknown differ as much as unknown and occupied do.
UNKNOWN_DARKNESS = 0.5


def evidence_darkness(log_odds: np.ndarray, prior_log_odds: float) -> np.ndarray:
    """Each cell's shade, 0 (white) to 1 (black): the probability its evidence alone gives,
    sigmoid(l - l0), so that the prior (no evidence) is UNKNOWN_DARKNESS. With the 0.5 prior of the
    ray model (l0 = 0) it is the cell's probability itself; a learned model's prior (~0.09 for
    the Intel laser) would otherwise draw unknown as light as free space."""
    return 1.0 / (1.0 + np.exp(-(np.asarray(log_odds, dtype=float) - float(prior_log_odds))))


def occupancy_map(ax, grid, trajectory: Optional[np.ndarray] = None, *, crop: str = "occupied",
                  margin: float = MAP_MARGIN, trajectory_label: str = "trajectory") -> Tuple[float, float, float, float]:
    """An OccupancyGrid2D as grey (black occupied, white free, mid grey unknown: the map's prior,
    ``evidence_darkness``) on metre axes,
    cropped to ``crop_bounds(grid, crop, margin)``, with ``trajectory`` (n, 2 or 3; metres) in red
    and a legend naming the trajectory and the three shades. Returns the extent shown, (x_min,
    x_max, y_min, y_max) in metres."""
    from matplotlib.patches import Patch

    r0, r1, c0, c1 = crop_bounds(grid, crop, margin)
    res, (x0, y0) = grid.resolution, grid.origin
    extent = (x0 + c0 * res, x0 + c1 * res, y0 + r0 * res, y0 + r1 * res)
    ax.imshow(1.0 - evidence_darkness(grid.log_odds[r0:r1, c0:c1], grid.l0), cmap="gray",
              vmin=0.0, vmax=1.0, origin="lower", extent=extent, interpolation="nearest")
    if trajectory is not None and len(trajectory):
        xy = np.asarray(trajectory, dtype=float)[:, :2]
        ax.plot(xy[:, 0], xy[:, 1], color="tab:red", lw=0.8, label=trajectory_label)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    handles, labels = ax.get_legend_handles_labels()
    shade = 1.0 - UNKNOWN_DARKNESS
    for label, colour in (("occupied", "black"), ("free", "white"), ("unknown", (shade, shade, shade))):
        handles.append(Patch(facecolor=colour, edgecolor="0.4", lw=0.5))
        labels.append(label)
    # Outside the axes: a map has no empty corner to spare.
    ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    return extent


def occupancy_map_figure(plt, grid, trajectory: Optional[np.ndarray], label: str, title: str):
    """A figure of ``occupancy_map`` (matplotlib's pyplot given): the map on metre axes, cropped to
    its walls, the trajectory and a legend beside it; nine inches for the map's longer side."""
    r0, r1, c0, c1 = crop_bounds(grid)
    scale = 9.0 / max(r1 - r0, c1 - c0)
    fig, ax = plt.subplots(figsize=(max((c1 - c0) * scale, 4.0) + 1.0, max((r1 - r0) * scale, 4.0) + 0.8))
    occupancy_map(ax, grid, trajectory, trajectory_label=label)
    ax.set_title(title, fontsize="medium")
    return fig
