"""Monte Carlo localization (C++ localization/) and the odometry motion model (core/), each
against an independent reference: Table 5.6's analytic moments, a brute-force nearest-obstacle
search for the likelihood field, Fox 2003's bound by hand, a one-dimensional corridor whose
posterior is integrated numerically, and tracking on a simulated corridor drive."""

import math

import numpy as np
import pytest

import probslam as ps
from corridor_world import ANGLES, MAX_RANGE, corridor_drive, scans_of
from probslam.localization import default_options

NOISE = np.array([0.05, 0.02, 0.03, 0.04])


def _table_5_6(previous, current):
    """(rot1, trans, rot2) by Table 5.6 lines 2-4, written out here."""
    dx, dy = current[0] - previous[0], current[1] - previous[1]
    rot1 = math.atan2(dy, dx) - previous[2]
    trans = math.hypot(dx, dy)
    rot2 = current[2] - previous[2] - rot1
    wrap = lambda a: (a + math.pi) % (2 * math.pi) - math.pi  # noqa: E731
    return wrap(rot1), trans, wrap(rot2)


def _variances(rot1, trans, rot2, a):
    return (a[0] * rot1 ** 2 + a[1] * trans ** 2, a[2] * trans ** 2 + a[3] * (rot1 ** 2 + rot2 ** 2),
            a[0] * rot2 ** 2 + a[1] * trans ** 2)


# ---- the odometry motion model ----

def test_odometry_motion_decomposition():
    prev, cur = np.array([1.0, 2.0, 0.3]), np.array([2.5, 2.9, 1.1])
    assert np.allclose(ps.odometry_motion(prev, cur), _table_5_6(prev, cur), atol=1e-12)
    # A pure turn: rot1 is 0, rot2 the whole turn.
    assert np.allclose(ps.odometry_motion([0, 0, 0.2], [0, 0, 0.9]), (0.0, 0.0, 0.7), atol=1e-12)


def test_sampler_moments_match_table_5_6():
    pose = np.array([0.5, -1.0, 0.4])
    prev, cur = np.array([0.0, 0.0, 0.1]), np.array([1.2, 0.5, 0.6])
    rot1, trans, rot2 = _table_5_6(prev, cur)
    v1, vt, v2 = _variances(rot1, trans, rot2, NOISE)
    n = 200_000
    x = ps.sample_odometry_motion(pose, prev, cur, NOISE, num_samples=n, seed=3)
    # The hatted motions recovered from the samples are independent normals (Table 5.6 lines 2-4).
    dx, dy = x[:, 0] - pose[0], x[:, 1] - pose[1]
    r1 = np.arctan2(dy, dx) - pose[2]
    t = np.hypot(dx, dy)
    r2 = ps.wrap_angle(x[:, 2] - pose[2] - r1)
    for sample, mean, var in ((r1, rot1, v1), (t, trans, vt), (r2, rot2, v2)):
        # Five standard errors of the mean, and of the variance (4th moment of a normal: 2 var^2 / n).
        assert abs(sample.mean() - mean) < 5 * math.sqrt(var / n)
        assert abs(sample.var() - var) < 5 * var * math.sqrt(2.0 / n)
    # The pose's mean in closed form: E[cos(a + e)] = cos(a) exp(-var / 2) for e ~ N(0, var).
    ex = pose[0] + trans * math.cos(pose[2] + rot1) * math.exp(-v1 / 2)
    ey = pose[1] + trans * math.sin(pose[2] + rot1) * math.exp(-v1 / 2)
    sd = math.sqrt(vt + trans ** 2 * v1)  # bounds the std of x and y
    assert abs(x[:, 0].mean() - ex) < 5 * sd / math.sqrt(n)
    assert abs(x[:, 1].mean() - ey) < 5 * sd / math.sqrt(n)


def test_density_against_its_own_samples():
    """E[log p] over draws of the sampler is minus the entropy of the three normals,
    -sum(1 + log(2 pi var)) / 2; and the density is scipy's normal pdf product."""
    scipy_stats = pytest.importorskip("scipy.stats")
    pose = np.array([0.0, 0.0, 0.0])
    prev, cur = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.3, 0.4])
    v = _variances(*_table_5_6(prev, cur), NOISE)
    x = ps.sample_odometry_motion(pose, prev, cur, NOISE, num_samples=20_000, seed=1)
    lp = np.array([ps.odometry_motion_log_density(pose, xi, prev, cur, NOISE) for xi in x])
    expected = -0.5 * sum(1 + math.log(2 * math.pi * vi) for vi in v)
    assert abs(lp.mean() - expected) < 5 * lp.std() / math.sqrt(len(lp))
    u = _table_5_6(prev, cur)
    h = _table_5_6(pose, x[0])
    ref = sum(scipy_stats.norm.logpdf(u[i] - h[i], scale=math.sqrt(v[i])) for i in range(3))
    assert ps.odometry_motion_log_density(pose, x[0], prev, cur, NOISE) == pytest.approx(ref, rel=1e-9)


