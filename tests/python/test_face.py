"""The face of every stateful class (docs/api.md): copy(), save / load and pickling that give
the same state, a pose or poses, and a line in docs/api.md. A class added without them fails
here."""

import pathlib
import pickle

import numpy as np
import pytest

import probslam as ps
import walled_room
from test_pose_graph import two_pose_graph

API = (pathlib.Path(__file__).resolve().parents[2] / "docs" / "api.md").read_text()


def room():
    return walled_room.room(0.1, 40, 30)


def ekf():
    f = ps.EkfSlam(np.diag([0.01, 0.01]), np.diag([0.01, 0.001]))
    f.predict(1.0, 0.1, 0.1)
    f.update(np.array([[4.0, 0.3], [6.0, -0.5]]), np.array([0, 1]))
    return f


def pose_graph_3d():
    return ps.graph.read_pose_graph_3d(ps.data.path("parking_garage_400.g2o"))


def grid_3d():
    g = ps.OccupancyGrid3D(0.2)
    g.insert_point_cloud(np.array([[1.0, 0.5, 0.2], [2.0, -1.0, 0.4]]), [0.0, 0.0, 0.0])
    return g


def scan_matcher():
    from test_incremental_scan_matching import ANGLES, drive
    true, odo, ranges = drive(8)
    m = ps.IncrementalScanMatcher(filter={"max_range": 30.0})
    m.add_scans(ranges, ANGLES, odo, np.arange(len(true), dtype=float))
    return m


#: Every stateful class, built and moved a little: (name, factory).
STATEFUL = [
    ("EkfSlam", ekf),
    ("MultiHypothesisEkfSlam", lambda: ps.MultiHypothesisEkfSlam(ekf())),
    ("FastSlam", lambda: ps.FastSlam(np.diag([0.01, 0.01, 0.002]), np.diag([0.01, 0.001]), num_particles=10, seed=1)),
    ("GridFastSlam", lambda: ps.GridFastSlam(num_particles=2)),
    ("SubmapSlam2D", lambda: ps.SubmapSlam2D()),
    ("IncrementalScanMatcher", scan_matcher),
    ("MonteCarloLocalization", lambda: ps.MonteCarloLocalization(room(), min_particles=20, max_particles=40)),
    ("OccupancyGrid2D", room),
    ("OccupancyGrid3D", grid_3d),
    ("PoseGraph2D", two_pose_graph),
    ("PoseGraph3D", pose_graph_3d),
]


def state(obj):
    """The object's state as bytes: its pickle (the C++ state file's bytes underneath)."""
    return pickle.dumps(obj)


@pytest.mark.parametrize("name, make", STATEFUL, ids=[n for n, _ in STATEFUL])
def test_copy_save_load_and_pickle_keep_the_state(name, make, tmp_path):
    obj = make()
    twin = obj.copy()
    assert twin is not obj and state(twin) == state(obj)
    obj.save(tmp_path / "s.psl")
    assert state(type(obj).load(tmp_path / "s.psl")) == state(obj)
    assert state(pickle.loads(pickle.dumps(obj))) == state(obj)


@pytest.mark.parametrize("name, make", STATEFUL, ids=[n for n, _ in STATEFUL])
def test_the_class_is_on_the_api_page(name, make):
    assert f"`{name}`" in API, f"docs/api.md does not list {name}"


@pytest.mark.parametrize("name, make", [s for s in STATEFUL if "Grid" not in s[0] or "FastSlam" in s[0]],
                         ids=[n for n, _ in STATEFUL if "Grid" not in n or "FastSlam" in n])
def test_filters_and_graphs_have_a_pose_or_poses(name, make):
    obj = make()
    assert hasattr(obj, "pose") or hasattr(obj, "poses")


def test_a_copy_is_independent():
    a = ekf()
    b = a.copy()
    b.predict(1.0, 0.5, 1.0)
    assert not np.array_equal(a.pose, b.pose)
    m = ps.MultiHypothesisEkfSlam(ekf())
    c = m.copy()
    c.predict(1.0, 0.5, 1.0)
    assert not np.array_equal(m.pose, c.pose)
    g = grid_3d()
    h = g.copy()
    h.clear()
    assert g.num_known_voxels > 0 == h.num_known_voxels
