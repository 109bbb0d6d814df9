"""Laser SLAM's frontend on simulated robots (probslam.sim_laser, issue 51), against the exact
truth: a short-range laser must keep perfect odometry (the map's edge used to pull every scan
back towards the previous pose: 0.16 m ATE in the office, a corridor 37 % too short), and a log
without odometry predicts each scan with the last matched motion."""

import numpy as np
import pytest

import probslam as ps
from probslam import geometry, sim_laser
from probslam.eval import ate

#: The frontend on the Stage-like robot (5 m, 90 beams over 270 deg) with perfect odometry in
#: the office: 0.038 m ATE measured (0.156 m before the matched hits were limited to the mapped
#: range); 0.08 m leaves room for other seeds (0.03-0.05 m) and fails the old frontend.
OFFICE_PERFECT_ATE = 0.08
#: The same robot in the 40 x 12 m corridor ring: the frontend alone 0.24 m ATE, its path
#: 0.5 % short (before: 6.7 m and 37 % short, scale 1.585); 2 % and 0.5 m fail the old frontend by far.
CORRIDOR_SCALE_TOL = 0.02
CORRIDOR_PERFECT_ATE = 0.5
#: The same robot without odometry in the office, the frontend: 0.51 m ATE (3.0 m before the
#: constant-velocity prediction, whose "no motion" let the scans pull the path short).
NONE_OFFICE_ATE = 1.0


def similarity_scale(estimate, truth):
    """The scale of the 2-D similarity that best maps the estimated positions onto the true
    ones (Umeyama): > 1 where the estimate is too small."""
    e = estimate[:, 0] + 1j * estimate[:, 1]
    r = truth[:, 0] + 1j * truth[:, 1]
    e, r = e - e.mean(), r - r.mean()
    return float(abs(np.vdot(e, r)) / np.vdot(e, e).real)


#: The frontend here matches the hits within this share of the usable range (match_fraction;
#: the default, 1, matches every hit: see IncrementalScanMatcherOptions::match_fraction).
NEAR_HITS = 0.6


def frontend(world, odometry, seed=0, match_fraction=NEAR_HITS, search="fallback"):
    sim = sim_laser.simulate(world, "stage", odometry, seed=seed)
    scans = sim.scans()
    # As a log that does not state its odometry's noise (the fixed model, 1 cm a scan): the
    # stated noise of perfect odometry would hold the frontend on it whatever the matching does.
    scans.odometry_noise[:] = np.nan
    options = ps.slam.default_options(scans).replace(closures={"enabled": False},
                                                     frontend={"match_fraction": match_fraction,
                                                               "search": search})
    result = ps.slam.run_slam(scans, progress=False, options=options)
    return sim, result


def test_short_range_frontend_keeps_perfect_odometry_in_the_office():
    sim, result = frontend("office", "perfect")
    err = ate(result.timestamps, result.frontend_poses, sim.timestamps, sim.truth)
    assert err.rmse < OFFICE_PERFECT_ATE


def test_short_range_frontend_does_not_shrink_a_corridor():
    sim, result = frontend("corridor", "perfect")
    err = ate(result.timestamps, result.frontend_poses, sim.timestamps, sim.truth)
    assert err.rmse < CORRIDOR_PERFECT_ATE
    assert abs(similarity_scale(result.frontend_poses, sim.truth) - 1.0) < CORRIDOR_SCALE_TOL


def test_every_hit_matched_brings_the_edge_pull_back():
    # The cause, shown: with match_fraction 1 and the search for every scan the same corridor
    # shrinks by a third (the search's best lattice pose is pulled back by the map's edge); the
    # local optimiser from the prediction (issue 54's default) stays in the prediction's basin
    # and shrinks it much less (1.06 on seed 0).
    sim, result = frontend("corridor", "perfect", match_fraction=1.0, search="always")
    assert similarity_scale(result.frontend_poses, sim.truth) > 1.2
    sim, result = frontend("corridor", "perfect", match_fraction=1.0)
    assert similarity_scale(result.frontend_poses, sim.truth) < 1.1


#: Scans without a hit (the laser blinded) take the prediction: constant velocity carries the
#: path on by the mean matched motion of the 5 scans before (1 cm over 10 scans: the composition
#: of a slightly turning motion against its straight extrapolation); "no motion" stops it.
BLIND_SCANS, VELOCITY_SCANS, BLIND_TOL = 10, 5, 0.01


