"""The laser robot simulator (``probslam.sim_laser``): its ray caster against a brute-force loop
solving each ray-segment pair as a 2x2 linear system, the simulated readings against that loop,
the odometry kinds' statistics against their models, determinism by seed, and the writers' round
trip through probslam's own readers (CARMEN, ROS 1 / ROS 2 bags, TUM)."""

import importlib.util
import math

import numpy as np
import pytest

from probslam import geometry
from probslam import sim_laser as sl
from probslam.io import has_odometry, read_carmen_log, read_rosbag, read_trajectory
from probslam.io.carmen import ODOMETRY_NOISE_PARAM

needs_rosbags = pytest.mark.skipif(importlib.util.find_spec("rosbags") is None,
                                   reason="rosbags is not installed (pip install rosbags)")

#: The caster and the linear-system loop compute the same intersection two ways; in worlds of
#: tens of metres they agree to ~1e-13 m (rounding), 1e-9 m leaves room and catches any miss.
CAST_TOL = 1e-9
#: CARMEN poses and stamps are printed with 6 decimals: they read back within half of 1e-6.
PRINTED_6_TOL = 5e-7
#: A heading through a quaternion and atan2 comes back within a few ulps; x, y within 1e-15 m.
BAG_POSE_TOL = 1e-12
#: TUM files are printed with 9 decimals.
TUM_TOL = 5e-9


def brute_force_cast(segments, origin, angle):
    """The nearest segment along one ray, one segment at a time in plain Python: the 2x2 system
    t d - u e = p - o solved by Cramer's rule; inf when none is met."""
    dx, dy = math.cos(angle), math.sin(angle)
    ox, oy = float(origin[0]), float(origin[1])
    best = math.inf
    for x1, y1, x2, y2 in np.asarray(segments, float).tolist():
        ex, ey = x2 - x1, y2 - y1
        det = -dx * ey + ex * dy  # det [[dx, -ex], [dy, -ey]]
        if abs(det) < 1e-12:
            continue
        wx, wy = x1 - ox, y1 - oy
        t = (-wx * ey + ex * wy) / det
        u = (dx * wy - dy * wx) / det
        if t > 0 and 0 <= u <= 1:
            best = min(best, t)
    return best


def angle_gap(a, b):
    """|a - b| wrapped: headings of -pi + ulp and pi are the same."""
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


def test_cast_rays_matches_brute_force_on_random_segments():
    rng = np.random.default_rng(3)
    segs = rng.uniform(-10, 10, (40, 4))
    origins = rng.uniform(-12, 12, (300, 2))
    angles = rng.uniform(-math.pi, math.pi, 300)
    fast = sl.cast_rays(segs, origins, angles)
    slow = np.array([brute_force_cast(segs, o, a) for o, a in zip(origins, angles)])
    assert np.array_equal(np.isinf(fast), np.isinf(slow))
    assert np.isfinite(fast).sum() > 100  # most rays hit something: the test compares distances
    np.testing.assert_allclose(fast[np.isfinite(fast)], slow[np.isfinite(slow)], rtol=0, atol=CAST_TOL)


def test_cast_rays_chunks_give_the_same_distances(monkeypatch):
    world = sl.make_world("office", 2)
    rng = np.random.default_rng(0)
    origins, angles = rng.uniform(3, 13, (500, 2)), rng.uniform(-4, 4, 500)
    whole = sl.cast_rays(world.segments, origins, angles)
    monkeypatch.setattr(sl, "CAST_CHUNK", 7 * len(world.segments))
    assert np.array_equal(sl.cast_rays(world.segments, origins, angles), whole)


@pytest.mark.parametrize("world, sensor", [("office", "stage"), ("repeated", "lds"), ("hall", "rplidar"),
                                           ("office", "sick"),
                                           pytest.param("corridor", "hokuyo", marks=pytest.mark.slow)])
def test_readings_are_the_brute_force_distances_with_the_sensor_noise(world, sensor):
    run = sl.simulate(world, sensor, "perfect", seed=4)
    s = run.sensor
    rows = np.random.default_rng(1).choice(len(run.truth), 2, replace=False)
    beams = s.angles()
    # 6 sigma of the noise at max range: readings of walls nearer than that to a range limit
    # may fall on either side of it, the rest must not.
    margin = 6 * max(s.sigma_abs, s.sigma_rel * s.max_range) + 1e-3
    for i in rows:
        truth = np.array([brute_force_cast(run.world.segments, run.truth[i, :2], run.truth[i, 2] + b) for b in beams])
        seen = np.isfinite(truth) & (truth < s.max_range - margin) & (truth > s.range_min + margin)
        r = run.ranges[i]
        sigma = np.maximum(s.sigma_abs, s.sigma_rel * truth[seen])
        # 6 sigma plus the mm rounding: a reading outside is no Gaussian noise of that sigma.
        assert np.all(np.abs(r[seen] - truth[seen]) <= 6 * sigma + 5e-4)
        never = ~np.isfinite(truth) | (truth > s.max_range + margin)
        assert np.all(run.no_return[i][never])
        if math.isinf(s.no_return):
            assert np.all(np.isinf(r[never]))
        else:
            assert np.all(r[never] == s.no_return)
        assert seen.sum() > 0.3 * len(beams)  # the robot sees its world: the test compares readings


