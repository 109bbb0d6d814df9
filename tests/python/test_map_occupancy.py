"""The forward beam model (ch. 6.3) and MAP occupancy grid mapping (ch. 9.4, Table 9.3)."""

import math

import numpy as np
import pytest
from scipy import stats
from scipy.special import erf

import probslam
from probslam.sim import open_door_scenario

#: Relative agreement of two double evaluations of the same log-likelihood (erf/exp/log in
#: numpy vs. libm): rounding only.
LOG_LIKELIHOOD_RTOL = 1e-9
#: Incremental vs. from-scratch eq. 9.24: sums of hundreds of terms ~10 nats, rounding ~1e-13 each.
OBJECTIVE_RTOL = 1e-9


def numpy_mixture(z, zs, m):
    """Eq. 6.4-6.12 evaluated independently: z readings, zs expected ranges, m the model."""
    z = np.minimum(np.asarray(z, dtype=float), m.max_range)
    zs = np.asarray(zs, dtype=float)
    s, zmax = m.sigma_hit, m.max_range
    cdf = lambda x: 0.5 * (1 + erf(x / math.sqrt(2)))  # noqa: E731
    eta_hit = 1.0 / (cdf((zmax - zs) / s) - cdf(-zs / s))
    p_hit = eta_hit * np.exp(-0.5 * ((z - zs) / s) ** 2) / (s * math.sqrt(2 * math.pi))
    with np.errstate(divide="ignore", invalid="ignore"):
        eta_short = 1.0 / (1.0 - np.exp(-m.lambda_short * zs))
        p_short = np.where((z <= zs) & (zs > 0), eta_short * m.lambda_short * np.exp(-m.lambda_short * z), 0.0)
    p_short = np.where((zs == 0) & (z == 0), 1.0, p_short)
    p_max = (z >= zmax).astype(float)
    p_rand = np.where(z < zmax, 1.0 / zmax, 0.0)
    return m.z_hit * p_hit + m.z_short * p_short + m.z_max * p_max + m.z_rand * p_rand


def random_map(rng, shape=(30, 40), fill=0.08):
    grid = probslam.OccupancyGrid2D(0.1, shape[1], shape[0], origin=(-1.0, -0.5))
    occupied = rng.random(shape) < fill
    return grid, occupied


def laser_range_brute_force(grid, occupied, pose, angle, max_range):
    """Slab intersection of the ray with every occupied cell's square: the nearest entry."""
    x0, y0 = grid.origin
    res = grid.resolution
    d = np.array([math.cos(pose[2] + angle), math.sin(pose[2] + angle)])
    rows, cols = np.nonzero(occupied)
    lo = np.stack([x0 + cols * res, y0 + rows * res], axis=1)
    hi = lo + res
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - pose[:2]) / d
        t2 = (hi - pose[:2]) / d
    t_near = np.where(d != 0, np.minimum(t1, t2), -np.inf).max(axis=1)
    t_far = np.where(d != 0, np.maximum(t1, t2), np.inf).min(axis=1)
    inside = (d != 0) | ((pose[:2] >= lo) & (pose[:2] < hi))
    hit = inside.all(axis=1) & (t_far >= np.maximum(t_near, 0.0))
    entry = np.maximum(t_near[hit], 0.0)
    entry = entry[entry < max_range]
    return entry.min() if entry.size else max_range


def sonar_range_brute_force(grid, occupied, pose, angle, beta, max_range):
    x0, y0 = grid.origin
    res = grid.resolution
    rows, cols = np.nonzero(occupied)
    dx = x0 + (cols + 0.5) * res - pose[0]
    dy = y0 + (rows + 0.5) * res - pose[1]
    r = np.hypot(dx, dy)
    off = np.abs(np.angle(np.exp(1j * (np.arctan2(dy, dx) - pose[2] - angle))))
    ok = (r < max_range) & (off <= beta / 2)
    return r[ok].min() if ok.any() else max_range


def test_laser_log_likelihood_matches_numpy_mixture_and_ray_geometry():
    rng = np.random.default_rng(3)
    grid, occupied = random_map(rng)
    bmap = probslam.BinaryMap2D(grid, occupied)
    model = probslam.BeamSensorModel("laser", 2.5, z_hit=0.6, z_short=0.2, z_max=0.1, z_rand=0.1, sigma_hit=0.08,
                                     lambda_short=1.5)
    for _ in range(20):
        pose = np.array([rng.uniform(-1, 3), rng.uniform(-0.5, 2.5), rng.uniform(-np.pi, np.pi)])
        angles = rng.uniform(-np.pi, np.pi, 12)
        expected = np.array([laser_range_brute_force(grid, occupied, pose, a, 2.5) for a in angles])
        np.testing.assert_allclose(model.expected_ranges(pose, angles, bmap), expected, rtol=1e-12, atol=1e-12)
        z = rng.uniform(0, 3.0, 12)  # some beyond max_range: max readings
        z[0] = np.inf
        np.testing.assert_allclose(model.log_likelihood(z, pose, angles, bmap),
                                   np.log(numpy_mixture(z, expected, model)), rtol=LOG_LIKELIHOOD_RTOL)


