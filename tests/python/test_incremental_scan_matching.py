"""Incremental scan matching (IncrementalScanMatcher): on a simulated drive through a known room
with drifting odometry, the matched trajectory stays close to the truth while odometry drifts."""

import re

import numpy as np
import pytest

import probslam as ps
from probslam import _core
from probslam.sim import cast_ranges

# A 10 m x 8 m room with a box and a slanted wall, off the cell borders of any 5 cm grid.
WALLS = [((-5.01, -4.02), (5.03, -4.02)), ((5.03, -4.02), (5.03, 3.97)), ((5.03, 3.97), (-5.01, 3.97)),
         ((-5.01, 3.97), (-5.01, -4.02)), ((1.01, 1.02), (2.03, 1.02)), ((2.03, 1.02), (2.03, 2.04)),
         ((2.03, 2.04), (1.01, 2.04)), ((1.01, 2.04), (1.01, 1.02)), ((-3.02, -2.01), (-1.03, -3.04))]
ANGLES = np.linspace(-np.pi / 2, np.pi / 2, 181)


def cast(pose, angles=ANGLES):
    """Ranges from `pose` to the nearest wall along each beam (inf where none)."""
    return cast_ranges(pose, angles, WALLS)


def drive(n=120, seed=3):
    """A loop around the box: true poses, drifting odometry poses, noisy ranges."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 2 * np.pi, n)
    true = np.stack([1.5 + 2.2 * np.cos(s), 1.5 + 2.2 * np.sin(s), s + np.pi / 2], axis=1)
    true[:, 2] = np.arctan2(np.sin(true[:, 2]), np.cos(true[:, 2]))
    odo = [true[0].copy()]
    for k in range(1, n):
        d = ps.Pose2(*true[k - 1]).between(ps.Pose2(*true[k]))
        step = np.array([d.x, d.y, d.theta]) * (1 + rng.normal(0, 0.05, 3)) + [0.0, 0.0, 0.01]
        odo.append(np.asarray(ps.Pose2(*odo[-1]).compose(ps.Pose2(*step)).as_array()))
    ranges = np.stack([cast(p) + rng.normal(0, 0.01, len(ANGLES)) for p in true])
    return true, np.array(odo), ranges


def test_matched_trajectory_beats_drifting_odometry():
    true, odo, ranges = drive()
    ism = _core.IncrementalScanMatcher(filter={"max_range": 30.0}, submap_distance=0.0, update=_core.UpdateTrigger())
    ism.add_scans(ranges, ANGLES, odo, np.arange(len(true), dtype=float))
    err = np.linalg.norm(ism.scan_poses[:, :2] - true[:, :2], axis=1)
    odo_err = np.linalg.norm(odo[:, :2] - true[:, :2], axis=1)
    info = ism.scan_info
    assert info[:, 0].all()  # every scan matched
    assert odo_err.max() > 0.5  # the odometry really drifts
    assert err.max() < 0.1, err.max()  # a couple of cells at most, after a full loop


def test_submaps_cut_by_travel():
    true, odo, ranges = drive()
    ism = _core.IncrementalScanMatcher(filter={"max_range": 30.0}, submap_distance=5.0, update=_core.UpdateTrigger())
    ism.add_scans(ranges, ANGLES, odo, np.arange(len(true), dtype=float))
    travel = np.linalg.norm(np.diff(ism.scan_poses[:, :2], axis=0), axis=1).sum()
    assert ism.num_submaps == int(travel // 5.0) + 1 or ism.num_submaps == int(travel // 5.0)
    assert isinstance(ism.submap_grid(0), ps.OccupancyGrid2D)
    with pytest.raises(ValueError, match="index"):
        ism.submap_grid(ism.num_submaps)


def test_scans_without_motion_are_not_matched():
    true, odo, ranges = drive(n=10)
    still = np.repeat(odo[:1], 5, axis=0)
    ism = _core.IncrementalScanMatcher(filter={"max_range": 30.0})
    ism.add_scans(ranges[:5], ANGLES, still, np.arange(5.0))
    assert ism.scan_info[1:, 0].sum() == 0
    np.testing.assert_allclose(ism.scan_poses, still)


@pytest.mark.parametrize("kwargs, path", [
    (dict(resolution=0.0), "resolution"), (dict(filter={"max_range": -1.0}), "filter.max_range"),
    (dict(field={"sigma": float("nan")}), "field.sigma"), (dict(field={"p_rand": 1.5}), "field.p_rand"),
    (dict(match={"window": {"linear": -1.0}}), "match.window.linear"), (dict(submap_scans=-1), "submap_scans"),
    (dict(min_match_quality=2.0), "min_match_quality"), (dict(update={"angle": -0.1}), "update.angle"),
    (dict(odometry={"trans_floor": 0.0}), "odometry.trans_floor"),
    (dict(odometry={"rot_per_metre": -1.0}), "odometry.rot_per_metre")])
def test_bad_options_name_the_path(kwargs, path):
    with pytest.raises(ValueError, match="^" + re.escape(path) + " "):
        _core.IncrementalScanMatcher(**kwargs)


def test_option_types_name_the_path():
    with pytest.raises(TypeError, match=r"^odometry\.trans_floor"):
        _core.IncrementalScanMatcher(odometry={"trans_floor": "0.1"})
    with pytest.raises(TypeError, match=r"^odometry: expected an OdometryNoise or a dict"):
        _core.IncrementalScanMatcher(odometry=[0.1, 0.02, 0.01, 0.1, 0.05, 0.005])


def test_bad_scans_change_nothing():
    true, odo, ranges = drive(n=6)
    ism = _core.IncrementalScanMatcher(filter={"max_range": 30.0})
    ism.add_scans(ranges[:2], ANGLES, odo[:2], np.arange(2.0))
    bad_odo = odo[2:4].copy()
    bad_odo[1, 0] = np.nan
    with pytest.raises(ValueError, match="odometry"):
        ism.add_scans(ranges[2:4], ANGLES, bad_odo, np.arange(2.0))
    with pytest.raises(ValueError, match="beam_angles"):
        ism.add_scans(ranges[2:4], ANGLES[:-1], odo[2:4], np.arange(2.0))
    with pytest.raises(ValueError, match="timestamps"):
        ism.add_scans(ranges[2:4], ANGLES, odo[2:4], np.arange(3.0))
    with pytest.raises(TypeError, match="ranges"):
        ism.add_scans("x", ANGLES, odo[2:4], np.arange(2.0))
    assert ism.num_scans == 2
    # A scan whose every reading is invalid is no hit: it takes the odometry's motion.
    ism.add_scans(np.full((1, len(ANGLES)), np.nan), ANGLES, odo[2:3], np.array([2.0]))
    assert ism.num_scans == 3 and ism.scan_info[2, 4] == 0 and ism.scan_info[2, 0] == 0
