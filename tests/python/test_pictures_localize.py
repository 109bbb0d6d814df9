"""The picture of `probslam localize`, tested through its matplotlib objects (as test_pictures.py):
the estimate is drawn only where it converged and is broken at jumps (no straight lines across the
map from a global start), and the particle snapshots are spaced by travel (a robot standing still
does not give the same cloud twice)."""

from types import SimpleNamespace

import numpy as np
import pytest

from probslam import _core
from probslam.localization import LocalizationResult
from probslam.pipelines import SNAPSHOT_TRAVEL, TRACK_JUMP, LocalizationRun, snapshot_times

plt = pytest.importorskip("matplotlib.pyplot", reason="the pictures need matplotlib")


@pytest.fixture
def figures():
    """The figures drawn, closed after the test."""
    seen = []
    yield seen
    for fig in seen:
        plt.close(fig)


def _draw(result, figures):
    figures.append(LocalizationRun(None, _room(), result).draw(plt, title="t"))


def _room():
    g = _core.OccupancyGrid2D(0.1, 100, 60, origin=(0.0, 0.0))
    lo = np.full((60, 100), -3.0)
    lo[0, :] = lo[-1, :] = lo[:, 0] = lo[:, -1] = 3.0
    g.log_odds[:] = lo
    return g


def _result(converged, poses, snapshots=()):
    n = len(poses)
    t = np.arange(n, dtype=float)
    return LocalizationResult(timestamps=t, poses=np.asarray(poses, float), covariances=np.zeros((n, 3, 3)),
                              num_particles=np.full(n, 500), converged=np.asarray(converged, bool),
                              updated=np.ones(n, bool), convergence_time=float(np.argmax(converged)),
                              travel_to_converge=1.0, seconds=1.0, log_duration=float(n - 1),
                              snapshots=list(snapshots))


def _estimate_line(fig):
    (line,) = [ln for ln in fig.axes[0].get_lines() if ln.get_label().startswith("MCL estimate")]
    return np.column_stack([line.get_xdata(), line.get_ydata()]).astype(float)


def test_the_estimate_is_drawn_only_where_converged_and_broken_at_jumps(tmp_path, figures):
    # A global start: four scans of a wandering, unconverged estimate on both sides of the room,
    # then a converged track along y = 3 with one relocation (a 4 m jump) in it.
    wander = [[1.0, 1.0, 0.0], [9.0, 5.0, 0.0], [2.0, 5.0, 0.0], [8.0, 1.0, 0.0]]
    track = [[2.0 + 0.2 * k, 3.0, 0.0] for k in range(10)] + [[6.5 + 0.2 * k, 3.0, 0.0] for k in range(6)]
    converged = [False] * 4 + [True] * 16
    _draw(_result(converged, wander + track), figures)
    (fig,) = figures
    xy = _estimate_line(fig)
    drawn = xy[np.isfinite(xy[:, 0])]
    assert np.array_equal(drawn, np.array(track)[:, :2])  # every converged pose, nothing before
    pieces = np.split(xy, np.flatnonzero(np.isnan(xy[:, 0])))
    assert [len(p[np.isfinite(p[:, 0])]) for p in pieces] == [10, 6]  # broken once, at the jump
    steps = np.hypot(*np.diff(xy, axis=0).T)
    assert np.nanmax(steps) < TRACK_JUMP  # no drawn segment crosses the map
    assert "where converged" in fig.axes[0].get_lines()[0].get_label()


def test_snapshots_are_spaced_by_travel_not_time():
    """A robot that stands still for the first 80% of the log: snapshots at shares of time would
    all show it at its start; spaced by travel they show it at distinct places."""
    n = 500
    x = np.concatenate([np.zeros(400), np.linspace(0.0, 20.0, 100)])
    scans = SimpleNamespace(timestamps=np.arange(n, dtype=float), laser_poses=np.column_stack([x, np.zeros(n),
                                                                                               np.zeros(n)]))
    times = snapshot_times(scans)
    assert len(times) == len(SNAPSHOT_TRAVEL)
    at = x[np.searchsorted(scans.timestamps, times)]
    assert np.all(np.diff(at) > 0.3)  # each cloud further along the path than the one before
    assert at[-1] == pytest.approx(20.0)
    # No travel at all (a log without odometry): one snapshot, not four of the same cloud.
    still = SimpleNamespace(timestamps=scans.timestamps, laser_poses=np.zeros((n, 3)))
    assert snapshot_times(still) == [0.0]


def test_the_picture_draws_the_snapshots_it_is_given(tmp_path, figures):
    rng = np.random.default_rng(0)
    snaps = [(0.0, rng.uniform(0, 10, (300, 3))), (5.0, rng.normal(3.0, 0.1, (200, 3)))]
    poses = [[3.0 + 0.1 * k, 3.0, 0.0] for k in range(8)]
    _draw(_result([True] * 8, poses, snaps), figures)
    (fig,) = figures
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels[:3] == ["MCL estimate (where converged)", "particles at 0 s (300)", "particles at 5 s (200)"]
