"""slam2d scan matching: the branch-and-bound search against an independent numpy brute force of
the same lattice, the smooth score against numpy, covariance calibration (NEES) at three levels of
range noise, and bad input."""

import numpy as np
import pytest
from scipy import stats

import probslam as ps
from probslam import _core
from probslam.sim import cast_ranges

RES = 0.05
ORIGIN = (-6.0123, -5.9871)  # walls off the cell borders
WALLS = [((-5, -4), (5, -4)), ((5, -4), (5, 4)), ((5, 4), (-5, 4)), ((-5, 4), (-5, -4)),
         ((1, 1), (2, 1)), ((2, 1), (2, 2)), ((2, 2), (1, 2)), ((1, 2), (1, 1)), ((-3, -2), (-1, -3))]
ANGLES = np.linspace(-np.pi / 2, np.pi / 2, 181)


def cast(pose, angles, walls=None):
    """Ranges from pose along angles to the nearest of walls (default WALLS; inf when none)."""
    return cast_ranges(pose, angles, WALLS if walls is None else walls)


@pytest.fixture(scope="module")
def room():
    rng = np.random.default_rng(7)
    g = ps.OccupancyGrid2D.covering((ORIGIN[0], ORIGIN[1], 6, 6), RES)
    for _ in range(20):
        pose = np.array([rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3)])
        g.insert_rays(pose, cast(pose, ANGLES), ANGLES, 30.0)
    return g


def make_matcher(grid, sigma=0.05, **kw):
    field = _core.LikelihoodField(grid, sigma=sigma)
    return field, _core.CorrelativeScanMatcher(field, **kw)


def scan_at(rng, pose, noise=0.01, walls=None):
    r = cast(pose, ANGLES, walls) + rng.normal(0, noise, len(ANGLES))
    return _core.scan_hits(r, ANGLES)


def true_pose(rng):
    """Inside the room, outside the pillar [1, 2]^2 with a 0.3 m margin."""
    while True:
        x = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-np.pi, np.pi)])
        if not (0.7 < x[0] < 2.3 and 0.7 < x[1] < 2.3):
            return x


def numpy_search(field, pts, prior, linear, angular, step, cov=None):
    """Best score over the lattice: rotations theta0 + (a - A) step, translations prior + c res."""
    table = field.log_likelihood.astype(np.float64)
    h, w = table.shape
    res, origin = field.resolution, np.asarray(field.origin)
    W = int(np.ceil(linear / res))
    A = int(np.floor(angular / step + 1e-9))
    info = None if cov is None else np.linalg.inv(cov)
    c = np.arange(-W, W + 1)
    best = -np.inf
    for a in range(2 * A + 1):
        dth = (a - A) * step
        th = prior[2] + dth
        R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        q = pts @ R.T + prior[:2]
        # floor((q + c res - origin) / res) = floor((q - origin) / res) + c for integer c; the
        # latter keeps the rounding of the search, which discretises once.
        col = np.floor((q[:, 0] - origin[0]) / res).astype(int)
        row = np.floor((q[:, 1] - origin[1]) / res).astype(int)
        cols = col[None, :] + c[:, None]  # (cx, N)
        rows = row[None, :] + c[:, None]  # (cy, N)
        vals = np.full((len(c), len(c), len(pts)), field.floor_value, dtype=np.float64)
        inside = ((cols[:, None, :] >= 0) & (cols[:, None, :] < w) & (rows[None, :, :] >= 0) & (rows[None, :, :] < h))
        cc = np.broadcast_to(cols[:, None, :], vals.shape)
        rr = np.broadcast_to(rows[None, :, :], vals.shape)
        vals[inside] = table[rr[inside], cc[inside]]
        s = vals.sum(axis=2)
        if info is not None:
            X, Y = np.meshgrid(c * res, c * res, indexing="ij")
            d = np.stack([X, Y, np.full_like(X, dth)], axis=-1)
            s = s - 0.5 * np.einsum("...i,ij,...j->...", d, info, d)
        best = max(best, s.max())
    return best


