"""Learning inverse measurement models from a forward model (ch. 9.3)."""

import numpy as np
import pytest

import probslam
from probslam import inverse_learning as il

#: Central differences with step 1e-6 on J(W) ~ 0.7: truncation ~1e-12, rounding ~1e-10.
FD_STEP = 1e-6
FD_ATOL = 1e-7


def sonar():
    angles = np.array([probslam.wrap_angle(a) for a in np.arange(16) * 2 * np.pi / 16])
    model = probslam.BeamSensorModel("sonar", 4.0, beta=np.radians(22.5), z_hit=0.8, z_short=0.1, z_max=0.05,
                                     z_rand=0.05, sigma_hit=0.05, lambda_short=0.5)
    return model, angles


def test_gradient_of_j_matches_finite_differences():
    rng = np.random.default_rng(1)
    m = il.LearnedInverseModel(hidden=5)
    s = rng.normal(size=(50, 7))
    y = (rng.random(50) < 0.3).astype(float)
    w = rng.normal(0, 0.5, m.n_weights(7))
    j, g = m.objective(w, s, y)
    numeric = np.empty_like(w)
    for k in range(w.size):
        e = np.zeros_like(w)
        e[k] = FD_STEP
        numeric[k] = (m.objective(w + e, s, y)[0] - m.objective(w - e, s, y)[0]) / (2 * FD_STEP)
    np.testing.assert_allclose(g, numeric, atol=FD_ATOL)
    # J is eq. 9.20 (per sample): -mean(y log f + (1 - y) log(1 - f)).
    _, u = m._forward(w, s)
    f = 1 / (1 + np.exp(-u))
    assert j == pytest.approx(-np.mean(y * np.log(f) + (1 - y) * np.log(1 - f)), rel=1e-12)


def test_random_map_prior_has_walls_rooms_and_free_space():
    grid = probslam.OccupancyGrid2D(0.1, 80, 60)
    occ = il.random_map(grid, np.random.default_rng(2))
    assert occ.shape == (60, 80)
    assert occ[0].all() and occ[-1].all() and occ[:, 0].all() and occ[:, -1].all()
    assert 0.03 < occ.mean() < 0.3  # walls and clutter, mostly free
    poses = il.free_poses(grid, occ, 200, np.random.default_rng(3))
    cells = probslam.BinaryMap2D(grid, occ)
    rows, cols = (poses[:, 1] / 0.1).astype(int), (poses[:, 0] / 0.1).astype(int)
    assert not occ[rows, cols].any()
    assert np.all((poses[:, 2] > -np.pi) & (poses[:, 2] <= np.pi))
    assert cells.shape == occ.shape


def test_field_features_encode_relative_polar_coordinates_and_neighbours():
    grid = probslam.OccupancyGrid2D(0.1, 60, 60)
    model, angles = sonar()
    pose = np.array([3.0, 3.0, 0.4])
    ranges = np.arange(16) * 0.1 + 1.0
    cells, x = il.field_features(grid, pose, ranges, angles, 4.0, model.beta / 2)
    assert x.shape == (cells.size, 7) and cells.size > 0
    rows, cols = np.divmod(cells, 60)
    dx, dy = (cols + 0.5) * 0.1 - 3.0, (rows + 0.5) * 0.1 - 3.0
    np.testing.assert_allclose(x[:, 0], np.hypot(dx, dy))
    assert np.all(np.abs(x[:, 1]) <= model.beta / 2) and np.all(x[:, 0] < 4.0)
    # The nearest beam's reading sits in the middle of the five; its neighbours by ring order.
    bearing = np.arctan2(dy, dx) - pose[2]
    k = np.argmin(np.abs(np.angle(np.exp(1j * (bearing[:, None] - angles[None, :])))), axis=1)
    np.testing.assert_allclose(x[:, 4], ranges[k])
    np.testing.assert_allclose(x[:, 2], ranges[(k - 2) % 16])