@pytest.mark.parametrize("constant_velocity", [True, False])
def test_without_odometry_blind_scans_continue_the_last_motion(constant_velocity):
    sim = sim_laser.simulate("office", "stage", "none", seed=0)
    scans = sim.scans()
    first = 30  # the robot drives straight from the start (drive_loop faces the next waypoint)
    scans.ranges[first:first + BLIND_SCANS] = sim.sensor.max_range  # no returns: nothing to match
    n = first + BLIND_SCANS
    # Without constant velocity, as run_slam ran such a log before: no prior ("no motion" in the
    # score holds the path at its start).
    m = ps.SubmapSlam2D(frontend=dict(filter={"max_range": sim.sensor.max_range}, update=ps.UpdateTrigger(),
                                      match={"window": {"linear": 0.5, "angular": 0.5}},
                                      constant_velocity=constant_velocity, use_odometry_prior=constant_velocity,
                                      match_fraction=NEAR_HITS), closures={"enabled": False})
    m.add_scans(scans.ranges[:n], scans.beam_angles()[:n], scans.laser_poses[:n], scans.timestamps[:n])
    poses = m.frontend_poses
    moved = np.hypot(*(poses[n - 1, :2] - poses[first - 1, :2]))
    velocity = np.hypot(*(poses[first - 1, :2] - poses[first - 1 - VELOCITY_SCANS, :2])) / VELOCITY_SCANS
    assert velocity > 0.02  # the robot was moving (0.05 m a scan)
    expected = BLIND_SCANS * velocity if constant_velocity else 0.0
    assert abs(moved - expected) < BLIND_TOL


def test_without_odometry_the_frontend_follows_the_office_loop():
    # The constant-velocity prior in the score: 0.51 m ATE (3.0 m with "no motion").
    sim, result = frontend("office", "none")
    err = ate(result.timestamps, result.frontend_poses, sim.timestamps, sim.truth)
    assert err.rmse < NONE_OFFICE_ATE


def test_default_options_follow_the_log():
    with_odometry = sim_laser.simulate("hall", "lds", "good", seed=0).scans()
    without = sim_laser.simulate("hall", "lds", "none", seed=0).scans()
    names = ("trans_per_metre", "trans_per_radian", "trans_floor", "rot_per_radian", "rot_per_metre", "rot_floor")
    stated = ps.OdometryNoise(**dict(zip(names, sim_laser.ODOMETRY["good"].stated_noise())))
    graph = ps.slam.default_options(with_odometry)
    assert isinstance(graph, ps.SubmapSlamOptions)
    expected = ps.SubmapSlamOptions()
    expected.frontend.filter.max_range = 3.5
    expected.frontend.odometry = stated
    assert graph == expected
    rbpf = ps.slam.default_options(with_odometry, method="rbpf")
    assert isinstance(rbpf, ps.GridFastSlamOptions)
    assert rbpf == ps.GridFastSlamOptions(filter={"max_range": 3.5}, odometry=stated)
    with_odometry.odometry_noise[:] = np.nan  # a log that states nothing: the fixed model
    expected.frontend.odometry = ps.OdometryNoise()
    assert ps.slam.default_options(with_odometry) == expected
    frontend = ps.slam.default_options(without).frontend
    assert frontend.filter.max_range == 3.5 and frontend.constant_velocity and frontend.update.distance == 0.0
    assert frontend.match.window.linear == 0.5
    assert not ps.slam.default_options(without, method="rbpf").corrector.constant_velocity
    with pytest.raises(ValueError, match="method"):
        ps.slam.default_options(without, method="particles")


def test_a_misshapen_odometry_noise_is_refused_by_name():
    scans = sim_laser.simulate("hall", "lds", "good", seed=0).scans()
    scans.odometry_noise = np.ones(6)  # one statement, not one per scan
    with pytest.raises(ValueError, match="odometry_noise"):
        ps.slam.default_options(scans)


@pytest.mark.parametrize("bad", [0.0, -0.5, 1.5, float("nan")])
def test_match_fraction_out_of_range_is_refused(bad):
    with pytest.raises(ValueError, match=r"^frontend\.match_fraction "):
        ps.SubmapSlam2D(frontend={"match_fraction": bad})