def test_density_refuses_a_dirac():
    with pytest.raises(ValueError, match="noise"):
        ps.odometry_motion_log_density([0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0], NOISE)


# ---- maps ----

def _box_map(res=0.1, w=60, h=40, walls=True):
    """A free room with walls on its border (and nothing else): occupancy set through log-odds."""
    g = ps.OccupancyGrid2D(res, w, h, origin=(0.0, 0.0))
    lo = np.full((h, w), -3.0)
    if walls:
        lo[0, :] = lo[-1, :] = lo[:, 0] = lo[:, -1] = 3.0
    g.log_odds[:] = lo
    return g


def _brute_log_likelihood(grid, pose, ranges, angles, sigma, p_rand, threshold=0.65, max_range=30.0):
    """Table 6.3 by brute force: each end point's cell, its centre's distance to every occupied
    cell's centre less half a cell (an obstacle lies somewhere in its cell), truncated at 6 sigma."""
    occ = np.argwhere(grid.probability() > threshold)  # (n, 2) rows, cols
    res, (x0, y0) = grid.resolution, grid.origin
    total = 0.0
    for r, a in zip(ranges, angles):
        if not 0 < r < max_range:
            continue
        x = pose[0] + r * math.cos(pose[2] + a)
        y = pose[1] + r * math.sin(pose[2] + a)
        col, row = math.floor((x - x0) / res), math.floor((y - y0) / res)
        if not (0 <= row < grid.height and 0 <= col < grid.width):
            total += math.log(p_rand)
            continue
        d_cells = np.min(np.hypot(occ[:, 0] - row, occ[:, 1] - col))
        d = min(6 * sigma, max(0.0, (d_cells - 0.5) * res))
        total += math.log((1 - p_rand) * math.exp(-d * d / (2 * sigma * sigma)) + p_rand)
    return total


def test_likelihood_field_weight_against_brute_force():
    g = _box_map()
    lo = g.log_odds.copy()
    lo[10:14, 20:23] = 3.0  # a pillar
    g.log_odds[:] = lo
    mcl = ps.MonteCarloLocalization(g, sigma=0.15, p_rand=0.05, max_beams=1000, max_particles=300,
                                    min_particles=10)
    rng = np.random.default_rng(0)
    angles = np.linspace(-math.pi, math.pi, 90, endpoint=False)
    for _ in range(5):
        pose = np.array([rng.uniform(0.5, 5.5), rng.uniform(0.5, 3.5), rng.uniform(-math.pi, math.pi)])
        ranges = rng.uniform(0.05, 8.0, len(angles))
        ref = _brute_log_likelihood(g, pose, ranges, angles, 0.15, 0.05)
        # The field stores float32 log p per cell: a relative 1e-6 per beam.
        assert mcl.measurement_log_likelihood(pose, ranges, angles) == pytest.approx(ref, rel=1e-5, abs=1e-4)


# ---- KLD sampling ----

def test_kld_bound_by_hand():
    # Fox 2003 eq. 12 for k = 10 bins, epsilon = 0.05, z_{0.99} = 2.326:
    # (9 / 0.1) * (1 - 2/81 + sqrt(2/81) * 2.326)^3 = 90 * 1.340805^3 = 90 * 2.410447 = 216.94
    a = 2 / 81
    by_hand = 90 * (1 - a + math.sqrt(a) * 2.326) ** 3
    assert by_hand == pytest.approx(216.94, abs=0.01)
    assert ps.MonteCarloLocalization.kld_bound(10, 0.05, 2.326) == pytest.approx(by_hand, rel=1e-12)
    assert ps.MonteCarloLocalization.kld_bound(1, 0.05, 2.326) == 0.0
    # k = 2: (1 / 0.1) * (1 - 2/9 + sqrt(2/9) * 2.326)^3
    assert ps.MonteCarloLocalization.kld_bound(2, 0.05, 2.326) == pytest.approx(
        10 * (7 / 9 + math.sqrt(2 / 9) * 2.326) ** 3, rel=1e-12)


