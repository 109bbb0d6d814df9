"""Readable __repr__s of the main classes: the class name and what sizes it, not an address."""

import re

import numpy as np
import pytest

import probslam as ps
from probslam import _core


def no_address(text: str) -> bool:
    return re.search(r"0x[0-9a-f]{6,}", text) is None


def test_occupancy_grids():
    g = ps.OccupancyGrid2D(0.05, 400, 300, origin=(-10.0, -7.5))
    assert repr(g) == "<OccupancyGrid2D: 400 x 300 cells of 0.05 m, origin (-10, -7.5) m>"
    g3 = ps.OccupancyGrid3D(0.1)
    assert repr(g3) == "<OccupancyGrid3D: 0.1 m voxels, 0 known, 0 occupied, 0 blocks>"
    g3.insert_point_cloud(np.array([[1.0, 0.0, 0.0]]), (0.0, 0.0, 0.0))
    r = repr(g3)
    assert r.startswith("<OccupancyGrid3D: 0.1 m voxels, ") and " 1 occupied, " in r and not r.startswith(
        "<OccupancyGrid3D: 0.1 m voxels, 0 known")


def test_pose_graph_and_reports():
    g = ps.PoseGraph2D()
    assert repr(g) == "<PoseGraph2D: 0 poses, 0 landmarks, 0 edges>"
    g.add_pose(0, (0.0, 0.0, 0.0))
    g.add_pose(1, (1.1, 0.0, 0.0))
    g.add_point(7, (2.0, 1.0))
    g.add_pose_edge(0, 1, (1.0, 0.0, 0.0), np.eye(3))
    g.add_point_edge(1, 7, (1.0, 1.0), np.eye(2))
    assert repr(g) == "<PoseGraph2D: 2 poses, 1 landmarks, 2 edges>"
    report = ps.optimize(g.copy())
    r = repr(report)
    assert r.startswith("<OptimizationReport: ") and " iterations, chi2 0.02 -> " in r and "converged" in r
    inc = ps.graph.optimize_incremental(g.copy(), poses_per_step=1)
    assert re.fullmatch(r"<IncrementalReport: \d+ steps, \d+ iterations, chi2 \S+>", repr(inc))


def test_pose2():
    assert repr(ps.Pose2(1.0, -2.5, 0.25)) == "Pose2(x=1, y=-2.5, theta=0.25)"


def test_beam_model_and_binary_map():
    laser = ps.BeamSensorModel("laser", 20.0)
    assert repr(laser) == ("<BeamSensorModel: laser, max_range 20 m, z_hit 0.85, z_short 0.05, z_max 0.05, "
                           "z_rand 0.05, sigma_hit 0.05 m, lambda_short 1 1/m>")
    sonar = ps.BeamSensorModel("sonar", 5.0, beta=0.35)
    assert repr(sonar).startswith("<BeamSensorModel: sonar, max_range 5 m, beta 0.35 rad, ")
    grid = ps.OccupancyGrid2D(0.1, 4, 3)
    occupied = np.zeros((3, 4), bool)
    occupied[1, 2] = True
    assert repr(ps.BinaryMap2D(grid, occupied)) == "<BinaryMap2D: 4 x 3 cells of 0.1 m, 1 occupied>"


def test_filters():
    ekf = ps.EkfSlam(np.diag([0.01, 0.01, 0.001]), np.diag([0.01, 0.001]), use_signatures=False)
    assert repr(ekf) == "<EkfSlam: 0 landmarks, state 3, pose (0, 0, 0)>"
    ekf.update(np.array([[2.0, 0.0]]), np.array([4]))
    assert repr(ekf).startswith("<EkfSlam: 1 landmarks, state 5, pose (")
    mht = ps.MultiHypothesisEkfSlam(ekf)
    assert re.fullmatch(r"<MultiHypothesisEkfSlam: 1 hypotheses, best 1 landmarks, cost \S+>", repr(mht))
    # An options class shows every field as its constructor takes it: the repr rebuilds it.
    options = ps.MapManagement(provisional=True, sensor_range=12.5)
    assert repr(options).startswith("MapManagement(provisional=True, min_observations=3, ")
    assert eval(repr(options), {"MapManagement": ps.MapManagement, "inf": float("inf")}) == options
    fs = ps.FastSlam(np.diag([0.01, 0.01, 0.001]), np.diag([0.01, 0.001]), num_particles=10, version=2)
    assert repr(fs) == "<FastSlam: version 2, 10 particles, best has 0 landmarks, N_eff 10>"
    rbpf = _core.GridFastSlam(num_particles=3)
    assert repr(rbpf) == "<GridFastSlam: 3 particles, 0 scans, best 0>"


def test_laser_slam_classes():
    assert repr(_core.SubmapSlam2D()) == "<SubmapSlam2D: 0 scans, 0 submaps, 0 loop closures>"
    assert repr(_core.IncrementalScanMatcher()) == "<IncrementalScanMatcher: 0 scans, 0 submaps>"
    grid = ps.OccupancyGrid2D(0.05, 40, 40)
    grid.log_odds[10, 10:30] = 5.0
    field = _core.LikelihoodField(grid)
    assert repr(field) == "<LikelihoodField: 40 x 40 cells of 0.05 m, 20 occupied, sigma 0.05 m>"
    matcher = _core.CorrelativeScanMatcher(field)
    points = np.column_stack([np.linspace(0.55, 1.45, 10), np.full(10, 0.525)])
    result = matcher.match(points, (0.0, 0.0, 0.0))
    assert re.fullmatch(r"<MatchResult: pose \(\S+, \S+, \S+\), score \S+, match_quality \S+, 10 points>", repr(result))


@pytest.mark.parametrize("name", ["OccupancyGrid2D", "OccupancyGrid3D", "PoseGraph2D", "OptimizationReport",
                                  "IncrementalReport", "BeamSensorModel", "BinaryMap2D", "FastSlam", "GridFastSlam",
                                  "SubmapSlam2D", "IncrementalScanMatcher", "LikelihoodField", "MatchResult",
                                  "MapManagement", "MultiHypothesisOptions", "_EkfSlam", "_MultiHypothesisEkfSlam"])
def test_main_classes_define_their_own_repr(name):
    cls = getattr(_core, name)
    assert "__repr__" in vars(cls), f"{name} shows an address"


def test_reprs_show_no_address():
    for obj in (ps.OccupancyGrid2D(1.0, 2, 2), ps.PoseGraph2D(), ps.BeamSensorModel("laser", 10.0),
                _core.MultiHypothesisOptions()):
        assert no_address(repr(obj)), repr(obj)
