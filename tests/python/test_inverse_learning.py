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


# --- issue 33: bounded memory, arguments refused by name, load checks what save writes ------

def cross_product_field_features(grid, pose, ranges, beam_angles, max_range, half_angle):
    """field_features as it was before issue 33: every cell in range against every beam at once
    (the reference the chunked version must equal bit for bit)."""
    h, w = grid.shape
    res = grid.resolution
    x0, y0 = grid.origin
    key = lambda v, v0: int(np.floor((v - v0) / res))  # noqa: E731
    c_lo, c_hi = max(0, key(pose[0] - max_range, x0)), min(w - 1, key(pose[0] + max_range, x0))
    r_lo, r_hi = max(0, key(pose[1] - max_range, y0)), min(h - 1, key(pose[1] + max_range, y0))
    rows, cols = np.mgrid[r_lo:r_hi + 1, c_lo:c_hi + 1]
    dx = x0 + (cols.ravel() + 0.5) * res - pose[0]
    dy = y0 + (rows.ravel() + 0.5) * res - pose[1]
    r = np.hypot(dx, dy)
    bearing = np.arctan2(dy, dx) - pose[2]
    off = np.angle(np.exp(1j * (bearing[:, None] - beam_angles[None, :])))
    k = np.argmin(np.abs(off), axis=1)
    phi = off[np.arange(k.size), k]
    keep = (r < max_range) & (np.abs(phi) <= half_angle)
    k, phi, r = k[keep], phi[keep], r[keep]
    cells = (rows.ravel() * w + cols.ravel())[keep]
    z = np.minimum(np.nan_to_num(ranges, posinf=max_range), max_range)
    near = z[(k[:, None] + np.arange(-(il.NEIGHBOURS // 2), il.NEIGHBOURS // 2 + 1)[None, :]) % len(beam_angles)]
    return cells, np.column_stack([r, phi, near])


def laser(beams=181):
    return np.linspace(-np.pi / 2, np.pi / 2, beams)


@pytest.mark.parametrize("chunk", [1, 7, 100, 1 << 20])
def test_field_features_in_chunks_equal_the_cross_product(monkeypatch, chunk):
    grid = probslam.OccupancyGrid2D(0.1, 60, 50, origin=(-1.0, 0.5))
    model, angles = sonar()
    rng = np.random.default_rng(6)
    for pose, z, beams, half in [((2.0, 2.5, 0.3), rng.uniform(0.2, 5.0, 16), angles, model.beta / 2),
                                 ((4.5, 1.0, -2.0), np.r_[rng.uniform(0.2, 3.0, 180), np.inf], laser(), 0.01),
                                 ((-0.9, 5.4, 3.1), np.full(16, np.inf), angles, 0.3)]:
        want = cross_product_field_features(grid, np.array(pose), z, beams, 4.0, half)
        monkeypatch.setattr(il, "FIELD_CHUNK_PAIRS", chunk)
        got = il.field_features(grid, pose, z, beams, 4.0, half)
        monkeypatch.undo()
        assert got[0].size > 0
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])


def test_field_features_memory_is_bounded_whatever_the_scan():
    """200 x 200 cells in range of 180 beams: 7.2 million (cell, beam) pairs, at least 230 MB of
    complex temporaries in one piece before; in chunks of FIELD_CHUNK_PAIRS it stays under 100 MB."""
    import tracemalloc

    grid = probslam.OccupancyGrid2D(0.05, 200, 200)
    beams = laser(180)
    tracemalloc.start()
    try:
        cells, _ = il.field_features(grid, (5.0, 5.0, 0.0), np.full(180, 3.0), beams, 30.0, np.pi / 360)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert cells.size > 10000
    assert peak < 100 * 2 ** 20, peak


def untrained_free_model(hidden=2, prior=0.2):
    """A model with fixed weights (no training needed), as load would build it."""
    m = il.LearnedInverseModel(hidden=hidden)
    m.weights = np.linspace(-0.5, 0.5, m.n_weights(2 + il.NEIGHBOURS))
    m.mean, m.scale, m.prior = np.zeros(2 + il.NEIGHBOURS), np.ones(2 + il.NEIGHBOURS), prior
    return m


@pytest.mark.parametrize("change, name, message", [
    (dict(beam_angles=np.where(np.arange(16) == 3, np.nan, np.arange(16) * 0.39)), "beam_angles", "NaN"),
    (dict(beam_angles=np.zeros(0), z=np.zeros(0)), "beam_angles", "at least one beam"),
    (dict(half_angle=np.nan), "half_angle", "must be finite and > 0"),
    (dict(half_angle=-0.1), "half_angle", "must be finite and > 0"),
    (dict(max_range=np.inf), "max_range", "must be finite and > 0"),
    (dict(max_range=np.nan), "max_range", "must be finite and > 0"),
    (dict(max_range=0.0), "max_range", "must be finite and > 0"),
])
def test_insert_scan_refuses_non_finite_geometry_by_name(change, name, message):
    """NaN beam angles or half-angle used to update nothing, silently; max_range=inf raised
    OverflowError and NaN "cannot convert float NaN to integer"."""
    m = untrained_free_model()
    grid = probslam.OccupancyGrid2D(0.1, 40, 40)
    args = dict(beam_angles=np.arange(16) * 0.39, z=np.full(16, 1.0), max_range=4.0, half_angle=0.2)
    args.update(change)
    before = grid.log_odds.copy()
    with pytest.raises(ValueError, match=f"{name}.*{message}|{message}.*{name}") as info:
        m.insert_scan(grid, (2.0, 2.0, 0.0), args["z"], args["beam_angles"], args["max_range"], args["half_angle"])
    assert name in str(info.value)
    np.testing.assert_array_equal(grid.log_odds, before)


def test_insert_scan_far_outside_the_grid_changes_nothing_and_does_not_overflow():
    m = untrained_free_model()
    grid = probslam.OccupancyGrid2D(0.1, 40, 40)
    assert m.insert_scan(grid, (1e300, -1e300, 0.0), np.ones(16), np.arange(16) * 0.39, 1e300, 0.2) == 0
    assert m.insert_scan(grid, (2.0, 2.0, 0.0), np.ones(16), np.arange(16) * 0.39, 1e300, 0.2) > 0
    assert np.all(np.isfinite(grid.log_odds))


@pytest.mark.parametrize("kwargs, name", [(dict(rng=3), "rng"), (dict(data=3), "data"),
                                          (dict(max_iterations=2.5), "max_iterations")])
def test_train_names_an_argument_of_the_wrong_type(kwargs, name):
    """train(rng=3) raised AttributeError from deep inside."""
    m = il.LearnedInverseModel(hidden=2)
    args = dict(data=il.TrainingSet(np.random.default_rng(0).normal(size=(6, 7)), np.arange(6) % 2 == 0),
                rng=np.random.default_rng(1), max_iterations=3)
    args.update(kwargs)
    with pytest.raises(TypeError, match=name):
        m.train(**args)
    assert m.weights is None and m.mean is None and m.prior is None


def test_train_refuses_inputs_that_overflow_and_keeps_the_model():
    m = untrained_free_model()
    before = m.weights.copy()
    x = np.full((6, 7), 1e300)
    x[::2] = -1e300
    with pytest.raises(ValueError, match="inputs"):
        m.train(il.TrainingSet(x, np.arange(6) % 2 == 0), np.random.default_rng(1), max_iterations=3)
    np.testing.assert_array_equal(m.weights, before)
    assert m.prior == 0.2


def write_model(path, drop=(), **arrays):
    """A model file as save writes it, with some arrays replaced or dropped."""
    m = untrained_free_model()
    content = dict(weights=m.weights, mean=m.mean, scale=m.scale, meta='{"hidden": 2, "prior": 0.2}')
    content.update(arrays)
    np.savez(path, **{k: v for k, v in content.items() if k not in drop})
    return path


def npy_bytes(header, data=b""):
    """A .npy member with a hand-written header."""
    text = repr(header).encode()
    pad = 64 - (10 + len(text) + 1) % 64
    return b"\x93NUMPY\x01\x00" + (len(text) + pad + 1).to_bytes(2, "little") + text + b" " * pad + b"\n" + data


def write_zip(path, members):
    import zipfile
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return path


def test_load_round_trips_what_save_writes(tmp_path):
    m = untrained_free_model()
    m.save(tmp_path / "m.npz")
    back = il.LearnedInverseModel.load(tmp_path / "m.npz")
    np.testing.assert_array_equal(back.weights, m.weights)
    assert back.prior == m.prior and back.hidden == m.hidden


@pytest.mark.parametrize("make, message", [
    (lambda p: write_model(p, weights=np.full(19, np.nan)), "weights holds NaN or inf"),
    (lambda p: write_model(p, mean=np.r_[np.inf, np.zeros(6)]), "mean holds NaN or inf"),
    (lambda p: write_model(p, scale=np.zeros(7)), r"scale holds a deviation <= 0"),
    (lambda p: write_model(p, meta='{"hidden": 2, "prior": 0}'), r"prior must lie in \(0, 1\), got 0"),
    (lambda p: write_model(p, meta='{"hidden": 2, "prior": NaN}'), r"prior must lie in \(0, 1\)"),
    (lambda p: write_model(p, meta='{"hidden": 2, "prior": 1.0}'), r"prior must lie in \(0, 1\)"),
    (lambda p: write_model(p, meta='{"hidden": true, "prior": 0.2}'), "hidden must be an integer >= 1"),
    (lambda p: write_model(p, meta='{"hidden": 2}'), "meta: expected"),
    (lambda p: write_model(p, meta='{"hidden": 2, "prior": 0.'), "meta: not JSON"),
    (lambda p: write_model(p, meta="[" * 100000), "meta: not JSON"),
    (lambda p: write_model(p, drop=("scale",)), "expected the arrays"),
    (lambda p: write_model(p, extra=np.zeros(2)), "expected the arrays"),
    (lambda p: write_model(p, weights=np.zeros(18)), "weights do not match hidden = 2"),
    (lambda p: write_model(p, weights=np.zeros((19, 1))), r"weights: expected a 1-D array"),
    (lambda p: write_model(p, weights=np.array(["a"] * 19)), "weights: expected a 1-D array of dtype kind 'f'"),
    (lambda p: write_model(p, meta=np.array([1.0])), "meta: expected a 0-D array"),
    (lambda p: (p.write_text("ODOMETRY 0 1\n"), p)[1], "not a model file"),
    (lambda p: (p.write_bytes(b""), p)[1], "not a model file"),
    (lambda p: (p.write_bytes(write_model(p).read_bytes()[:300]), p)[1], "not a model file"),
    (lambda p: (p.write_bytes(npy_bytes({"descr": "<f8", "fortran_order": False, "shape": (3,)}, bytes(24))), p)[1],
     "not a model file"),
    (lambda p: write_zip(p, {"weights.npy": npy_bytes({"descr": "<f8", "fortran_order": False, "shape": (10 ** 12,)}),
                             "mean.npy": b"", "scale.npy": b"", "meta.npy": b""}), "do not fill the shape"),
    (lambda p: write_zip(p, {"weights.npy": b"\x93NUMPY junk", "mean.npy": b"", "scale.npy": b"",
                             "meta.npy": b""}), "weights: not a numpy array"),
])
def test_load_refuses_every_malformed_file_by_path_and_reason(tmp_path, make, message):
    """load took NaN weights and a prior of 0; a bad file gave KeyError or BadZipFile."""
    path = make(tmp_path / "model.npz")
    with pytest.raises(ValueError, match=message) as info:
        il.LearnedInverseModel.load(path)
    assert str(info.value).startswith(str(path) + ":")


def test_load_refuses_what_is_not_a_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        il.LearnedInverseModel.load(tmp_path / "missing.npz")
    with pytest.raises(ValueError, match="not a regular file"):
        il.LearnedInverseModel.load(tmp_path)
    with pytest.raises(TypeError, match="path"):
        il.LearnedInverseModel.load(3)
