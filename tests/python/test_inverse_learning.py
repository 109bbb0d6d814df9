"""Learning inverse measurement models from a forward model (ch. 9.3)."""

import numpy as np
import pytest

import probslam
from probslam import inverse_learning as il
from probslam.pipelines.map_run import BUNDLED_INVERSE_MODEL
from probslam.data import path as data_path

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


def train_sonar(seed, cells, maps, poses_per_map, cells_per_scan, hidden, iterations):
    """A sonar model trained on sampled rooms of cells x cells at 0.1 m: (model, training set, grid)."""
    rng = np.random.default_rng(seed)
    grid = probslam.OccupancyGrid2D(0.1, cells, cells)
    model, angles = sonar()
    data = il.sample_training_set(grid, model, angles, maps=maps, poses_per_map=poses_per_map, rng=rng,
                                  cells_per_scan=cells_per_scan)
    return il.LearnedInverseModel(hidden=hidden).train(data, rng, max_iterations=iterations), data, grid


@pytest.fixture(scope="module")
def trained():
    return train_sonar(4, 80, 4, 25, 250, 8, 200)[:2]


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


# --- issue 37: evidence scale, calibration, real-data training set, another world prior ------

#: Expected calibration error (10 bins) of a small model's single-scan probabilities on held-out
#: scans: 0.017 at the sizes below (docs/occupancy_mapping.md: ~0.03 for the study's sonar);
#: 0.05 leaves room for other seeds while the same model with its log-odds tripled
#: (overconfident, the failure the measure detects) scores 0.107, above twice that.
ECE_LIMIT = 0.05


def expected_calibration_error(p, y, bins=10):
    b = np.minimum((p * bins).astype(int), bins - 1)
    return sum(np.sum(b == k) / p.size * abs(p[b == k].mean() - y[b == k].mean()) for k in range(bins) if np.any(b == k))


@pytest.fixture(scope="module")
def small_sonar_model():
    """A sonar model trained in a few seconds (2 maps x 12 poses, 4 hidden units)."""
    m, _, grid = train_sonar(11, 60, 2, 12, 300, 4, 150)
    return (m, grid) + sonar()


def test_single_scan_probabilities_are_calibrated_on_held_out_scans(small_sonar_model):
    m, grid, model, angles = small_sonar_model
    held_out = il.sample_training_set(grid, model, angles, maps=2, poses_per_map=10, rng=np.random.default_rng(99),
                                      cells_per_scan=10 ** 6)
    p, y = m.probability(held_out.inputs), held_out.occupied.astype(float)
    assert expected_calibration_error(p, y) < ECE_LIMIT
    # the measure sees an overconfident model (its log-odds tripled: what many scans added as
    # if independent do to a map)
    sharpened = 1 / (1 + np.exp(-3 * probability_logit(p)))
    assert expected_calibration_error(sharpened, y) > 2 * ECE_LIMIT


def probability_logit(p):
    return np.log(p) - np.log1p(-p)


def test_fit_evidence_scale_minimises_the_map_cross_entropy_and_round_trips(small_sonar_model, tmp_path):
    m, grid, model, angles = small_sonar_model
    worlds = il.sample_scans(grid, model, angles, maps=1, poses_per_map=30, rng=np.random.default_rng(12))
    s = m.fit_evidence_scale(worlds, grid, angles, model.max_range, model.beta / 2)
    assert 0 < s < 2 and m.evidence_scale == s

    def map_ce(scale):  # Table 9.1 through insert_scan, scored over the cells some scan covers
        g = probslam.OccupancyGrid2D(0.1, 60, 60, p_prior=m.prior, clamp=None)
        m.evidence_scale = scale
        seen = np.zeros(3600, bool)
        occ, poses, scans = worlds[0]
        for pose, z in zip(poses, scans):
            m.insert_scan(g, pose, z, angles, model.max_range, model.beta / 2)
            seen[il.field_features(g, pose, z, angles, model.max_range, model.beta / 2)[0]] = True
        return il.map_cross_entropy(g.log_odds.ravel()[seen], occ.ravel()[seen])

    best = map_ce(s)
    assert best <= map_ce(s * 1.2) and best <= map_ce(s / 1.2)
    m.evidence_scale = s
    m.save(tmp_path / "scaled.npz")
    back = il.LearnedInverseModel.load(tmp_path / "scaled.npz")
    assert back.evidence_scale == s
    x = np.random.default_rng(5).normal(2.0, 1.0, (20, 7))
    np.testing.assert_array_equal(back.probability(x), m.probability(x))


