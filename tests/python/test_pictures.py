"""Pictures a person can read (issue 36): metre axes, a legend naming every line and marker, a
title naming the command and the data, maps cropped to their cells with a margin, and the
ellipses' confidence said and true. Checked on the matplotlib objects, not on pixels."""

from __future__ import annotations

import math

import numpy as np
import pytest

import probslam as ps
from probslam import cli, plot
from probslam.data import path as data_path

plt = pytest.importorskip("matplotlib.pyplot", reason="the pictures need matplotlib")


def legend_texts(ax):
    return [t.get_text() for t in ax.get_legend().get_texts()]


@pytest.fixture
def figures(monkeypatch):
    """The figures the command line saves, as (title, x label, y label, legend texts, axes)."""
    seen = []
    save = cli.commands._save_figure

    def record(plt_, fig, path):
        ax = fig.axes[0]
        seen.append(dict(title=ax.get_title(), xlabel=ax.get_xlabel(), ylabel=ax.get_ylabel(),
                         legend=legend_texts(ax), xlim=ax.get_xlim(), ylim=ax.get_ylim(), path=path,
                         suptitle=fig.get_suptitle(), axes=list(fig.axes)))
        return save(plt_, fig, path)

    monkeypatch.setattr(cli.commands, "_save_figure", record)
    return seen


# --- the ellipses --------------------------------------------------------------------------------

def test_the_95_percent_ellipse_holds_95_percent():
    """Monte Carlo: the share of samples of N(0, C) inside the drawn ellipse. With 200 000 samples
    the share's standard deviation is sqrt(0.95 * 0.05 / 2e5) = 4.9e-4; 0.003 is six of them."""
    assert plot.ellipse_scale(0.95) == pytest.approx(math.sqrt(5.991464547107979), rel=1e-12)  # chi2(2).ppf(0.95)
    fig, ax = plt.subplots()
    cov = np.array([[2.0, 0.6], [0.6, 0.5]])
    e = plot.covariance_ellipse(ax, np.array([1.0, -2.0]), cov)
    rng = np.random.default_rng(0)
    samples = rng.multivariate_normal([1.0, -2.0], cov, 200_000)
    inside = e.contains_points(ax.transData.transform(samples))
    assert np.mean(inside) == pytest.approx(0.95, abs=0.003)
    two_sigma = plot.covariance_ellipse(ax, np.array([1.0, -2.0]), cov, n_sigma=2.0)
    assert np.mean(two_sigma.contains_points(ax.transData.transform(samples))) == pytest.approx(
        1 - math.exp(-2.0), abs=0.003)  # 86.5%: what "2 sigma" drew before
    plt.close(fig)
    with pytest.raises(ValueError, match="confidence must lie in"):
        plot.ellipse_scale(1.0)


# --- the occupancy map ---------------------------------------------------------------------------

def small_grid():
    """A 200 x 100 grid at 0.1 m whose only known cells are a wall block and a free block."""
    grid = ps.OccupancyGrid2D(0.1, 200, 100, origin=(-5.0, -3.0))
    rows, cols = np.meshgrid(np.arange(40, 50), np.arange(60, 90), indexing="ij")  # occupied
    grid.add_log_odds((rows * 200 + cols).ravel(), np.full(rows.size, 3.0))
    rows, cols = np.meshgrid(np.arange(20, 30), np.arange(10, 20), indexing="ij")  # free, further out
    grid.add_log_odds((rows * 200 + cols).ravel(), np.full(rows.size, -3.0))
    return grid


def test_the_map_is_cropped_to_its_walls_or_its_known_cells_with_a_margin():
    grid = small_grid()
    # Occupied rows 40..49, columns 60..89, and 1 m = 10 cells around them.
    assert plot.crop_bounds(grid, "occupied", 1.0) == (30, 60, 50, 100)
    # Known cells reach rows 20.. and columns 10..
    assert plot.crop_bounds(grid, "known", 1.0) == (10, 60, 0, 100)
    assert plot.crop_bounds(grid, "none") == (0, 100, 0, 200)
    assert plot.crop_bounds(ps.OccupancyGrid2D(0.1, 20, 10), "occupied") == (0, 10, 0, 20)  # nothing: all
    fig, ax = plt.subplots()
    extent = plot.occupancy_map(ax, grid, np.array([[0.5, 1.0, 0.0], [1.5, 1.2, 0.0]]), trajectory_label="path")
    # Columns 50..100 of x0 = -5 at 0.1 m: x in [0, 5]; rows 30..60 of y0 = -3: y in [0, 3].
    assert extent == pytest.approx((0.0, 5.0, 0.0, 3.0))
    assert ax.get_xlim() == pytest.approx((0.0, 5.0)) and ax.get_ylim() == pytest.approx((0.0, 3.0))
    image = ax.get_images()[0]
    assert image.get_array().shape == (30, 50) and image.get_extent() == pytest.approx(list(extent))
    # Black is occupied: the wall's cells are dark, in the image's row order (origin lower).
    assert image.get_array()[10:20, 10:40].max() < 0.1 and image.get_array()[0, 0] == pytest.approx(0.5)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [m]", "y [m]")
    assert legend_texts(ax) == ["path", "occupied", "free", "unknown"]
    plt.close(fig)