def test_sonar_log_likelihood_matches_numpy_mixture_and_cone_geometry():
    rng = np.random.default_rng(4)
    grid, occupied = random_map(rng, fill=0.04)
    model = probslam.BeamSensorModel("sonar", 3.0, beta=0.4, z_hit=0.7, z_short=0.1, z_max=0.1, z_rand=0.1,
                                     sigma_hit=0.1, lambda_short=0.5)
    for _ in range(20):
        pose = np.array([rng.uniform(-1, 3), rng.uniform(-0.5, 2.5), rng.uniform(-np.pi, np.pi)])
        angles = rng.uniform(-np.pi, np.pi, 12)
        expected = np.array([sonar_range_brute_force(grid, occupied, pose, a, 0.4, 3.0) for a in angles])
        # The map as an OccupancyGrid2D thresholded at p > 0.5.
        g = probslam.OccupancyGrid2D(0.1, 40, 30, origin=(-1.0, -0.5))
        g.log_odds[:] = np.where(occupied, 1.0, -1.0)
        np.testing.assert_allclose(model.expected_ranges(pose, angles, g), expected, rtol=1e-12)
        z = rng.uniform(0, 3.5, 12)
        np.testing.assert_allclose(model.log_likelihood(z, pose, angles, g),
                                   np.log(numpy_mixture(z, expected, model)), rtol=LOG_LIKELIHOOD_RTOL)


def mixture_cdf(x, zs, m):
    """CDF of the mixture's continuous part at x < max_range (the max mass sits at max_range)."""
    s, zmax = m.sigma_hit, m.max_range
    cdf = lambda v: 0.5 * (1 + erf(v / math.sqrt(2)))  # noqa: E731
    hit = (cdf((x - zs) / s) - cdf(-zs / s)) / (cdf((zmax - zs) / s) - cdf(-zs / s))
    short = np.where(x >= zs, 1.0, (1 - np.exp(-m.lambda_short * x)) / (1 - np.exp(-m.lambda_short * zs)))
    return m.z_hit * hit + m.z_short * short + m.z_rand * x / zmax


@pytest.mark.parametrize("shape", ["laser", "sonar"])
def test_samples_follow_the_mixture_chi_square(shape):
    # A wall 1.5 m ahead: z* is fixed for every beam pointing at it.
    grid = probslam.OccupancyGrid2D(0.1, 40, 20)
    occupied = np.zeros((20, 40), dtype=bool)
    occupied[:, 25] = True
    model = probslam.BeamSensorModel(shape, 3.0, beta=0.1, z_hit=0.6, z_short=0.2, z_max=0.1, z_rand=0.1,
                                     sigma_hit=0.15, lambda_short=1.0)
    pose = np.array([1.0, 1.05, 0.0])
    n = 40000
    angles = np.zeros(n)
    bmap = probslam.BinaryMap2D(grid, occupied)
    zs = model.expected_ranges(pose, angles[:1], bmap)[0]
    assert zs == pytest.approx(1.5 if shape == "laser" else 1.55)
    z = model.sample(pose, angles, bmap, np.random.default_rng(11))
    assert np.all((z >= 0) & (z <= 3.0))
    edges = np.linspace(0.0, 3.0, 31)
    counts = np.histogram(z[z < 3.0], bins=edges)[0]
    counts = np.append(counts, np.sum(z >= 3.0))
    cdf = mixture_cdf(edges, zs, model)
    probs = np.append(np.diff(cdf), model.z_max)
    assert probs.sum() == pytest.approx(1.0, abs=1e-12)
    chi2 = np.sum((counts - n * probs) ** 2 / (n * probs))
    assert chi2 < stats.chi2.ppf(0.999, df=len(probs) - 1), chi2