def test_a_model_file_without_evidence_scale_loads_with_one(tmp_path):
    back = il.LearnedInverseModel.load(write_model(tmp_path / "old.npz"))
    assert back.evidence_scale == 1.0
    with pytest.raises(ValueError, match="evidence_scale must be finite and >= 0"):
        il.LearnedInverseModel.load(write_model(tmp_path / "bad.npz",
                                                meta='{"hidden": 2, "prior": 0.2, "evidence_scale": -1}'))


def test_real_training_set_labels_a_hand_checked_cell():
    """A 5 m x 5 m known map of 0.5 m cells with a wall in column 8 (x in [4, 4.5)); one scan of
    three beams from (1.25, 2.25) heading 0. The cell of row 4, column 5 has its centre at
    (2.75, 2.25): range 1.5 m, straight on beam 1, free; the wall cell (row 4, column 8) at
    3.0 m is occupied; the cell in column 6 is undecided in the known map and left out."""
    grid = probslam.OccupancyGrid2D(0.5, 10, 10)
    occupied = np.zeros((10, 10), bool)
    occupied[:, 8] = True
    known = np.ones((10, 10), bool)
    known[4, 6] = False
    angles = np.array([-0.1, 0.0, 0.1])
    ranges = np.array([[2.76, 2.75, 81.9]])  # the third: the sensor's no-return value
    data = il.real_training_set(grid, occupied, known, np.array([[1.25, 2.25, 0.0]]), ranges, angles,
                                max_range=4.0, half_angle=0.05, no_return=81.9)
    z = [4.0, 2.76, 2.75, 4.0, 2.76]  # beams 2, 0, 1, 2, 0 (ring order around beam 1); no return -> max_range
    rows = {tuple(np.round(x[:2], 9)): (x, y) for x, y in zip(data.inputs, data.occupied)}
    x, y = rows[(1.5, 0.0)]
    np.testing.assert_allclose(x[2:], z)
    assert not y
    x, y = rows[(3.0, 0.0)]
    assert y
    assert (2.0, 0.0) not in rows  # column 6: undecided
    # every row is a decided cell in the field, labelled by the known map
    cells, feats = il.field_features(grid, (1.25, 2.25, 0.0), np.array([2.76, 2.75, np.inf]), angles, 4.0, 0.05)
    keep = known.ravel()[cells]
    np.testing.assert_array_equal(data.inputs, feats[keep])
    np.testing.assert_array_equal(data.occupied, occupied.ravel()[cells[keep]])


def test_pillar_map_has_outer_walls_and_round_pillars():
    grid = probslam.OccupancyGrid2D(0.1, 80, 60)
    occ = il.pillar_map(grid, np.random.default_rng(2), walls=0, pillars=1)
    assert occ[0].all() and occ[-1].all() and occ[:, 0].all() and occ[:, -1].all()
    inner = occ[1:-1, 1:-1]
    rows, cols = np.nonzero(inner)
    area = inner.sum() * 0.01
    radius = np.sqrt(area / np.pi)
    assert 0.08 < radius < 0.45  # one disc of radius 0.1-0.4 m (cell-rounded)
    assert np.ptp(rows) == pytest.approx(np.ptp(cols), abs=1)  # round: as tall as wide
    slanted = il.pillar_map(grid, np.random.default_rng(3), walls=3, pillars=0)
    assert slanted[1:-1, 1:-1].sum() > 3 * 10  # three walls of 1.5 m or more (clipped at the border)