#: The issue's bar for the truth as odometry: GraphSLAM (closures on, every default) under
#: 0.02 m ATE. The Stage-like robot in the office measured 0.005 m with the odometry's stated
#: noise as the prior (1.02 m with the fixed model, 10 % of the distance and 1 cm a scan).
PERFECT_ODOMETRY_ATE = 0.02


def test_run_slam_keeps_perfect_odometry_with_its_stated_noise():
    sim = sim_laser.simulate("office", "stage", "perfect", seed=0)
    result = ps.slam.run_slam(sim.scans(), progress=False)
    assert ate(result.timestamps, result.poses, sim.timestamps, sim.truth).rmse < PERFECT_ODOMETRY_ATE


def test_run_slam_improves_on_good_odometry():
    # Good odometry (0.5 % scale, 0.2 deg/m) stated as such: 0.068 m ATE against 0.584 m alone.
    sim = sim_laser.simulate("office", "stage", "good", seed=0)
    result = ps.slam.run_slam(sim.scans(), progress=False)
    slam = ate(result.timestamps, result.poses, sim.timestamps, sim.truth).rmse
    assert slam < 0.5 * ate(sim.timestamps, sim.odometry, sim.timestamps, sim.truth).rmse


def test_stated_noise_bounds_the_simulated_steps():
    # The stated per-step sd against the simulated odometry's step errors (no slips: the
    # Gaussian part the statement is for): within it in more than 95 % of the steps, per axis.
    model = sim_laser.ODOMETRY["good"]
    trans_m, trans_rad, trans_floor, rot_rad, rot_m, rot_floor = model.stated_noise()
    sim = sim_laser.simulate("office", "stage", "good", seed=3)
    truth, odo = geometry.steps(sim.truth), geometry.steps(sim.odometry)
    d, a = np.hypot(truth[:, 0], truth[:, 1]), np.abs(truth[:, 2])
    sd_xy = trans_m * d + trans_rad * a + trans_floor
    sd_th = rot_rad * a + rot_m * d + rot_floor
    err_xy = np.hypot(*(odo[:, :2] - truth[:, :2]).T)
    err_th = np.abs(np.angle(np.exp(1j * (odo[:, 2] - truth[:, 2]))))
    assert np.mean(err_xy <= 2 * sd_xy) > 0.95 and np.mean(err_th <= 2 * sd_th) > 0.95
    assert sim_laser.ODOMETRY["perfect"].stated_noise() == (0.0, 0.0, sim_laser.STATED_NOISE_FLOOR, 0.0, 0.0,
                                                             sim_laser.STATED_NOISE_FLOOR)


#: The issue's bar for false closures: none that moves the result by more than 0.1 m from what
#: the frontend and the odometry's prior give without closures.
FALSE_CLOSURE_MOVE = 0.1


@pytest.mark.parametrize("world, odometry, seed", [
    ("repeated", "poor", 0), ("repeated", "poor", 1),
    pytest.param("corridor", "good", 0, marks=pytest.mark.slow)])
def test_look_alike_closures_are_refused(world, odometry, seed):
    # The 3 x 3 array of identical boxes with the Stage-like robot (5 m, 90 beams) on poor
    # odometry: closures to the neighbouring box passed the graph's gate one by one (the poor
    # odometry's stated spread allows metres) and pulled the map 2.16 m (seed 0) / 2.49 m (seed
    # 1) off; without closures 0.31 / 0.20 m. A closure must now agree with the consecutive
    # chain between its submaps and with every other closure: 0.26 / 0.17 m measured.
    # The corridor ring with good odometry: one lone closure 4.3 m along the corridor (no other
    # closure to contradict it) took the map to 1.76 m against 0.29 m without closures; a
    # closure's match must now explain its scan better than the runner-up place the graph
    # admits as well (Vuong's statistic, SubmapSlam2D::unique_match): 0.088 m measured.
    sim = sim_laser.simulate(world, "stage", odometry, seed=seed)
    scans = sim.scans()
    with_closures = ps.slam.run_slam(scans, progress=False)
    without = ps.slam.run_slam(scans, progress=False,
                               options=ps.slam.default_options(scans).replace(closures={"enabled": False}))
    ate_with = ate(with_closures.timestamps, with_closures.poses, sim.timestamps, sim.truth).rmse
    ate_without = ate(without.timestamps, without.poses, sim.timestamps, sim.truth).rmse
    assert ate_with <= ate_without + FALSE_CLOSURE_MOVE, (ate_with, ate_without)