@pytest.mark.parametrize("seed", range(6))
def test_branch_and_bound_equals_numpy_brute_force(room, seed):
    rng = np.random.default_rng(seed)
    field, m = make_matcher(room, max_level=[0, 1, 3, 6, 6, 2][seed])
    true = true_pose(rng)
    pts = scan_at(rng, true)[::3]
    prior = true + rng.uniform(-0.2, 0.2, 3)
    linear, angular, step = rng.uniform(0.1, 0.4), rng.uniform(0.05, 0.3), rng.uniform(0.01, 0.03)
    cov = None
    if seed % 2:
        L = np.array([[0.1, 0, 0], [0.05, 0.2, 0], [0.02, -0.03, 0.1]])
        cov = L @ L.T
    r = m.match(pts, prior, linear_window=linear, angular_window=angular, angular_step=step,
                prior_covariance=cov, refine=False)
    expected = numpy_search(field, pts, prior, linear, angular, step, cov)
    assert r.search_score == pytest.approx(expected, abs=1e-6)
    bf = m.match(pts, prior, linear_window=linear, angular_window=angular, angular_step=step,
                 prior_covariance=cov, refine=False, brute_force=True)
    assert bf.search_score == pytest.approx(expected, abs=1e-6)


def numpy_smooth_score(field, pts, pose):
    res, origin = field.resolution, np.asarray(field.origin)
    D = field.distance.astype(np.float64)
    h, w = D.shape
    cap = field.truncation
    c, s = np.cos(pose[2]), np.sin(pose[2])
    q = pts @ np.array([[c, -s], [s, c]]).T + pose[:2]
    u = (q[:, 0] - origin[0]) / res - 0.5
    v = (q[:, 1] - origin[1]) / res - 0.5
    c0, r0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - c0, v - r0

    def at(r, cc):
        ok = (r >= 0) & (r < h) & (cc >= 0) & (cc < w)
        out = np.full(len(r), cap)
        out[ok] = D[r[ok], cc[ok]]
        return out

    bottom = at(r0, c0) + fu * (at(r0, c0 + 1) - at(r0, c0))
    top = at(r0 + 1, c0) + fu * (at(r0 + 1, c0 + 1) - at(r0 + 1, c0))
    d = bottom + fv * (top - bottom)
    sig, p = field.sigma, field.p_rand
    return np.log((1 - p) * np.exp(-d * d / (2 * sig * sig)) + p).sum(), len(pts)


@pytest.mark.parametrize("seed", range(4))
def test_smooth_score_equals_numpy(room, seed):
    rng = np.random.default_rng(50 + seed)
    field, m = make_matcher(room, sigma=[0.05, 0.03, 0.1, 0.05][seed])
    true = true_pose(rng)
    pts = scan_at(rng, true)
    pose = true + rng.normal(0, 0.05, 3)
    expected, n = numpy_smooth_score(field, pts, pose)
    assert m.smooth_score(pts, pose) == pytest.approx(expected, abs=1e-5 * n)
    # with a prior: the Gaussian term joins
    prior = pose + np.array([0.03, -0.02, 0.01])
    cov = np.diag([0.01, 0.02, 0.005])
    d = pose - prior
    got = m.smooth_score(pts, pose, prior=prior, prior_covariance=cov)
    assert got == pytest.approx(expected - 0.5 * d @ np.linalg.solve(cov, d), abs=1e-5 * n)


def room_with_origin(origin, walls):
    """The map of walls, built as the `room` fixture builds its own, on a lattice from `origin`."""
    rng = np.random.default_rng(7)
    g = ps.OccupancyGrid2D.covering((origin[0], origin[1], 6, 6), RES)
    for _ in range(20):
        pose = np.array([rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3)])
        g.insert_rays(pose, cast(pose, ANGLES, walls), ANGLES, 30.0)
    return g