def small_scenario(seed=5, shape="sonar"):
    rng = np.random.default_rng(seed)
    grid = probslam.OccupancyGrid2D(0.25, 14, 10, p_prior=0.3)
    truth = np.zeros((10, 14), dtype=bool)
    truth[[0, -1], :] = True
    truth[:, [0, -1]] = True
    truth[5, 6:8] = True
    model = probslam.BeamSensorModel(shape, 3.0, beta=0.4, z_hit=0.7, z_short=0.1, z_max=0.1, z_rand=0.1,
                                     sigma_hit=0.1, lambda_short=0.5)
    bmap = probslam.BinaryMap2D(grid, truth)
    poses = np.array([[0.8 + 0.3 * t, 0.9 + 0.08 * t, 0.3 * t] for t in range(6)])
    angles = np.arange(8) * 2 * np.pi / 8
    angles = np.where(angles > np.pi, angles - 2 * np.pi, angles)
    scans = np.stack([model.sample(p, angles, bmap, rng) for p in poses])
    return grid, poses, scans, angles, model


@pytest.mark.parametrize("shape", ["sonar", "laser"])
def test_table_9_3_reaches_a_local_maximum_brute_force(shape):
    grid, poses, scans, angles, model = small_scenario(shape=shape)
    r = probslam.map_occupancy_grid_mapping(poses, scans, angles, model, grid)
    assert r.converged and r.flips > 0
    best = probslam.map_log_posterior(probslam.BinaryMap2D(grid, r.occupied), poses, scans, angles, model, 0.3)
    assert r.objective == pytest.approx(best, rel=OBJECTIVE_RTOL)
    gains = np.empty(r.occupied.shape)
    for i, j in np.ndindex(*r.occupied.shape):
        m = r.occupied.copy()
        m[i, j] = not m[i, j]
        gains[i, j] = probslam.map_log_posterior(probslam.BinaryMap2D(grid, m), poses, scans, angles, model, 0.3) - best
    assert gains.max() <= 1e-9  # no single flip raises eq. 9.24
    np.testing.assert_allclose(r.sensitivity, gains, atol=OBJECTIVE_RTOL * abs(best))


@pytest.mark.parametrize("shape", ["sonar", "laser"])
def test_incremental_objective_equals_full_evaluation_after_every_flip(shape):
    grid, poses, scans, angles, model = small_scenario(6, shape=shape)
    r = probslam.map_occupancy_grid_mapping(poses, scans, angles, model, grid, record_trace=True)
    assert len(r.trace_cells) == r.flips > 0
    m = np.zeros(r.occupied.shape, dtype=bool)
    for cell, objective in zip(r.trace_cells, r.trace_objective):
        m.flat[cell] = not m.flat[cell]
        full = probslam.map_log_posterior(probslam.BinaryMap2D(grid, m), poses, scans, angles, model, 0.3)
        assert objective == pytest.approx(full, rel=OBJECTIVE_RTOL)
    np.testing.assert_array_equal(m, r.occupied)
    full_run = probslam.map_occupancy_grid_mapping(poses, scans, angles, model, grid, scoring="full",
                                                   record_trace=True)
    np.testing.assert_array_equal(full_run.trace_cells, r.trace_cells)
    np.testing.assert_array_equal(full_run.occupied, r.occupied)


def test_max_evaluations_stops_early_unconverged():
    grid, poses, scans, angles, model = small_scenario()
    r = probslam.map_occupancy_grid_mapping(poses, scans, angles, model, grid, max_evaluations=7)
    assert r.evaluations == 7 and not r.converged
    best = probslam.map_log_posterior(probslam.BinaryMap2D(grid, r.occupied), poses, scans, angles, model, 0.3)
    assert r.objective == pytest.approx(best, rel=OBJECTIVE_RTOL)


def classify_standard(grid):
    """+1 occupied (p > 0.5), 0 unknown (at the prior), -1 free."""
    return np.sign(grid.log_odds - grid.l0)


def test_open_door_map_keeps_the_opening_the_standard_algorithm_loses():
    sc = open_door_scenario()
    standard = classify_standard(sc.standard_map())
    r = probslam.map_occupancy_grid_mapping(sc.poses, sc.scans, sc.beam_angles, sc.model, sc.grid)
    assert r.converged
    # The door: free in the MAP map, occupied or unknown (never free) in the standard one.
    assert not r.occupied[sc.door].any()
    assert np.all(standard[sc.door] >= 0)
    # Cells that differ from the truth, over the cells some sonar covers.
    field = r.field
    map_wrong = np.sum((r.occupied != sc.truth) & field)
    standard_wrong = np.sum(((standard > 0) != sc.truth) & (standard != 0) & field)
    standard_unknown = np.sum((standard == 0) & field)
    print(f"open door: MAP differs in {map_wrong} cells, standard in {standard_wrong} "
          f"(+{standard_unknown} unknown) of {field.sum()} observed cells")
    assert map_wrong < standard_wrong + standard_unknown


# ---- bad input ----