def test_kld_particle_count_matches_the_bins_it_filled():
    """After a resampling the count n is the first with n >= bound(k), k the bins occupied by the
    n new particles (binned here as the filter documents: floor(x / bin_xy), floor((theta + pi) /
    bin_theta))."""
    g = _box_map()
    eps, z, bxy, bth = 0.05, 2.326, 0.5, math.radians(10)
    mcl = ps.MonteCarloLocalization(g, initial_pose=[3.0, 2.0, 0.0], initial_covariance=np.diag([0.3, 0.3, 0.3]),
                                    min_particles=10, max_particles=5000, kld_epsilon=eps, kld_z=z, bin_xy=bxy,
                                    bin_theta=bth, resample_threshold=1.0, alpha_slow=0.0, alpha_fast=0.0)
    ranges = np.full(36, 2.0)
    u = mcl.update(ranges, np.linspace(-math.pi, math.pi, 36, endpoint=False))
    assert u.resampled
    p = mcl.poses
    n = len(p)
    bins = {(math.floor(x / bxy), math.floor(y / bxy), math.floor((t + math.pi) / bth)) for x, y, t in p}
    k = len(bins)
    bound = ps.MonteCarloLocalization.kld_bound(k, eps, z)
    assert 10 < n < 5000
    assert bound <= n < bound + 1


# ---- the posterior of a one-dimensional corridor ----

def test_one_dimensional_corridor_posterior():
    """A corridor along x closed at x = 5.95..6.05 m; the start is known in y and theta and
    N(2.0, 0.3^2) in x; one beam straight ahead reads 3.8 m. The posterior over x is the prior
    times the beam's likelihood, integrated here on a fine grid with the brute-force field."""
    res = 0.05
    g = ps.OccupancyGrid2D(res, 122, 40, origin=(0.0, 0.0))
    lo = np.full((40, 122), -3.0)
    lo[:, 119:121] = 3.0  # the end wall, x in [5.95, 6.05)
    lo[:, 121] = 3.0
    g.log_odds[:] = lo
    sigma, p_rand = 0.2, 0.05
    mcl = ps.MonteCarloLocalization(g, initial_pose=[2.0, 1.0, 0.0], initial_covariance=np.diag([0.09, 0.0, 0.0]),
                                    sigma=sigma, p_rand=p_rand, max_particles=40000, min_particles=40000,
                                    resample_threshold=0.0, weight_scale=1.0, seed=7)
    ranges, angles = np.array([3.8]), np.array([0.0])
    mcl.update(ranges, angles)
    p, w = mcl.poses, mcl.weights
    assert np.allclose(p[:, 1], 1.0, atol=1e-12) and np.allclose(p[:, 2], 0.0, atol=1e-12)
    xs = np.linspace(0.0, 4.0, 4001)
    like = np.exp([_brute_log_likelihood(g, [x, 1.0, 0.0], ranges, angles, sigma, p_rand) for x in xs])
    post = like * np.exp(-0.5 * (xs - 2.0) ** 2 / 0.09)
    post /= np.trapezoid(post, xs)
    mean = np.trapezoid(xs * post, xs)
    var = np.trapezoid((xs - mean) ** 2 * post, xs)
    est = np.sum(w * p[:, 0])
    est_var = np.sum(w * (p[:, 0] - est) ** 2)
    n_eff = 1.0 / np.sum(w ** 2)
    assert abs(est - mean) < 5 * math.sqrt(var / n_eff)
    assert est_var == pytest.approx(var, rel=10 * math.sqrt(2 / n_eff))
    assert mean == pytest.approx(2.15, abs=0.1)  # the wall pulls the estimate towards 6.0 - 3.8


# ---- tracking and global localization on the simulated corridor ----

def _corridor_map(true, ranges):
    g = ps.OccupancyGrid2D.covering((-1.0, -1.0, 21.0, 13.0), 0.1)
    g.insert_scans(true, np.where(np.isfinite(ranges), ranges, MAX_RANGE), ANGLES, MAX_RANGE)
    return g


@pytest.fixture(scope="module")
def corridor():
    true, odo, ranges = corridor_drive(laps=1.25, step=0.25, seed=5)
    return true, odo, ranges, _corridor_map(true, ranges)


def _position_errors(poses, true):
    return np.hypot(poses[:, 0] - true[:, 0], poses[:, 1] - true[:, 1])


def test_tracking_converges_on_a_simulated_drive(corridor):
    true, odo, ranges, grid = corridor
    # The odometry starts at the true pose but drifts (a heading bias): MCL must hold the track.
    scans = scans_of(true, odo, ranges)
    r = ps.localize(scans, grid, initial_pose=true[0], progress=False,
                    options=default_options(scans).replace(seed=1, max_particles=3000))
    err = _position_errors(r.poses, true)
    drift = _position_errors(odo, true)
    assert drift.max() > 1.0  # the odometry alone is lost
    # The map's cells are 0.1 m: the estimate stays within a few cells.
    assert np.median(err[10:]) < 0.1
    assert err.max() < 0.35
    assert r.convergence_time is not None and r.convergence_time <= 5.0  # one scan a second
    assert r.num_particles[-1] < 3000  # KLD shrank the cloud


