"""Issue 48: an argument of a bound class (an OccupancyGrid2D, a Pose2, a BeamSensorModel) of the
wrong type is a one-line TypeError naming the argument, where pybind11's typed caster answered
with its list of signatures ("incompatible function arguments ... Invoked with: 3"); the right
type computes what it did."""

import numpy as np
import pytest

import probslam as ps
from probslam import _core

GRID = ps.OccupancyGrid2D(0.5, 8, 6)
OCCUPIED = np.zeros((6, 8), bool)
MODEL = ps.BeamSensorModel("laser", 5.0)
POSES, SCANS, ANGLES = np.zeros((1, 3)), np.full((1, 2), 1.0), np.array([0.0, 0.5])

#: (call with the wrong object, the argument named, the class expected).
CALLS = [
    (lambda w: ps.Pose2(1, 2, 0.5).compose(w), "other", "a Pose2"),
    (lambda w: ps.Pose2(1, 2, 0.5).between(w), "other", "a Pose2"),
    (lambda w: ps.BinaryMap2D(w, OCCUPIED), "grid", "an OccupancyGrid2D"),
    (lambda w: ps.BinaryMap2D.from_grid(w), "grid", "an OccupancyGrid2D"),
    (lambda w: ps.fuse_max([GRID, w]), r"grids\[1\]", "an OccupancyGrid2D"),
    (lambda w: ps.map_log_posterior(ps.BinaryMap2D(GRID, OCCUPIED), POSES, SCANS, ANGLES, w, 0.5), "model",
     "a BeamSensorModel"),
    (lambda w: _core.map_occupancy_grid_mapping(POSES, SCANS, ANGLES, w, GRID), "model", "a BeamSensorModel"),
    (lambda w: _core.map_occupancy_grid_mapping(POSES, SCANS, ANGLES, MODEL, w), "grid", "an OccupancyGrid2D"),
    (lambda w: ps.LikelihoodField(w), "grid", "an OccupancyGrid2D"),
    (lambda w: ps.CorrelativeScanMatcher(w), "field", "a LikelihoodField"),
]
WRONG = [3, None, np.zeros(3), "x", ps.PoseGraph2D()]


@pytest.mark.parametrize("call, name, expected", CALLS)
@pytest.mark.parametrize("wrong", WRONG, ids=lambda w: type(w).__name__)
def test_a_wrong_class_is_a_type_error_naming_the_argument(call, name, expected, wrong):
    with pytest.raises(TypeError, match=rf"^{name}: expected {expected}, got {type(wrong).__name__}$"):
        call(wrong)


@pytest.mark.parametrize("call, message", [
    (lambda: ps.fuse_max(3), "^grids: expected a sequence of OccupancyGrid2D, got int"),
    (lambda: ps.fuse_max("grids"), "^grids: expected a sequence of OccupancyGrid2D, got str"),
    (lambda: ps.BeamSensorModel(3, 5.0), "^shape must be a str"),
    (lambda: ps.BeamSensorModel("laser", "5"), "^max_range must be a real number"),
    (lambda: ps.BeamSensorModel("laser", 5.0, z_hit=None), "^z_hit must be a real number"),
    (lambda: ps.OccupancyGrid3D.read_bt(3), r"^path: expected a file path"),
    (lambda: ps.OccupancyGrid3D.read_bt("x.bt", p_hit="0.7"), "^p_hit must be a real number"),
    (lambda: ps.OccupancyGrid3D(0.2).write_bt(None), r"^path: expected a file path"),
])
def test_other_arguments_of_these_calls_are_named(call, message):
    with pytest.raises(TypeError, match=message) as caught:
        call()
    assert "\n" not in str(caught.value)


def test_the_checked_calls_compute_what_they_did(tmp_path):
    """Pose composition by hand; a thresholded map; the cell-wise maximum; a .bt round trip."""
    a, b = ps.Pose2(1.0, 2.0, 0.5), ps.Pose2(0.3, -0.2, 0.4)
    c = a.compose(b)
    np.testing.assert_allclose(c.as_array(), [1.0 + 0.3 * np.cos(0.5) + 0.2 * np.sin(0.5),
                                              2.0 + 0.3 * np.sin(0.5) - 0.2 * np.cos(0.5), 0.9], atol=1e-12)
    np.testing.assert_allclose(a.between(c).as_array(), b.as_array(), atol=1e-12)
    grid = ps.OccupancyGrid2D(0.5, 8, 6)
    other = ps.OccupancyGrid2D(0.5, 8, 6)
    grid.insert_rays((1.0, 1.0, 0.0), [1.5], [0.0], max_range=5.0)
    other.insert_rays((1.0, 2.0, 0.0), [1.0], [0.0], max_range=5.0)
    np.testing.assert_array_equal(ps.fuse_max((grid, other)).log_odds, np.maximum(grid.log_odds, other.log_odds))
    np.testing.assert_array_equal(ps.BinaryMap2D.from_grid(grid).occupied, grid.log_odds > 0)
    voxels = ps.OccupancyGrid3D(0.2)
    voxels.insert_point_cloud(np.array([[1.0, 0.0, 0.5]]), (0.0, 0.0, 0.5))
    voxels.write_bt(tmp_path / "v.bt")
    back = ps.OccupancyGrid3D.read_bt(str(tmp_path / "v.bt"))
    np.testing.assert_array_equal(back.occupied_voxels()[0], voxels.occupied_voxels()[0])


def test_settable_properties_check_their_value_by_name():
    """A settable property of a stateful class refuses a wrong value naming itself (pybind11's
    typed setter listed its signatures instead), and a failed set changes nothing; EkfSlam's
    gate_distance is a property (setting a name that is none would add an attribute silently)."""
    grid = ps.OccupancyGrid2D(0.5, 8, 6)
    ekf = ps.EkfSlam(np.eye(2) * 0.01, np.eye(2) * 0.01)
    for obj, name, bad, error in [(grid, "p_hit", "0.9", TypeError), (grid, "p_miss", None, TypeError),
                                  (grid, "p_hit", 1.5, ValueError), (ekf, "gate_distance", "x", TypeError),
                                  (ekf, "gate_distance", -1.0, ValueError)]:
        before = getattr(obj, name)
        with pytest.raises(error, match=f"^{name}"):
            setattr(obj, name, bad)
        assert getattr(obj, name) == before
    ekf.gate_distance = 2.5
    grid.p_hit = 0.9
    assert ekf.gate_distance == 2.5 and grid.p_hit == 0.9 and "gate_distance" not in vars(ekf)