def test_bad_mixture_parameters_raise_value_error_naming_them():
    with pytest.raises(ValueError, match="^z_short"):
        probslam.BeamSensorModel("laser", 5.0, z_hit=0.9, z_short=-0.05, z_max=0.1, z_rand=0.05)
    with pytest.raises(ValueError, match="sum to 1"):
        probslam.BeamSensorModel("laser", 5.0, z_hit=0.9, z_short=0.05, z_max=0.1, z_rand=0.05)
    with pytest.raises(ValueError, match="^sigma_hit"):
        probslam.BeamSensorModel("laser", 5.0, sigma_hit=0.0)
    with pytest.raises(ValueError, match="^lambda_short"):
        probslam.BeamSensorModel("laser", 5.0, lambda_short=-1.0)
    with pytest.raises(ValueError, match="^max_range"):
        probslam.BeamSensorModel("laser", float("nan"))
    with pytest.raises(ValueError, match="^beta"):
        probslam.BeamSensorModel("sonar", 5.0, beta=0.0)
    with pytest.raises(ValueError, match="^beta"):
        probslam.BeamSensorModel("sonar", 5.0, beta=-0.3)
    with pytest.raises(ValueError, match="^shape"):
        probslam.BeamSensorModel("radar", 5.0)


def test_bad_readings_and_maps():
    grid = probslam.OccupancyGrid2D(0.1, 10, 10)
    model = probslam.BeamSensorModel("sonar", 2.0, beta=0.3)
    pose, angles = np.array([0.5, 0.5, 0.0]), np.array([0.0, 1.0])
    with pytest.raises(ValueError, match="^ranges"):
        model.log_likelihood([1.0, float("nan")], pose, angles, grid)
    with pytest.raises(ValueError, match="^ranges"):
        model.log_likelihood([1.0, -0.1], pose, angles, grid)
    with pytest.raises(ValueError, match="^beam_angles"):
        model.log_likelihood([1.0, 1.0, 1.0], pose, angles, grid)
    with pytest.raises(ValueError, match="^pose"):
        model.log_likelihood([1.0, 1.0], [0.5, 0.5], angles, grid)
    with pytest.raises(TypeError, match="^map"):
        model.log_likelihood([1.0, 1.0], pose, angles, np.zeros((10, 10), dtype=bool))
    with pytest.raises(TypeError, match="^occupied"):
        probslam.BinaryMap2D(grid, np.zeros((10, 10)))
    with pytest.raises(ValueError, match="^occupied"):
        probslam.BinaryMap2D(grid, np.zeros((10, 9), dtype=bool))
    with pytest.raises(TypeError, match="^rng"):
        model.sample(pose, angles, grid, "seed")


def test_bad_mapping_input():
    grid, poses, scans, angles, model = small_scenario()
    run = probslam.map_occupancy_grid_mapping
    with pytest.raises(ValueError, match="^scans must have one row per pose"):
        run(poses[:-1], scans, angles, model, grid)
    bad = scans.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="^scans"):
        run(poses, bad, angles, model, grid)
    with pytest.raises(ValueError, match="^poses"):
        run(poses[:, :2], scans, angles, model, grid)
    with pytest.raises(ValueError, match="^scans"):
        run(poses, scans[:, 0], angles, model, grid)
    with pytest.raises(ValueError, match="^beam_angles"):
        run(poses, scans, angles[:-1], model, grid)
    with pytest.raises(ValueError, match="^prior"):
        run(poses, scans, angles, model, grid, prior=1.0)
    with pytest.raises(ValueError, match="^prior"):
        run(poses, scans, angles, model, grid, prior=np.full((3, 3), 0.3))
    with pytest.raises(ValueError, match="^scoring"):
        run(poses, scans, angles, model, grid, scoring="fast")
    with pytest.raises(ValueError, match="^max_sweeps"):
        run(poses, scans, angles, model, grid, max_sweeps=0)
    no_rand = probslam.BeamSensorModel("sonar", 3.0, beta=0.4, z_hit=0.9, z_short=0.0, z_max=0.1, z_rand=0.0)
    with pytest.raises(ValueError, match="^z_rand"):
        run(poses, scans, angles, no_rand, grid)
    with pytest.raises(TypeError):
        run(poses, scans, angles, "sonar", grid)


def test_mixture_probability_rejects_nan():
    model = probslam.BeamSensorModel("laser", 2.0)
    with pytest.raises(ValueError, match="^z_expected"):
        model.probability([1.0], [float("nan")])
    with pytest.raises(ValueError, match="^z"):
        model.probability([float("nan")], [1.0])
    np.testing.assert_allclose(model.probability([0.5, 2.0], [1.0, 1.0]), numpy_mixture([0.5, 2.0], [1.0, 1.0], model))