def test_map_command_uses_a_saved_learned_model(tmp_path, capsys):
    """probslam map LOG --inverse-model MODEL.npz: the same grid as inserting every scan of the
    log with insert_scan by hand (no-return readings as inf, half a beam spacing either side)."""
    from probslam import cli, io

    m = untrained_free_model()
    m.evidence_scale = 0.5
    m.save(tmp_path / "model.npz")
    scans = io.read_carmen_log(data_path(cli.BUNDLED_LOG)).scans
    summary = il.map_laser_log_learned(m, scans, resolution=0.2, max_range=4.0, progress=False)
    grid = summary.grid
    by_hand = probslam.OccupancyGrid2D(0.2, grid.width, grid.height, origin=grid.origin, p_prior=0.2,
                                       clamp=il.learned_map_clamp(0.2))
    angles = scans.beam_angles()
    for pose, z, a, step in zip(scans.laser_poses, scans.ranges, angles, scans.angular_resolutions):
        m.insert_scan(by_hand, pose, np.where(z >= 81.83, np.inf, z), a, 4.0, abs(step) / 2)  # 81.83: no return
    np.testing.assert_array_equal(grid.log_odds, by_hand.log_odds)
    assert summary.scans == len(scans)
    args = ["map", "--inverse-model", str(tmp_path / "model.npz"), "--resolution", "0.2", "--max-range", "4",
            "-o", str(tmp_path / "m"), "--no-progress", "--no-plot"]
    assert cli.main(args) == 0
    assert f"cells updated: {summary.cells_updated}" in capsys.readouterr().out
    saved = io.load_ros_map(tmp_path / "m.yaml")
    assert saved.same_geometry(grid)
    (tmp_path / "bad.npz").write_text("not a model")
    args[2] = str(tmp_path / "bad.npz")
    assert cli.main(args) == 2
    assert "--inverse-model" in capsys.readouterr().err


def test_bundled_model_maps_the_bundled_log_as_the_ray_model_where_it_is_sure(tmp_path):
    """`probslam map --inverse-model bundled`: the model shipped in probslam.data (trained on the
    first half of the Intel corrected log, studies/eval_inverse_real.py --save-model) loads and
    maps; on the bundled Intel excerpt its map agrees with the ray model's where the latter is
    sure (beyond p = 0.88 either way: walls above the prior, free space below it)."""
    from probslam import cli, io

    model = il.LearnedInverseModel.load(probslam.data.path(BUNDLED_INVERSE_MODEL))
    assert 0.0 < model.evidence_scale < 1.0  # fitted for Table 9.1's overlapping scans
    assert cli.main(["map", "--inverse-model", "bundled", "--resolution", "0.1", "--max-range", "10",
                     "-o", str(tmp_path / "learned"), "--no-progress", "--no-plot"]) == 0
    assert (tmp_path / "learned.yaml").exists()
    scans = io.read_carmen_log(data_path(cli.BUNDLED_LOG)).scans
    learned = il.map_laser_log_learned(model, scans, resolution=0.1, max_range=10.0, progress=False).grid
    rays = probslam.map_laser_log(scans, resolution=0.1, max_range=10.0, progress=False).grid
    # The two grids are bounded differently: the learned map's cell at each sure ray cell's centre.
    rows, cols = np.nonzero(np.abs(rays.log_odds) > 2.0)
    x = rays.origin[0] + (cols + 0.5) * rays.resolution
    y = rays.origin[1] + (rows + 0.5) * rays.resolution
    c = np.floor((x - learned.origin[0]) / learned.resolution).astype(int)
    r = np.floor((y - learned.origin[1]) / learned.resolution).astype(int)
    inside = (r >= 0) & (r < learned.height) & (c >= 0) & (c < learned.width)
    ours = learned.log_odds[r[inside], c[inside]] - probslam.logit(model.prior)
    agree = np.sign(ours) == np.sign(rays.log_odds[rows[inside], cols[inside]])
    assert inside.sum() > 1000 and agree.mean() > 0.9, (inside.sum(), agree.mean())


def test_learned_map_clamp_lies_below_the_prior():
    """A real laser's prior (~0.09) lies below OccupancyGrid2D's default lower clamp (0.119):
    the learned map's clamp moves it to CLAMP_BELOW_PRIOR log-odds below the prior, so free
    cells can fall below unknown; a prior of 0.5 keeps the default."""
    for prior in (0.0876, 0.02, 0.3):
        lo, hi = il.learned_map_clamp(prior)
        assert lo < prior and hi == il.DEFAULT_CLAMP[1]
        if prior < 0.3:
            np.testing.assert_allclose(probslam.logit(prior) - probslam.logit(lo), il.CLAMP_BELOW_PRIOR)
    assert il.learned_map_clamp(0.5) == il.DEFAULT_CLAMP
