"""The Python modules' public functions name a wrong argument: TypeError for a wrong type,
ValueError for a wrong shape or value, raised before any work (an AttributeError or IndexError
from deep inside would name nothing)."""

import numpy as np
import pytest

import probslam as ps
from probslam import eval as ev
from probslam import inverse_learning as il
from probslam import landmark_slam as ls
from probslam import mapping, sim
from probslam import slam as sl
from probslam.datasets import mrclam, victoria_park

RNG = np.random.default_rng(0)
GRID = ps.OccupancyGrid2D(0.1, 20, 20)
Q = np.diag([0.01, 0.001])

# (call, argument it must name) with an object of the wrong type in that argument.
WRONG_TYPES = [
    (lambda: mrclam.perceptual_field(None), "data"),
    (lambda: mrclam.run_ekf("folder", Q, Q), "data"),
    (lambda: ev.score_mrclam(object(), None), "result"),
    (lambda: ev.majority_labels({}), "result"),
    (lambda: ev.primary_landmarks([]), "result"),
    (lambda: ev.association_accuracy(None), "result"),
    (lambda: mrclam.fit_range_scale(3), "data"),
    (lambda: mrclam.same_scan_residuals(None), "data"),
    (lambda: mrclam.survey_label_swaps(None), "data"),
    (lambda: ev.score_landmarks([(0, 0)], None), "landmarks"),
    (lambda: mrclam.dead_reckoning_map(None), "data"),
    (lambda: victoria_park.run_ekf(None), "data"),
    (lambda: ls.run_ekf_on_graph("graph.g2o"), "graph"),
    (lambda: ls.polar_measurements([["a", "b"]], np.eye(2)[None]), "xy"),
    (lambda: mrclam.run_fastslam(None, Q, Q), "data"),
    (lambda: victoria_park.run_fastslam(None), "data"),
    (lambda: ps.run_landmark_slam(3), "dataset"),
    (lambda: mapping.scan_bounds(None, 10.0), "scans"),
    (lambda: ps.map_laser_log("log.clf"), "scans"),
    (lambda: ps.io.has_odometry(None), "scans"),
    (lambda: sim.observe(np.zeros(3), None, sim.Sensor(Q), RNG), "world"),
    (lambda: sim.observe(np.zeros(3), sim.LandmarkWorld(np.zeros((1, 2)), np.zeros(1)), None, RNG), "sensor"),
    (lambda: sim.observe(np.zeros(3), sim.LandmarkWorld(np.zeros((1, 2)), np.zeros(1)), sim.Sensor(Q), 0), "rng"),
    (lambda: sim.pose_error("abc", np.zeros(3)), "estimate"),
    (lambda: sim.filter_known(None, Q, Q), "run"),
    (lambda: sim.fastslam_known(None, Q, Q, 10), "run"),
    (lambda: il.random_map(None, RNG), "grid"),
    (lambda: il.random_map(GRID, 0), "rng"),
    (lambda: il.free_poses(None, np.zeros((20, 20), bool), 3, RNG), "grid"),
    (lambda: il.field_features(None, np.zeros(3), np.ones(4), np.zeros(4), 5.0, 0.1), "grid"),
    (lambda: il.sample_training_set(GRID, None, np.zeros(4), 1, 1, RNG), "model"),
]


@pytest.mark.parametrize("call, name", WRONG_TYPES)
def test_a_wrong_type_is_a_type_error_naming_the_argument(call, name):
    with pytest.raises(TypeError, match=f"^{name}: expected"):
        call()