# --- what each command draws ---------------------------------------------------------------------

@pytest.mark.slow
def test_map_and_slam_pictures(tmp_path, figures):
    assert cli.main(["map", "--no-progress", "-o", str(tmp_path / "m")]) == 0
    assert cli.main(["slam", "--no-progress", "-o", str(tmp_path / "s")]) == 0
    (m, s) = figures
    assert m["title"] == "probslam map: intel_excerpt.log.gz\noccupancy grid at the log's poses"
    assert s["title"] == f"probslam slam --method graph: {cli.BUNDLED_SLAM_LOG}\nGraphSLAM over submaps"
    for f in figures:
        assert (f["xlabel"], f["ylabel"]) == ("x [m]", "y [m]")
        assert f["legend"][1:] == ["occupied", "free", "unknown"] and "laser poses" in f["legend"][0]
    # The map's extent: its walls and 1 m, no more (the grid itself is larger).
    grid = ps.io.load_ros_map(tmp_path / "m.yaml")
    r0, r1, c0, c1 = plot.crop_bounds(grid)
    x0, y0 = grid.origin
    assert m["xlim"] == pytest.approx((x0 + c0 * grid.resolution, x0 + c1 * grid.resolution))
    assert m["ylim"] == pytest.approx((y0 + r0 * grid.resolution, y0 + r1 * grid.resolution))
    walls = np.argwhere(grid.probability() > plot.OCCUPIED_PROBABILITY)
    assert r0 == walls[:, 0].min() - 20 and c1 == walls[:, 1].max() + 1 + 20  # 1 m of 0.05 m cells


@pytest.mark.slow
def test_the_rbpf_picture_is_cropped(tmp_path, figures):
    """The RBPF map's grid is grown for every particle's rays: the picture shows the walls."""
    assert cli.main(["slam", data_path(cli.BUNDLED_RAW_LOG), "--method", "rbpf", "--particles", "4",
                     "--no-progress", "-o", str(tmp_path / "r")]) == 0
    (r,) = figures
    assert r["title"].startswith("probslam slam --method rbpf: intel_raw_loop.log.gz\ngrid-based FastSLAM")
    grid = ps.io.load_ros_map(tmp_path / "r.yaml")
    shown = (r["xlim"][1] - r["xlim"][0]) * (r["ylim"][1] - r["ylim"][0])
    assert shown < 0.9 * grid.width * grid.height * grid.resolution ** 2


def test_landmark_pictures(tmp_path, figures):
    assert cli.main(["ekf-slam", "--no-progress", "-o", str(tmp_path / "e")]) == 0
    assert cli.main(["fastslam", "--particles", "10", "--no-progress", "-o", str(tmp_path / "f")]) == 0
    assert cli.main(["ekf-slam", ps.data.path("victoria_park_1000.txt"), "--no-progress", "-o", str(tmp_path / "v")]) == 0
    e, f, v = figures
    assert e["title"] == ("probslam ekf-slam: UTIAS MRCLAM mrclam7_robot1_120s robot 1\nEKF SLAM, known correspondences"
                          "; estimate aligned onto ground truth")
    assert f["title"] == ("probslam fastslam: UTIAS MRCLAM mrclam7_robot1_120s robot 1\nFastSLAM 1.0, 10 particles, "
                          "known correspondences; estimate aligned onto ground truth")
    assert v["title"].startswith("probslam ekf-slam: Victoria Park victoria_park_1000.txt")
    ellipses = "95% confidence ellipses (chi2, 2 dof: 2.45 sigma)"
    assert e["legend"] == ["dead reckoning (aligned)", "ground truth", "EKF SLAM (aligned)", "surveyed landmarks",
                           "estimated landmarks (aligned)", ellipses]
    assert f["legend"] == ["dead reckoning (aligned)", "ground truth", "best particle's path (aligned)",
                           "particles (10) (aligned)", "surveyed landmarks", "best particle's landmarks (aligned)",
                           ellipses]
    assert v["legend"] == ["EKF SLAM", "estimated landmarks", ellipses]
    for fig in figures:
        assert (fig["xlabel"], fig["ylabel"]) == ("x [m]", "y [m]")