def test_global_localization_converges_on_a_simulated_drive(corridor):
    true, odo, ranges, grid = corridor
    scans = scans_of(true, odo, ranges)
    r = ps.localize(scans, grid, progress=False, options=default_options(scans).replace(seed=2))
    assert r.convergence_time is not None
    k = int(np.searchsorted(r.timestamps, r.convergence_time))
    err = _position_errors(r.poses[k:], true[k:])
    assert np.median(err) < 0.15
    assert r.num_particles[-1] < 2000


def test_thread_count_does_not_change_the_result(corridor):
    true, odo, ranges, grid = corridor
    out = []
    for threads in (1, 3):
        mcl = ps.MonteCarloLocalization(grid, seed=11, threads=threads, max_particles=4000)
        for k in range(40):
            if k:
                mcl.predict_odometry(previous=odo[k - 1], current=odo[k])
            mcl.update(ranges[k], ANGLES)
        out.append((mcl.poses, mcl.weights, mcl.pose, mcl.covariance))
    for a, b in zip(*out):
        assert np.array_equal(a, b)


def test_beam_model_tracks(corridor):
    true, odo, ranges, grid = corridor
    scans = scans_of(true[:80], odo[:80], ranges[:80])
    options = default_options(scans).replace(sensor_model="beam", max_particles=1000, max_beams=30,
                                             beam={"sigma_hit": 0.1})
    r = ps.localize(scans, grid, initial_pose=true[0], progress=False, options=options)
    assert np.median(_position_errors(r.poses, true[:80])) < 0.15


def test_predict_odometry_forms_agree_and_pose_follows(corridor):
    true, odo, ranges, grid = corridor
    a = ps.MonteCarloLocalization(grid, initial_pose=true[0], max_particles=500)
    b = a.copy()
    a.predict_odometry(previous=odo[0], current=odo[1])
    d = ps.Pose2(*odo[0]).between(ps.Pose2(*odo[1]))
    b.predict_odometry([d.x, d.y, d.theta])
    assert np.allclose(a.pose, b.pose, atol=1e-12)
    # No update yet (0.25 m < update.distance... or not): the pose moved by the pending odometry.
    before = ps.MonteCarloLocalization(grid, initial_pose=true[0], max_particles=500).pose
    expect = ps.Pose2(*before).compose(ps.Pose2(d.x, d.y, d.theta)).as_array()
    assert np.allclose(a.pose, expect, atol=1e-9)


def test_copy_is_independent(corridor):
    true, odo, ranges, grid = corridor
    a = ps.MonteCarloLocalization(grid, initial_pose=true[0], max_particles=500, seed=4)
    a.update(ranges[0], ANGLES)
    b = a.copy()
    for m in (a, b):
        m.predict_odometry(previous=odo[0], current=odo[3])
        m.update(ranges[3], ANGLES)
    assert np.array_equal(a.poses, b.poses)
    a.predict_odometry(previous=odo[3], current=odo[6])
    a.update(ranges[6], ANGLES)
    assert not np.array_equal(a.poses, b.poses)


# ---- bad input ----