# (call, argument it must name) with a value of the right type but the wrong shape or value.
WRONG_VALUES = [
    (lambda: ev.align_rigid(np.zeros((3, 2)), np.zeros((4, 2))), "truth"),
    (lambda: ev.align_rigid(np.zeros((0, 2)), np.zeros((0, 2))), "estimate"),
    (lambda: ev.align_rigid(np.full((3, 2), np.nan), np.zeros((3, 2))), "estimate"),
    (lambda: ev.truth_positions(np.zeros((5, 2)), np.zeros(3)), "groundtruth"),
    (lambda: ev.truth_positions(np.zeros((0, 3)), np.zeros(3)), "groundtruth"),
    (lambda: ev.truth_positions(np.zeros((5, 3)), np.zeros((3, 1))), "times"),
    (lambda: ls.polar_measurements(np.zeros((2, 2)), np.tile(np.eye(2), (2, 1, 1))), "xy"),
    (lambda: ls.polar_measurements(np.ones((2, 2)), np.eye(2)), "xy_cov"),
    (lambda: sim.pose_error(np.zeros(2), np.zeros(3)), "estimate"),
    (lambda: sim.pose_error(np.zeros(3), np.zeros((4, 2))), "truth"),
    (lambda: sim.cast_ranges(np.zeros(2), np.zeros(3), []), "pose"),
    (lambda: sim.cast_ranges(np.zeros(3), np.full(3, np.inf), []), "angles"),
    (lambda: sim.observe(np.array([0.0, np.nan, 0.0]), sim.LandmarkWorld(np.zeros((1, 2)), np.zeros(1)),
                         sim.Sensor(Q), RNG), "pose"),
    (lambda: il.free_poses(GRID, np.zeros((20, 21), bool), 3, RNG), "occupied"),
    (lambda: il.free_poses(GRID, np.zeros((20, 20)), 3, RNG), "occupied"),
    (lambda: il.field_features(GRID, np.zeros(4), np.ones(4), np.zeros(4), 5.0, 0.1), "pose"),
]


@pytest.mark.parametrize("call, name", WRONG_VALUES)
def test_a_wrong_shape_or_value_is_a_value_error_naming_the_argument(call, name):
    with pytest.raises(ValueError, match=f"^{name}: "):
        call()


def test_checked_functions_still_compute_what_they_did():
    """The checks change no result: Kabsch recovers a known motion, polar_measurements equals
    the hand conversion, pose_error wraps the heading, cast_ranges hits a wall at its distance."""
    rng = np.random.default_rng(1)
    points = rng.normal(size=(6, 2))
    angle, shift = 0.3, np.array([1.0, -2.0])
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    r, t = ev.align_rigid(points, points @ rot.T + shift)
    np.testing.assert_allclose(r, rot, atol=1e-12)
    np.testing.assert_allclose(t, shift, atol=1e-12)
    z, cov = ls.polar_measurements(np.array([[3.0, 4.0]]), np.eye(2)[None] * 0.01)
    np.testing.assert_allclose(z, [[5.0, np.arctan2(4.0, 3.0)]])
    np.testing.assert_allclose(cov[0], np.diag([0.01, 0.01 / 25.0]), atol=1e-15)
    np.testing.assert_allclose(sim.pose_error([0, 0, 3.0], [0, 0, -3.0]), [0, 0, 6.0 - 2 * np.pi])
    np.testing.assert_allclose(sim.cast_ranges([0, 0, 0], [0.0], [((2.0, -1.0), (2.0, 1.0))]), [2.0])
    truth = np.column_stack([[0.0, 1.0], [0.0, 2.0], [0.0, 4.0]])
    np.testing.assert_allclose(ev.truth_positions(truth, [0.5]), [[1.0, 2.0]])


# Integer options read by the bindings' keyword parser and GridFastSlam's particle argument:
# an array of several numbers (which has __index__ but refuses it) or an int beyond 64 bits
# was a RuntimeError ("Unable to cast Python instance ...") from pybind11's cast.
INT_OPTIONS = [
    (lambda v: ps.FastSlam(np.eye(2) * 0.01, Q, num_particles=5, threads=v), "threads"),
    (lambda v: ps.FastSlam(np.eye(2) * 0.01, Q, num_particles=5, version=v), "version"),
    (lambda v: ps.FastSlam(np.eye(2) * 0.01, Q, num_particles=5, seed=v), "seed"),
    (lambda v: ps._core.GridFastSlam(num_particles=v), "num_particles"),
    (lambda v: ps._core.GridFastSlam(threads=v), "threads"),
    (lambda v: ps._core.SubmapSlam2D(max_rounds=v), "max_rounds"),
    (lambda v: ps._core.SubmapSlam2D(closures={"scans_per_submap": v}), "closures.scans_per_submap"),
    (lambda v: ps._core.GridFastSlam(matching={"refinements": v}), "matching.refinements"),
    (lambda v: ps._core.GridFastSlam(num_particles=2).map(v), "particle"),
    (lambda v: ps._core.GridFastSlam(num_particles=2).path(v), "particle"),
    (lambda v: ps.FastSlam(np.eye(2) * 0.01, Q, num_particles=5).path(v), "particle"),
    (lambda v: ps.FastSlam(np.eye(2) * 0.01, Q, num_particles=5).landmarks(v), "particle"),
]