def test_refined_landmark_picture_draws_the_refinement(tmp_path, figures, monkeypatch):
    """--refine graphslam: the picture is the refinement's path and map, one ellipse per refined
    landmark from the final GraphSLAM's marginal covariance (not the filter's)."""
    from probslam.datasets import LandmarkDataset

    drawn = {}
    draw = LandmarkDataset.draw

    def spy(dataset, ax, result, score, refinement=None, *rest):
        drawn["refinement"] = refinement.refinement
        note = draw(dataset, ax, result, score, refinement, *rest)
        drawn["ellipses"] = [p for p in ax.patches if p.get_edgecolor()[:3] == plt.matplotlib.colors.to_rgb("tab:red")]
        return note

    monkeypatch.setattr(LandmarkDataset, "draw", spy)
    assert cli.main(["fastslam", "--unknown", "--refine", "graphslam", "--particles", "10", "--no-progress",
                     "-o", str(tmp_path / "r")]) == 0
    (fig,) = figures
    assert fig["title"].endswith("unknown correspondences, GraphSLAM refinement (ch. 11.6); estimate aligned onto "
                                 "ground truth")
    assert fig["legend"] == ["dead reckoning (aligned)", "ground truth", "GraphSLAM refinement (aligned)",
                             "surveyed landmarks", "estimated landmarks (aligned)",
                             "95% confidence ellipses (chi2, 2 dof: 2.45 sigma)"]
    r = drawn["refinement"]
    assert sorted(r.landmark_covariances) == sorted(r.landmarks) and len(drawn["ellipses"]) == len(r.landmarks)
    for label, cov in r.landmark_covariances.items():
        assert np.array_equal(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0), label


def test_optimize_picture(tmp_path, figures):
    assert cli.main(["optimize", "--edges", "-o", str(tmp_path / "o")]) == 0
    (o,) = figures
    assert o["title"].startswith("probslam optimize: intel_400.g2o\ngauss-newton, chi2 ")
    assert o["legend"] == ["initial guess", "edges", "optimised poses"]
    assert (o["xlabel"], o["ylabel"]) == ("x [m]", "y [m]")


def test_optimize_3d_picture_is_a_top_and_a_side_view(tmp_path, figures):
    path = ps.data.path("parking_garage_400.g2o")
    assert cli.main(["optimize", path, "--edges", "--no-progress", "-o", str(tmp_path / "o")]) == 0
    (o,) = figures
    assert o["suptitle"].startswith("probslam optimize: parking_garage_400.g2o\ngauss-newton from chordal, chi2 ")
    top, side = o["axes"]
    assert (top.get_title(), top.get_xlabel(), top.get_ylabel()) == ("top view (x-y)", "x [m]", "y [m]")
    g = ps.graph.read_pose_graph_3d(tmp_path / "o.g2o")
    stretch = plot.side_view_exaggeration(g.poses[:, 0], g.poses[:, 2])
    assert stretch > 1  # a garage: metres of height over a hundred metres of floor
    assert (side.get_title(), side.get_xlabel(), side.get_ylabel()) == (
        f"side view (x-z), z stretched {stretch}x", "x [m]", "z [m]")
    assert side.get_aspect() == stretch and top.get_aspect() == 1.0
    assert legend_texts(top) == ["initial guess", "edges", "optimised poses"]
    # Both views show every pose: the garage's levels (z spans metres) are inside the side view.
    for ax, column in ((top, 1), (side, 2)):
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        assert x0 <= g.poses[:, 0].min() and g.poses[:, 0].max() <= x1
        assert y0 <= g.poses[:, column].min() and g.poses[:, column].max() <= y1
    assert np.ptp(g.poses[:, 2]) > 5.0
    assert (tmp_path / "o.png").read_bytes()[:4] == b"\x89PNG"


def test_side_view_is_stretched_only_when_flat():
    x = np.array([0.0, 100.0])
    assert plot.side_view_exaggeration(x, np.array([0.0, 30.0])) == 1  # 30 % of x: drawn to scale
    assert plot.side_view_exaggeration(x, np.array([0.0, 8.0])) == 5  # 8 m -> 40 m >= 25 m
    assert plot.side_view_exaggeration(x, np.array([0.0, 2.6])) == 10
    assert plot.side_view_exaggeration(x, np.array([0.0, 1e-4])) == 1000  # at most 1000
    assert plot.side_view_exaggeration(x, np.zeros(2)) == 1  # a planar graph: nothing to stretch
    assert plot.side_view_exaggeration(np.zeros(2), np.zeros(2)) == 1