def match_nees(walls, noise, n=120, seed=2024):
    """Mean NEES of n matches, each on a map whose lattice origin is drawn anew within a cell, and
    the per-axis mean of err^2 / var. The map holds a wall only to a cell, so its offset from the
    truth is an error the covariance must cover; on one fixed lattice all trials would share one
    draw of it (the fixed `room` gives 2.56 here, its offset being 0.25 cells on both axes), and
    the chi-square band, which assumes independent trials, would not apply."""
    rng = np.random.default_rng(seed)
    nees, sq = [], []
    for _ in range(n):
        origin = (-6.0 - rng.uniform(0, RES), -6.0 - rng.uniform(0, RES))
        _, m = make_matcher(room_with_origin(origin, walls), sigma=0.05)
        true = true_pose(rng)
        pts = scan_at(rng, true, noise=noise, walls=walls)
        prior = true + rng.uniform(-0.1, 0.1, 3)
        r = m.match(pts, prior, linear_window=0.2, angular_window=0.15)
        e = r.pose - true
        e[2] = (e[2] + np.pi) % (2 * np.pi) - np.pi
        nees.append(e @ np.linalg.solve(r.covariance, e))
        sq.append(e * e / np.diag(r.covariance))
    return float(np.mean(nees)), np.mean(sq, axis=0)


NEES_BAND = stats.chi2.ppf([0.025, 0.975], 3 * 120) / 120  # 95% band of the mean of 120 chi2(3)
AXIS_WALLS = WALLS[:8]  # the room and the pillar: all on one lattice offset (integer coordinates)


@pytest.mark.parametrize("noise", [0.005, 0.015, 0.03])
@pytest.mark.slow
def test_covariance_is_calibrated_nees(noise):
    # Range noise from a third of the field's sigma to below it: the sandwich follows the points'
    # scatter, not sigma. Measured (mean, per-axis x y theta): 0.005: 2.61 (0.94 0.91 0.76);
    # 0.015: 2.84 (0.92 0.92 0.99); 0.03: 2.81 (0.91 0.91 0.97).
    mean, ratios = match_nees(AXIS_WALLS, noise)
    print(f"noise {noise}: mean NEES {mean:.3f} band {NEES_BAND.round(3)} per-axis err^2/var {ratios.round(3)}")
    assert NEES_BAND[0] <= mean <= NEES_BAND[1], (mean, NEES_BAND, ratios)


@pytest.mark.xfail(strict=True, reason="overconfident in rotation with the slanted wall: mean NEES 3.86, per-axis "
                   "0.90 0.70 2.26. Its offset on the lattice is its own, not the room's; the covariance models one "
                   "offset shared by all walls (no residual shows it), and a wall whose offset differs tilts the "
                   "pose by an amount no residual shows either. Walls at arbitrary positions (real maps) do the same.")
@pytest.mark.slow
def test_covariance_is_calibrated_nees_with_an_offset_wall():
    mean, ratios = match_nees(WALLS, 0.015)
    print(f"mean NEES {mean:.3f} band {NEES_BAND.round(3)} per-axis err^2/var {ratios.round(3)}")
    assert NEES_BAND[0] <= mean <= NEES_BAND[1], (mean, NEES_BAND, ratios)


def test_recovers_pose(room):
    rng = np.random.default_rng(11)
    _, m = make_matcher(room)
    for _ in range(8):
        true = true_pose(rng)
        pts = scan_at(rng, true, noise=0.01)
        r = m.match(pts, true + rng.uniform(-0.2, 0.2, 3))
        assert np.all(np.abs(r.pose[:2] - true[:2]) <= RES / 2)
        assert abs((r.pose[2] - true[2] + np.pi) % (2 * np.pi) - np.pi) <= max(r.angular_step, 0.01)