@pytest.mark.parametrize("call, name", INT_OPTIONS)
def test_int_options_refuse_arrays_and_out_of_range_ints_by_name(call, name):
    for value in (np.array([1, 2]), np.zeros(3), True, 2.0, "2"):
        with pytest.raises(TypeError, match=f"^{name} must be an int"):
            call(value)
    for value in (10 ** 30, -10 ** 30):
        with pytest.raises(ValueError, match=f"^{name} "):
            call(value)


def test_int_options_take_numpy_integers():
    f = ps.FastSlam(np.eye(2) * 0.01, Q, num_particles=5, threads=np.int64(2), seed=np.uint8(3))
    assert f.num_particles == 5
    g = ps._core.GridFastSlam(num_particles=np.int32(2))
    assert g.num_particles == 2
    with pytest.raises(ValueError, match="^particle has no map before the first scan"):
        g.map(np.int64(1))
    with pytest.raises(ValueError, match="^particle must be in"):
        g.map(2)


@pytest.mark.parametrize("method", ["landmark", "landmark_covariance", "existence", "remove_landmark"])
def test_ekf_landmark_ids_are_integers(method):
    """int() truncated a float id (2.7 read landmark 2) and raised OverflowError on inf."""
    ekf = ps.EkfSlam(np.eye(2) * 0.01, Q, use_signatures=False)
    ekf.update(np.array([[2.0, 0.1]]), [2])
    call = getattr(ekf, method)
    for value in (2.7, 2.0, float("inf"), float("nan"), True, "2", None):
        with pytest.raises(TypeError, match="^id must be an integer"):
            call(value)
    for value in (2 ** 63, -2 ** 70):
        with pytest.raises(ValueError, match=r"^id must lie in \[-9223372036854775808, 9223372036854775807\], got "):
            call(value)
    call(np.int64(2))  # numpy integers are ids


def test_learned_inverse_model_hidden_units_are_an_integer():
    for value in (2.5, "16", None, True):
        with pytest.raises(TypeError, match="^hidden must be an integer"):
            il.LearnedInverseModel(value)
    with pytest.raises(ValueError, match="^hidden must be >= 1"):
        il.LearnedInverseModel(0)
    assert il.LearnedInverseModel(np.int64(3)).hidden == 3


def test_writers_check_what_they_write(tmp_path):
    out = tmp_path / "x"
    with pytest.raises(TypeError, match="^grid: expected OccupancyGrid2D"):
        ps.io.write_png("map", out)
    for bad in (np.zeros((4, 4)), np.zeros(3), np.zeros((2, 3, 1))):
        with pytest.raises(ValueError, match="^trajectory: expected shape"):
            ps.io.write_png(GRID, out, trajectory=bad)
    with pytest.raises(TypeError, match="^trajectory: expected real numbers"):
        ps.io.write_png(GRID, out, trajectory=[["a", "b"]])
    with pytest.raises(ValueError, match="^poses: expected shape"):
        sl.write_trajectory(np.arange(3.0), np.zeros((2, 3)), out)
    with pytest.raises(ValueError, match="^timestamps: contains NaN"):
        sl.write_trajectory(np.array([0.0, np.nan]), np.zeros((2, 3)), out)
    assert not out.exists()
    ps.io.write_png(GRID, out, trajectory=np.array([[0.05, 0.25], [np.nan, 0.0]]))  # non-finite rows left out
    sl.write_trajectory(np.arange(2.0), np.ones((2, 3)), tmp_path / "t.txt")
    np.testing.assert_allclose(np.loadtxt(tmp_path / "t.txt"), np.column_stack([np.arange(2.0), np.ones((2, 3))]))