def test_the_loop_returns_to_its_start_and_never_crosses_a_wall():
    for kind in sl.WORLDS:
        world = sl.make_world(kind, 5)
        poses = sl.drive_loop(world.waypoints, 0.1)
        np.testing.assert_allclose(poses[-1, :2], poses[0, :2], atol=1e-12)
        # every step is shorter than a wall is away: cast from each pose towards the next
        step = np.diff(poses[:, :2], axis=0)
        length = np.hypot(step[:, 0], step[:, 1])
        moving = length > 0
        free = sl.cast_rays(world.segments, poses[:-1][moving, :2], np.arctan2(step[moving, 1], step[moving, 0]))
        assert np.all(free > length[moving]), kind
        # and the robot keeps 0.3 m from every wall (a robot's radius)
        around = sl.cast_rays(world.segments, np.repeat(poses[:, :2], 36, axis=0),
                              np.tile(np.linspace(-math.pi, math.pi, 36, endpoint=False), len(poses)))
        assert around.min() > 0.3, kind


def test_same_seed_same_log_other_seed_other_log():
    a = sl.simulate("office", "stage", "poor", seed=7)
    b = sl.simulate("office", "stage", "poor", seed=7)
    c = sl.simulate("office", "stage", "poor", seed=8)
    for name in ("timestamps", "truth", "odometry", "ranges"):
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True)
    assert np.array_equal(a.world.segments, b.world.segments)
    assert not np.array_equal(a.world.segments, c.world.segments)
    assert not np.array_equal(a.odometry, c.odometry)


def test_perfect_odometry_is_the_truth_and_none_is_zero():
    perfect = sl.simulate("repeated", "stage", "perfect", seed=1)
    np.testing.assert_allclose(perfect.odometry[:, :2], perfect.truth[:, :2], atol=1e-12)
    assert angle_gap(perfect.odometry[:, 2], perfect.truth[:, 2]).max() < 1e-12
    none = sl.simulate("repeated", "stage", "none", seed=1)
    assert np.all(none.odometry == 0)
    assert not has_odometry(none.scans()) and has_odometry(perfect.scans())


def _step_errors(model, seed=0):
    truth = sl.drive_loop(sl.make_world("corridor", 0).waypoints, 0.1)
    odo = sl.simulate_odometry(truth, model, np.random.default_rng(seed))
    t, o = geometry.steps(truth), geometry.steps(odo)
    dist = np.hypot(t[:, 0], t[:, 1])
    return t, o, dist


def test_odometry_scale_drift_and_noise_match_the_model():
    model = sl.OdometryModel(scale=0.03, drift=math.radians(1.5), sigma_dist=0.03, sigma_turn=math.radians(1.5))
    t, o, dist = _step_errors(model)
    straight = dist > 0.01
    factor = np.hypot(o[straight, 0], o[straight, 1]) / dist[straight]
    n = straight.sum()
    # the mean within 4 standard errors of 1 + scale, the spread within 15 % of sigma_dist
    assert abs(factor.mean() - 1.03) < 4 * 0.03 / math.sqrt(n)
    assert abs(factor.std() / 0.03 - 1) < 0.15
    turn = np.arctan2(np.sin(o[:, 2] - t[:, 2]), np.cos(o[:, 2] - t[:, 2]))
    z = (turn - model.drift * dist) / (model.sigma_turn * (np.sqrt(dist) + np.abs(t[:, 2])))
    assert abs(z.mean()) < 4 / math.sqrt(len(z)) and abs(z.std() - 1) < 0.1
    # the whole path: 3 % long, and the heading drifted 1.5 deg per metre
    assert abs(np.hypot(o[:, 0], o[:, 1]).sum() / dist.sum() - 1.03) < 0.005


def test_odometry_slip_adds_distance_up_to_slip_max():
    model = sl.OdometryModel(slip_rate=1.0, slip_max=0.4)
    t, o, dist = _step_errors(model)
    straight = dist > 0.01
    extra = np.hypot(o[straight, 0], o[straight, 1]) / dist[straight] - 1
    assert extra.min() >= 0 and extra.max() <= 0.4
    assert abs(extra.mean() - 0.2) < 4 * 0.4 / math.sqrt(12 * straight.sum())  # uniform on [0, 0.4]
    none = sl.OdometryModel(slip_rate=0.0, slip_max=0.4)
    t, o, dist = _step_errors(none)
    np.testing.assert_allclose(o[:, :2], t[:, :2], atol=1e-12)
    assert angle_gap(o[:, 2], t[:, 2]).max() < 1e-12