@pytest.fixture(scope="module")
def trained():
    rng = np.random.default_rng(4)
    grid = probslam.OccupancyGrid2D(0.1, 80, 80)
    model, angles = sonar()
    data = il.sample_training_set(grid, model, angles, maps=4, poses_per_map=25, rng=rng, cells_per_scan=250)
    return il.LearnedInverseModel(hidden=8).train(data, rng, max_iterations=200), data


@pytest.mark.slow
def test_learned_model_has_table_9_2_shape(trained):
    m, data = trained
    assert 0.02 < m.prior < 0.3
    z = 2.0
    def p(r):
        return m.probability(np.array([[r, 0.0, z, z, z, z, z]]))[0]
    before = [p(r) for r in (0.5, 1.0, 1.5)]
    at = p(z)
    beyond = p(3.5)
    assert max(before) < m.prior / 3  # free before the range
    assert at > 2 * m.prior  # occupied at it
    assert m.prior / 3 < beyond < 2 * m.prior  # about the prior beyond


@pytest.mark.slow
def test_learned_model_inserts_into_table_9_1_and_round_trips(trained, tmp_path):
    m, _ = trained
    model, angles = sonar()
    grid = probslam.OccupancyGrid2D(0.1, 80, 80, p_prior=m.prior, clamp=None)
    occ = np.zeros((80, 80), dtype=bool)
    occ[:, 60] = True  # a wall at x = 6 m
    pose = np.array([4.0, 4.0, 0.0])
    z = model.expected_ranges(pose, angles, probslam.BinaryMap2D(grid, occ))
    changed = m.insert_scan(grid, pose, z, angles, model.max_range, model.beta / 2)
    assert changed > 0
    p = grid.probability()
    assert p[40, 50] < m.prior  # between robot and wall: freer
    assert p[40, 60] > m.prior  # the wall: more occupied
    assert p[10, 10] == pytest.approx(m.prior)  # outside the field: untouched
    m.save(tmp_path / "model.npz")
    back = il.LearnedInverseModel.load(tmp_path / "model.npz")
    x = np.random.default_rng(5).normal(2.0, 1.0, (20, 7))
    np.testing.assert_array_equal(back.probability(x), m.probability(x))
    assert back.prior == m.prior


def test_untrained_and_bad_input():
    m = il.LearnedInverseModel()
    with pytest.raises(RuntimeError, match="untrained"):
        m.probability(np.zeros((1, 7)))
    with pytest.raises(RuntimeError, match="untrained"):
        m.save("never.npz")
    with pytest.raises(ValueError, match="hidden"):
        il.LearnedInverseModel(hidden=0)
    with pytest.raises(ValueError, match="both classes"):
        m.train(il.TrainingSet(np.ones((5, 7)), np.zeros(5, dtype=bool)), np.random.default_rng(0))
    with pytest.raises(ValueError, match="inputs"):
        m.train(il.TrainingSet(np.ones((5, 7)), np.zeros(4, dtype=bool)), np.random.default_rng(0))


@pytest.mark.slow
def test_insert_scan_rejects_bad_readings(trained):
    m, _ = trained
    model, angles = sonar()
    grid = probslam.OccupancyGrid2D(0.1, 40, 40)
    z = np.full(16, 1.0)
    z[3] = np.nan
    with pytest.raises(ValueError, match="ranges"):
        m.insert_scan(grid, (2.0, 2.0, 0.0), z, angles, 4.0, 0.2)
    with pytest.raises(ValueError, match="ranges"):
        m.insert_scan(grid, (2.0, 2.0, 0.0), np.ones(15), angles, 4.0, 0.2)
    with pytest.raises(ValueError, match="pose"):
        m.insert_scan(grid, (2.0, 2.0), np.ones(16), angles, 4.0, 0.2)
    with pytest.raises(ValueError, match="inputs"):
        m.probability(np.zeros((3, 5)))