def test_bad_input_names_the_argument(room):
    field, m = make_matcher(room)
    pts = np.array([[1.0, 0.0], [0.0, 1.0], [2.0, 0.5]])
    prior = np.zeros(3)

    def raises(call, name, kinds=(ValueError, TypeError)):
        with pytest.raises(kinds) as e:
            call()
        assert name in str(e.value), str(e.value)

    raises(lambda: m.match(np.zeros((3, 3)), prior), "points")
    raises(lambda: m.match(np.zeros((0, 2)), prior), "points")
    raises(lambda: m.match(np.array([[np.nan, 0.0]]), prior), "points")
    raises(lambda: m.match(None, prior), "points")
    raises(lambda: m.match("abc", prior), "points")
    raises(lambda: m.match(pts, np.zeros(2)), "prior")
    best = m.match(pts, prior)
    raises(lambda: m.runner_up(pts, prior, best, -1.0), "distinct_chi2")
    raises(lambda: m.runner_up(pts, prior, best, np.nan), "distinct_chi2")
    raises(lambda: m.runner_up(pts, prior, best, 16.27, admitted=np.ones(2)), "admitted")
    raises(lambda: m.runner_up(pts, prior, m.match(pts, prior, min_score=0.0), 16.27), "best")
    raises(lambda: m.closeness(pts[:1], prior, prior), "points")
    raises(lambda: m.closeness(pts, prior, np.array([0.0, np.inf, 0.0])), "b")
    raises(lambda: m.match(pts, [np.nan, 0, 0]), "prior")
    raises(lambda: m.match(pts, None), "prior")
    raises(lambda: m.match(pts, "abc"), "prior")
    raises(lambda: m.match(pts, prior, linear_window=-0.1), "linear_window")
    raises(lambda: m.match(pts, prior, angular_window=4.0), "angular_window")
    raises(lambda: m.match(pts, prior, linear_window=np.nan), "linear_window")
    raises(lambda: m.match(pts, prior, linear_window=2000.0, angular_window=0.0), "window")
    raises(lambda: m.match(pts, prior, prior_covariance=-np.eye(3)), "prior_covariance")
    raises(lambda: m.match(pts, prior, prior_covariance=np.eye(2)), "prior_covariance")
    raises(lambda: m.match(pts, prior, prior_covariance=np.full((3, 3), np.nan)), "prior_covariance")
    raises(lambda: m.smooth_score(pts, np.zeros(2)), "pose")
    raises(lambda: m.smooth_score(np.zeros((2, 3)), prior), "points")
    raises(lambda: _core.CorrelativeScanMatcher(field, max_level=11), "max_level")
    raises(lambda: _core.CorrelativeScanMatcher(field, max_level=-1), "max_level")
    raises(lambda: _core.LikelihoodField(room, sigma=0.0), "sigma")
    raises(lambda: _core.LikelihoodField(room, sigma=np.nan), "sigma")
    raises(lambda: _core.LikelihoodField(room, p_rand=1.0), "p_rand")
    raises(lambda: _core.LikelihoodField(room, p_rand=0.0), "p_rand")
    raises(lambda: _core.LikelihoodField(room, region=(0, 0, np.nan, 1)), "region")
    raises(lambda: _core.LikelihoodField(room, region=(1, 1, 0, 0)), "region")
    raises(lambda: _core.LikelihoodField(room, region=(0, 0, 1)), "region")
    raises(lambda: _core.scan_hits(np.ones(3), np.ones(2)), "beam_angles")
    raises(lambda: _core.scan_hits(np.ones((3, 2)), np.ones(3)), "ranges")
    raises(lambda: _core.scan_hits(np.ones(3), np.ones(3), min_range=-1.0), "min_range")
    raises(lambda: _core.scan_hits(np.ones(3), np.ones(3), max_range=np.nan), "max_range")
    raises(lambda: _core.ranges_for_insertion(np.ones(3), max_usable_range=np.inf), "max_usable_range")
    raises(lambda: _core.scan_hits(np.ones(3), np.ones(3), min_point_spacing=-1.0), "min_point_spacing")


def test_scan_filter_semantics():
    r = np.array([1.0, np.nan, np.inf, 10.0, 12.0, -1.0, 0.05, 6.0, 2.0])
    a = np.linspace(-1, 1, len(r))
    hits = _core.scan_hits(r, a, max_range=10.0, min_range=0.1, max_usable_range=5.0)
    np.testing.assert_allclose(np.hypot(hits[:, 0], hits[:, 1]), [1.0, 2.0])
    out, usable = _core.ranges_for_insertion(r, max_range=10.0, min_range=0.1, max_usable_range=5.0)
    assert usable == 5.0
    np.testing.assert_array_equal(out, [1.0, 5.0, 5.0, 5.0, 5.0, np.nan, np.nan, 5.0, 2.0])
    out, _ = _core.ranges_for_insertion(r, max_range=10.0, min_range=0.1, max_usable_range=5.0,
                                        clear_no_return=False)
    np.testing.assert_array_equal(out, [1.0] + [np.nan] * 7 + [2.0])