@pytest.mark.parametrize("odometry", ["good", "none"])
def test_carmen_log_reads_back_as_simulated(tmp_path, odometry):
    run = sl.simulate("office", "lds", odometry, seed=2)
    sl.write_carmen(run, tmp_path / "sim.log")
    log = read_carmen_log(tmp_path / "sim.log")
    want = run.scans("carmen")
    assert log.skipped_rows == 0 and len(log.scans) == len(run.truth)
    assert np.array_equal(log.scans.ranges, want.ranges)  # mm values read back bit for bit
    for name in ("laser_poses", "robot_poses", "timestamps"):
        np.testing.assert_allclose(getattr(log.scans, name), getattr(want, name), rtol=0, atol=PRINTED_6_TOL)
    np.testing.assert_allclose(log.scans.beam_angles()[0], run.sensor.angles(), atol=1e-9)
    assert np.all(log.scans.max_ranges == run.sensor.max_range)
    assert len(log.odometry.poses) == (0 if odometry == "none" else len(run.truth))
    assert has_odometry(log.scans) == (odometry != "none")
    # the PARAM line, bit for bit (repr); NaN (stated nowhere) without odometry
    np.testing.assert_array_equal(log.scans.odometry_noise, want.odometry_noise)
    assert np.isnan(want.odometry_noise).all() == (odometry == "none")


@pytest.mark.parametrize("value", ["0.1,0,0.01", "0.1,0,0,0.1,0.05,0.005", "a,b,c,d,e,f", "0.1,0,0.01,0.1,nan,0.005"])
def test_a_malformed_odometry_noise_param_is_ignored_with_a_warning(tmp_path, value):
    run = sl.simulate("office", "lds", "good", seed=2)
    sl.write_carmen(run, tmp_path / "sim.log")
    text = (tmp_path / "sim.log").read_text().splitlines()
    text = [f"PARAM {ODOMETRY_NOISE_PARAM} {value}" if t.startswith("PARAM") else t for t in text]
    (tmp_path / "bad.log").write_text("\n".join(text) + "\n")
    with pytest.warns(UserWarning, match=ODOMETRY_NOISE_PARAM):
        log = read_carmen_log(tmp_path / "bad.log")
    assert np.isnan(log.scans.odometry_noise).all() and len(log.scans) == len(run.truth)


@needs_rosbags
@pytest.mark.parametrize("fmt, sensor, odometry", [("rosbag1", "lds", "poor"), ("rosbag2", "rplidar", "none"),
                                                   ("mcap", "stage", "perfect")])
def test_bag_reads_back_as_simulated(tmp_path, fmt, sensor, odometry):
    run = sl.simulate("repeated", sensor, odometry, seed=3)
    path = tmp_path / ("sim.bag" if fmt == "rosbag1" else "sim")
    sl.write_bag(run, path, format=fmt)
    log = read_rosbag(path)
    want = run.scans("carmen").ranges
    if run.sensor.no_return == 0:  # a 0 below the stated range_min is no reading (REP 117)
        want = np.where(run.no_return, np.nan, want)
    assert np.array_equal(log.scans.ranges, want, equal_nan=True)
    assert log.pose_source == ("none" if odometry == "none" else "odometry /odom")
    np.testing.assert_allclose(log.scans.laser_poses[:, :2], run.odometry[:, :2], rtol=0, atol=BAG_POSE_TOL)
    assert angle_gap(log.scans.laser_poses[:, 2], run.odometry[:, 2]).max() <= BAG_POSE_TOL
    np.testing.assert_allclose(log.scans.timestamps, run.timestamps, rtol=0, atol=1e-9)
    assert np.all(log.scans.max_ranges == run.sensor.max_range)


def test_truth_reads_back_from_tum(tmp_path):
    run = sl.simulate("hall", "rplidar", "good", seed=0)
    sl.write_truth(run, tmp_path / "truth.tum")
    tr = read_trajectory(tmp_path / "truth.tum")
    np.testing.assert_allclose(tr.timestamps, run.timestamps, rtol=0, atol=TUM_TOL)
    np.testing.assert_allclose(tr.poses[:, :2], run.truth[:, :2], rtol=0, atol=TUM_TOL)
    assert angle_gap(tr.poses[:, 2], run.truth[:, 2]).max() < 1e-8


def test_bad_arguments_name_themselves():
    with pytest.raises(ValueError, match="kind"):
        sl.make_world("cave")
    with pytest.raises(ValueError, match="sensor"):
        sl.simulate("office", "velodyne")
    with pytest.raises(ValueError, match="odometry"):
        sl.simulate("office", "lds", "great")
    with pytest.raises(ValueError, match="speed"):
        sl.simulate("office", "lds", speed=0.0)
    with pytest.raises(TypeError, match="world"):
        sl.simulate(3, "lds")


@needs_rosbags
@pytest.mark.parametrize("range_min", [-0.1, math.nan, math.inf, "0.1"])
def test_write_rosbag_refuses_a_bad_range_min_and_writes_nothing(tmp_path, range_min):
    from probslam.io import write_rosbag

    run = sl.simulate("repeated", "stage", "perfect", seed=0)
    with pytest.raises(ValueError, match="range_min"):
        write_rosbag(run.scans("driver"), tmp_path / "x.bag", range_min=range_min)
    assert not (tmp_path / "x.bag").exists()
