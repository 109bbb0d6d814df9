"""The pictures of a first run (issue 49): what they draw is what the numbers say. A learned
inverse model's map tells free from unknown; the landmark pictures draw the estimate where its
aligned RMSE puts it; the README's hero image is the current `probslam map` picture. Checked on
the matplotlib objects, not on pixels, as test_pictures.py does."""

from __future__ import annotations

import math
import pathlib
import re

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

import probslam as ps
from probslam import cli, eval as evaluation, io, plot
from probslam.pipelines.map_run import BUNDLED_INVERSE_MODEL
from probslam.data import path as data_path

plt = pytest.importorskip("matplotlib.pyplot", reason="the pictures need matplotlib")

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


@pytest.fixture
def axes(monkeypatch):
    """The axes of every figure the command line saves (the first axes of each)."""
    seen = []
    save = cli.commands._save_figure

    def record(plt_, fig, path):
        seen.append(fig.axes[0])
        return save(plt_, fig, path)

    monkeypatch.setattr(cli.commands, "_save_figure", record)
    return seen


def line(ax, label):
    (found,) = [x for x in ax.get_lines() if x.get_label() == label]
    return np.column_stack(found.get_data())


#: How far apart the mean shades of two kinds of cells must lie for a reader to tell them apart:
#: a fifth of the scale from white to black (main drew the learned map's free and unknown cells
#: 0.08 apart, 0.91 and 0.99).
DISTINCT_SHADES = 0.2


def test_evidence_darkness_puts_the_prior_at_mid_grey():
    grid = ps.OccupancyGrid2D(0.1, 3, 1, p_prior=0.09, clamp=None)
    grid.add_log_odds([0, 2], [-2.0, 2.0])
    shade = plot.evidence_darkness(grid.log_odds, grid.l0)
    np.testing.assert_allclose(shade, [[1 / (1 + math.e ** 2), 0.5, 1 / (1 + math.e ** -2)]])
    ray = ps.OccupancyGrid2D(0.1, 3, 1)  # the ray model's 0.5 prior: the probability, as before
    ray.add_log_odds([0, 2], [-2.0, 2.0])
    np.testing.assert_allclose(plot.evidence_darkness(ray.log_odds, ray.l0), ray.probability())


@pytest.mark.slow  # 180 scans through the learned model: 15 s under the sanitizers
def test_learned_map_draws_free_and_unknown_apart(tmp_path, axes, capsys):
    """`map --inverse-model bundled`: the model's prior (0.088) is the unknown cells'. Main drew
    them 0.91 grey and free space 0.93-0.99; now unknown is mid grey (its legend swatch), and the
    cells the scans show free or occupied (1 log-odds or more from the prior) far from it."""
    assert cli.main(["map", "--inverse-model", "bundled", "--no-progress", "-o", str(tmp_path / "m")]) == 0
    capsys.readouterr()
    (ax,) = axes
    model = ps.inverse_learning.LearnedInverseModel.load(ps.data.path(BUNDLED_INVERSE_MODEL))
    grid = ps.inverse_learning.map_laser_log_learned(model, io.read_carmen_log(data_path(cli.BUNDLED_LOG)).scans,
                                                     progress=False).grid
    r0, r1, c0, c1 = plot.crop_bounds(grid)
    shown = np.asarray(ax.get_images()[0].get_array())
    assert shown.shape == (r1 - r0, c1 - c0)
    evidence = (grid.log_odds - grid.l0)[r0:r1, c0:c1]
    free, occupied = shown[evidence < -1.0], shown[evidence > 1.0]
    assert min(len(free), len(occupied)) > 100
    (swatch,) = [h for h, t in zip(ax.get_legend().legend_handles, ax.get_legend().get_texts())
                 if t.get_text() == "unknown"]
    unknown = swatch.get_facecolor()[0]
    assert unknown == pytest.approx(1.0 - plot.UNKNOWN_DARKNESS)
    assert free.min() - unknown > DISTINCT_SHADES, (free.min(), unknown)
    assert unknown - occupied.max() > DISTINCT_SHADES, (unknown, occupied.max())


#: The scores are printed to the millimetre.
PRINTED = 1e-3


def aligned_rmse(text: str, what: str) -> float:
    return float(re.search(rf"{what} RMSE:\s+\S+ m raw, (\S+) m aligned", text).group(1))


@pytest.mark.parametrize("command", [["ekf-slam"], ["fastslam", "--particles", "10"]])
def test_landmark_picture_draws_the_aligned_estimate(tmp_path, axes, capsys, command):
    """The default ekf-slam / fastslam picture: the estimate drawn through its alignment onto the
    ground truth, so the drawn path lies from Vicon's by the printed aligned path RMSE and the
    drawn landmarks from the survey by the aligned landmark RMSE; the legend and title say so."""
    assert cli.main(command + ["--no-progress", "-o", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    (ax,) = axes
    assert ax.get_title().endswith("; estimate aligned onto ground truth")
    data = ps.io.read_mrclam(ps.data.path(cli.BUNDLED_LANDMARKS), robot=1)
    times = io.read_trajectory(tmp_path / "r_trajectory.tum").timestamps
    truth = evaluation.truth_positions(data.groundtruth, times)
    path_label, landmark_label = (("EKF SLAM", "estimated landmarks") if command[0] == "ekf-slam" else
                                  ("best particle's path", "best particle's landmarks"))
    drawn = line(ax, path_label + plot.ALIGNED_SUFFIX)
    assert evaluation.rmse(drawn, truth) == pytest.approx(aligned_rmse(out, "path"), abs=PRINTED)
    # The drawn landmarks against the survey, each paired with a surveyed one by the assignment of
    # least squared distance: no farther than the printed aligned RMSE, which pairs them by
    # barcode (a pairing the assignment can only improve on). Unaligned they lay 1-2 m off.
    survey = np.array(list(data.landmark_positions.values()))
    dots = line(ax, landmark_label + plot.ALIGNED_SUFFIX)
    rows, cols = linear_sum_assignment(np.sum((dots[:, None] - survey[None]) ** 2, axis=2))
    assert evaluation.rmse(dots[rows], survey[cols]) <= aligned_rmse(out, "landmark") + PRINTED
    assert "dead reckoning" + plot.ALIGNED_SUFFIX in [t.get_text() for t in ax.get_legend().get_texts()]


def test_the_readme_hero_image_is_the_map_command_s_picture():
    """README's first picture: made by `probslam map` as it draws today (matplotlib, with axes
    and a legend: its PNG carries matplotlib's Software text), not io.write_png's one pixel a
    cell; the caption names what the picture shows."""
    text = README.read_text()
    hero = re.search(r"!\[[^]]*\]\((docs/[^)]+\.png)\)\n\n\*([^*]+)\*", text)
    png = (README.parent / hero.group(1)).read_bytes()
    assert b"tEXtSoftware\x00Matplotlib" in png
    caption = hero.group(2)
    assert "probslam map" in caption and "red dots" not in caption