#: The loop closures' uniqueness test (SubmapSlam2D::unique_match): a match is another place's
#: look-alike when Vuong's statistic against its runner-up is below the one-sided normal quantile
#: of dissolve_chi2's confidence (chi2(3) 16.27: 0.999, z 3.09).
UNIQUE_Z = stats.norm.ppf(stats.chi2.cdf(16.27, 3))
#: The scans of the look-alike test see this far: one box, not the other nor the room's walls.
NEAR = 1.6


def box(cx, cy, half=0.4):
    c = [(cx - half, cy - half), (cx + half, cy - half), (cx + half, cy + half), (cx - half, cy + half)]
    return [(c[k], c[(k + 1) % 4]) for k in range(4)]


def look_alike(second):
    """A 10 x 8 m room with a box at (-1.5, 0) and `second` (walls) beside it; a map of it, a
    matcher, and a near scan of the first box from its lower left."""
    walls = [((-5, -4), (5, -4)), ((5, -4), (5, 4)), ((5, 4), (-5, 4)), ((-5, 4), (-5, -4))] + box(-1.5, 0) + second
    angles = np.linspace(-np.pi, np.pi, 720, endpoint=False)
    g = ps.OccupancyGrid2D.covering((-5.5123, -4.4871, 5.5, 4.5), RES)
    for x in (-3.0, -1.5, 0.0, 1.5, 3.0):
        for y in (-1.5, 1.5):
            g.insert_rays(np.array([x, y, 0.0]), cast_ranges(np.array([x, y, 0.0]), angles, walls), angles, 30.0)
    _, m = make_matcher(g)
    true = np.array([-2.3, -1.1, np.pi / 4])
    r = cast_ranges(true, ANGLES, walls)
    return m, true, _core.scan_hits(np.where(r <= NEAR, r, np.inf), ANGLES)


def test_runner_up_is_the_look_alike_box_and_as_likely():
    m, true, pts = look_alike(box(1.5, 0))
    prior = true + np.array([0.1, -0.05, 0.03])
    kw = dict(linear_window=3.5, angular_window=0.2)
    best = m.match(pts, prior, **kw)
    ru = m.runner_up(pts, prior, best, 16.27, **kw)
    assert ru.found
    # One of them is the true place, the other the same place by the look-alike box, 3 m on.
    places = sorted([best.pose[0], ru.pose[0]])
    np.testing.assert_allclose(places, [true[0], true[0] + 3.0], atol=RES)
    np.testing.assert_allclose([best.pose[1], ru.pose[1]], true[1], atol=RES)
    assert abs(m.closeness(pts, best.pose, ru.pose)) < UNIQUE_Z
    # The branch and bound's runner-up is the brute force's over the same lattice.
    lattice = [m.runner_up(pts, prior, best, 16.27, refine=False, brute_force=bf, **kw) for bf in (False, True)]
    assert lattice[0].search_score == pytest.approx(lattice[1].search_score, abs=1e-6)
    np.testing.assert_allclose(lattice[0].search_pose, lattice[1].search_pose, atol=1e-9)
    # Admitted only within a metre of the prior, the other box is no runner-up.
    near = m.runner_up(pts, prior, best, 16.27, admitted=np.diag([1.0, 1.0, 0.0]), **kw)
    assert not near.found or np.linalg.norm(near.pose[:2] - prior[:2]) <= 1.0 + RES


def test_a_unique_match_explains_the_scan_better_than_its_runner_up():
    # The second box turned into a wall: nothing else looks like the first box from there.
    m, true, pts = look_alike([((1.0, -0.4), (2.0, 0.4))])
    prior = true + np.array([0.1, -0.05, 0.03])
    kw = dict(linear_window=3.5, angular_window=0.2)
    best = m.match(pts, prior, **kw)
    assert np.abs(best.pose[:2] - true[:2]).max() <= RES
    ru = m.runner_up(pts, prior, best, 16.27, **kw)
    assert not ru.found or m.closeness(pts, best.pose, ru.pose) > UNIQUE_Z, ru