def test_bad_input_names_the_argument_and_changes_nothing():
    g = _box_map()
    with pytest.raises(ValueError, match="map"):
        ps.MonteCarloLocalization(ps.OccupancyGrid2D(0.1, 10, 10))  # all unknown: no free cell
    with pytest.raises(TypeError, match="map"):
        ps.MonteCarloLocalization(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="initial_pose"):
        ps.MonteCarloLocalization(g, initial_pose=[100.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="initial_pose"):
        ps.MonteCarloLocalization(g, initial_pose=[0.05, 0.05, 0.0])  # the wall
    with pytest.raises(ValueError, match="initial_pose"):
        ps.MonteCarloLocalization(g, initial_pose=[math.nan, 1.0, 0.0])
    with pytest.raises(ValueError, match="initial_covariance"):
        ps.MonteCarloLocalization(g, initial_pose=[3, 2, 0], initial_covariance=-np.eye(3))
    with pytest.raises(ValueError, match="max_particles"):
        ps.MonteCarloLocalization(g, min_particles=100, max_particles=50)
    with pytest.raises(ValueError, match="min_range"):
        ps.MonteCarloLocalization(g, min_range=40.0, max_range=30.0)
    with pytest.raises(ValueError, match="sensor_model"):
        ps.MonteCarloLocalization(g, sensor_model="sonar")
    with pytest.raises(ValueError, match="alpha_fast"):
        ps.MonteCarloLocalization(g, alpha_slow=0.5, alpha_fast=0.1)
    with pytest.raises(ValueError, match="free_threshold"):
        ps.MonteCarloLocalization(g, free_threshold=0.9)
    with pytest.raises(TypeError, match="max_beams"):
        ps.MonteCarloLocalization(g, max_beams=2.5)
    mcl = ps.MonteCarloLocalization(g, initial_pose=[3, 2, 0], min_particles=100, max_particles=300, seed=1)
    angles = np.linspace(-1, 1, 5)
    before = (mcl.poses, mcl.weights, mcl.num_updates)
    for bad in ([1, 2, math.nan, 1, 1], [1, 2, math.inf, 1, 1], [1, 2, -1, 1, 1]):
        with pytest.raises(ValueError, match="ranges"):
            mcl.update(np.array(bad, float), angles)
    with pytest.raises(ValueError, match="ranges"):
        mcl.update(np.array([]), np.array([]))
    with pytest.raises(ValueError, match="angles"):
        mcl.update(np.ones(5), np.ones(4))
    with pytest.raises(ValueError, match="delta"):
        mcl.predict_odometry([0.0, math.nan, 0.0])
    with pytest.raises(ValueError, match="delta"):
        mcl.predict_odometry()
    with pytest.raises(ValueError, match="pose"):
        mcl.initialize_pose([100.0, 0, 0], np.eye(3))
    after = (mcl.poses, mcl.weights, mcl.num_updates)
    for x, y in zip(before, after):
        assert np.array_equal(x, y)


def test_localize_driver_checks_its_arguments(corridor):
    true, odo, ranges, grid = corridor
    scans = scans_of(true, odo, ranges)
    with pytest.raises(TypeError, match="map"):
        ps.localize(scans, "map.yaml")
    with pytest.raises(ValueError, match="stop"):
        ps.localize(scans, grid, stop=10 ** 6, progress=False)
    with pytest.raises(ValueError, match="start"):
        ps.localize(scans, grid, start=5, stop=5, progress=False)
    with pytest.raises(TypeError, match="^options: expected a MonteCarloLocalizationOptions, got dict"):
        ps.localize(scans, grid, options={"seed": 1}, progress=False)


def test_kidnapped_robot_recovers(corridor):
    """The drive cut after 100 scans and resumed at scan 150: the odometry continues smoothly
    (the second piece re-expressed from the first's end) while the robot jumps; augmented MCL
    injects particles in free space and finds it again."""
    true, odo, ranges, grid = corridor
    a, b = np.arange(0, 100), np.arange(150, len(true))
    start = ps.Pose2(*odo[b[0]])
    joined = [ps.Pose2(*odo[a[-1]]).compose(start.between(ps.Pose2(*p))).as_array() for p in odo[b]]
    odo2 = np.vstack([odo[a], np.array(joined)])
    truth = np.vstack([true[a], true[b]])
    scans = scans_of(truth, odo2, np.vstack([ranges[a], ranges[b]]))
    r = ps.localize(scans, grid, initial_pose=truth[0], progress=False, options=default_options(scans).replace(seed=5))
    err = _position_errors(r.poses, truth)
    assert np.median(err[:100]) < 0.1
    assert err[100] > 2.0  # the jump (about 12 m of corridor)
    assert np.max(err[-30:]) < 0.3, err[100::10]


def test_resample_interval_resamples_at_every_kth_update_only(corridor):
    """AMCL's resample_interval: with N_eff always below the threshold (resample_threshold 1), the
    filter resamples at updates 3, 6, ... only."""
    true, odo, ranges, grid = corridor
    mcl = ps.MonteCarloLocalization(grid, initial_pose=true[0], min_particles=200, max_particles=200, seed=2,
                                    resample_threshold=1.0, resample_interval=3)
    resampled = [mcl.update(ranges[0], ANGLES, force=True).resampled for _ in range(7)]
    assert resampled == [False, False, True, False, False, True, False]
    every = ps.MonteCarloLocalization(grid, initial_pose=true[0], min_particles=200, max_particles=200, seed=2,
                                      resample_threshold=1.0)
    assert all(every.update(ranges[0], ANGLES, force=True).resampled for _ in range(3))
    with pytest.raises(ValueError, match="^resample_interval must lie in"):
        ps.MonteCarloLocalizationOptions(resample_interval=0)
