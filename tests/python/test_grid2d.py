"""OccupancyGrid2D: Table 9.1/9.2 against a brute-force numpy loop, the laser-beam update against a
pure-Python reference and its stated properties, geometry, fusion, growth and bad input."""

import numpy as np
import pytest

import probslam as ps
from reference import cell_centres, cone_update, ism_numpy, rays_update, walk


def random_scan(rng, n, z_max, fov=2 * np.pi):
    angles = np.sort(rng.uniform(-fov / 2, fov / 2, n))
    ranges = rng.uniform(0.2, z_max * 1.1, n)
    ranges[rng.random(n) < 0.05] = np.nan
    return ranges, angles


@pytest.mark.parametrize("seed", range(6))
def test_insert_cone_scan_equals_all_cells_numpy_loop(seed):
    rng = np.random.default_rng(seed)
    clamp = None if seed % 2 == 0 else (0.2, 0.9)
    grid = ps.OccupancyGrid2D(0.1, 80, 60, origin=(-3.0, -2.5), p_prior=0.45, clamp=clamp)
    expected = grid.log_odds.copy()
    lo, hi = (ps.logit(clamp[0]), ps.logit(clamp[1])) if clamp else (-np.inf, np.inf)
    for _ in range(4):
        pose = np.array([rng.uniform(-3, 5), rng.uniform(-2.5, 3.5), rng.uniform(-np.pi, np.pi)])
        ranges, angles = random_scan(rng, int(rng.integers(5, 60)), 4.0, fov=rng.uniform(0.5, 2 * np.pi))
        params = dict(z_max=4.0, alpha=0.25, beta=np.radians(rng.uniform(1, 20)), l_occ=0.85, l_free=-0.4)
        grid.insert_cone_scan(pose, ranges, angles, **params)
        updated = cone_update(expected, grid.origin, 0.1, pose, ranges, angles, l0=grid.l0, **params)
        in_field = updated != expected  # Table 9.1 line 3: cells whose ism differs from l0
        expected = np.where(in_field, np.clip(updated, lo, hi), expected)
        np.testing.assert_array_equal(grid.log_odds, expected)


def test_inverse_range_sensor_model_matches_numpy_and_ties():
    rng = np.random.default_rng(1)
    pose = np.array([0.3, -0.2, 0.9])
    ranges, angles = random_scan(rng, 40, 5.0)
    cells = rng.uniform(-6, 6, (5000, 2))
    args = dict(z_max=5.0, alpha=0.3, beta=0.2, l0=0.1, l_occ=1.0, l_free=-1.0)
    np.testing.assert_array_equal(ps.inverse_range_sensor_model(cells, pose, ranges, angles, **args),
                                  ism_numpy(cells, pose, ranges, angles, **args))
    # A single (2,) cell gives a float; duplicated beam angles resolve to the lowest index.
    cell = np.array([2.0, 0.0])
    dup = ps.inverse_range_sensor_model(cell, [0, 0, 0], [2.0, 1.0], [0.0, 0.0], **args)
    assert isinstance(dup, float) and dup == args["l_occ"]
    dup2 = ps.inverse_range_sensor_model(cell, [0, 0, 0], [1.0, 2.0], [0.0, 0.0], **args)
    assert dup2 == args["l0"]  # beam 0 (1 m) wins: the cell lies behind its obstacle


@pytest.mark.parametrize("seed", range(5))
def test_insert_rays_equals_pure_python_reference(seed):
    rng = np.random.default_rng(100 + seed)
    clamp = (0.12, 0.97)
    grid = ps.OccupancyGrid2D(0.1, 70, 50, origin=(-3.5, -2.0), clamp=clamp)
    expected = grid.log_odds.copy()
    for _ in range(4):
        pose = np.array([rng.uniform(-4, 4), rng.uniform(-2.5, 3.5), rng.uniform(-np.pi, np.pi)])
        ranges, angles = random_scan(rng, 90, 5.0)
        grid.insert_rays(pose, ranges, angles, 5.0)
        expected = rays_update(expected, grid.origin, 0.1, pose, ranges, angles, 5.0,
                               clamp=(ps.logit(clamp[0]), ps.logit(clamp[1])))
        np.testing.assert_array_equal(grid.log_odds, expected)


def crossing_length(segments, centres, res):
    """(n_cells,) longest length of any segment inside each cell (exact slab test)."""
    best = np.zeros(len(centres))
    for (ox, oy), (ex, ey) in segments:
        d = np.array([ex - ox, ey - oy])
        t0, t1 = np.zeros(len(centres)), np.ones(len(centres))
        for axis, o in ((0, ox), (1, oy)):
            lo, hi = centres[:, axis] - res / 2, centres[:, axis] + res / 2
            if d[axis] == 0:
                inside = (o >= lo) & (o < hi)
                t1 = np.where(inside, t1, -1.0)
                continue
            a, b = (lo - o) / d[axis], (hi - o) / d[axis]
            t0, t1 = np.maximum(t0, np.minimum(a, b)), np.minimum(t1, np.maximum(a, b))
        best = np.maximum(best, (t1 - t0) * np.hypot(*d))
    return best


@pytest.mark.parametrize("seed", range(4))
def test_insert_rays_properties(seed):
    rng = np.random.default_rng(seed)
    res, max_range = 0.1, 4.0
    grid = ps.OccupancyGrid2D(res, 120, 120, origin=(-6.0, -6.0))  # holds every end point
    pose = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-np.pi, np.pi)])
    ranges, angles = random_scan(rng, 60, max_range)
    grid.insert_rays(pose, ranges, angles, max_range)
    l = grid.log_odds.ravel()
    hit, miss = ps.logit(0.7), ps.logit(0.4)

    valid = np.isfinite(ranges) & (ranges >= 0)
    reach = np.minimum(ranges[valid], max_range)
    bearing = pose[2] + angles[valid]
    ends = pose[:2] + reach[:, None] * np.column_stack([np.cos(bearing), np.sin(bearing)])
    is_hit = ranges[valid] < max_range
    end_cells = grid.cell_of(ends)
    end_index = end_cells[:, 0] * grid.width + end_cells[:, 1]
    # End cells of hits are occupied.
    assert np.all(l[end_index[is_hit]] == hit)
    # Cells the rays cross (beyond a grazing touch), other than end cells, are free.
    crossed = crossing_length([(pose[:2], e) for e in ends], cell_centres(grid.origin, res, 120, 120), res)
    ends_all = np.zeros(l.size, bool)
    ends_all[end_index] = True
    assert np.all(l[(crossed > 1e-9) & ~ends_all] == miss)
    # Untouched cells hold the prior exactly.
    assert np.all(l[(crossed <= 0) & ~ends_all] == grid.l0)
    # Duplicating every beam changes nothing.
    twin = ps.OccupancyGrid2D(res, 120, 120, origin=(-6.0, -6.0))
    twin.insert_rays(pose, np.repeat(ranges, 2), np.repeat(angles, 2), max_range)
    np.testing.assert_array_equal(twin.log_odds, grid.log_odds)


def test_max_range_readings_clear_but_mark_nothing_and_invalid_are_skipped():
    grid = ps.OccupancyGrid2D(0.1, 100, 20, origin=(0.0, 0.0), clamp=None)
    n = grid.insert_rays([0.05, 1.05, 0.0], [5.0, np.nan, np.inf, -1.0], [0.0, 0.1, 0.2, 0.3], 5.0)
    assert n == 50  # cells 0..49 along the ray, nothing marked at 5 m
    assert np.all(grid.log_odds[10, :50] == ps.logit(0.4))
    assert np.all(grid.log_odds[10, 50:] == 0.0)
    assert np.count_nonzero(grid.log_odds) == 50


def test_rays_leaving_the_map_are_clipped():
    grid = ps.OccupancyGrid2D(0.1, 20, 20, origin=(0.0, 0.0))
    angles = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    grid.insert_rays([-1.0, 1.0, 0.0], np.full(360, 10.0), angles, 30.0)  # sensor outside
    grid.insert_rays([1.0, 1.0, 0.0], np.full(360, 10.0), angles, 30.0)   # ends outside
    assert np.all(np.isfinite(grid.log_odds))
    assert np.count_nonzero(grid.log_odds) == 400


def test_log_odds_is_a_zero_copy_view_and_probability_is_eq_9_6():
    grid = ps.OccupancyGrid2D(0.5, 4, 3)
    view = grid.log_odds
    assert view.shape == (3, 4) and not view.flags.owndata
    view[1, 2] = 2.0
    assert grid.log_odds[1, 2] == 2.0
    assert np.shares_memory(view, grid.log_odds)
    np.testing.assert_allclose(grid.probability(), 1 - 1 / (1 + np.exp(grid.log_odds)))
    del grid
    assert view[1, 2] == 2.0  # the view keeps its grid alive


def test_geometry_helpers():
    grid = ps.OccupancyGrid2D(0.25, 8, 4, origin=(1.0, -1.0))
    np.testing.assert_array_equal(grid.cell_of([[1.0, -1.0], [2.99, -0.01], [0.9, 0.0]]), [[0, 0], [3, 7], [4, -1]])
    centres = grid.cell_centers()
    np.testing.assert_allclose(centres, cell_centres((1.0, -1.0), 0.25, 4, 8))
    assert grid.shape == (4, 8)


def test_textbook_update_accumulates_without_clamp():
    grid = ps.OccupancyGrid2D(0.1, 40, 5, clamp=None)
    for _ in range(30):
        grid.insert_rays([0.05, 0.25, 0.0], [2.0], [0.0], 3.0)
    assert grid.log_odds[2, 20] == pytest.approx(30 * ps.logit(0.7))
    assert grid.log_odds[2, 5] == pytest.approx(30 * ps.logit(0.4))


def test_insert_scans_equals_sequence_of_insert_rays():
    rng = np.random.default_rng(5)
    poses = np.column_stack([rng.uniform(-1, 1, 6), rng.uniform(-1, 1, 6), rng.uniform(-3, 3, 6)])
    angles = np.linspace(-2, 2, 50)
    ranges = rng.uniform(0.5, 3.5, (6, 50))
    a, b = ps.OccupancyGrid2D(0.05, 120, 120, origin=(-3, -3)), ps.OccupancyGrid2D(0.05, 120, 120, origin=(-3, -3))
    a.insert_scans(poses, ranges, angles, 3.0)
    for p, r in zip(poses, ranges):
        b.insert_rays(p, r, angles, 3.0)
    np.testing.assert_array_equal(a.log_odds, b.log_odds)


def test_clear_footprint_fuse_max_and_grow():
    grid = ps.OccupancyGrid2D(0.1, 30, 30, clamp=None)
    assert grid.clear_footprint([1.55, 1.55, 0.0], 0.25, l_free=-2.0) == 21
    other = grid.copy()
    other.log_odds[0, 0] = 4.0
    grid.log_odds[29, 29] = 1.0
    fused = ps.fuse_max([grid, other])
    np.testing.assert_array_equal(fused.log_odds, np.maximum(grid.log_odds, other.log_odds))
    np.testing.assert_allclose(fused.probability(), np.maximum(grid.probability(), other.probability()))
    grown = grid.grown((-1.0, -0.5, 4.0, 3.0))
    assert grown.shape == (35, 50) and grown.origin == pytest.approx((-1.0, -0.5))
    np.testing.assert_array_equal(grown.log_odds[5:35, 10:40], grid.log_odds)
    assert np.all(grown.log_odds[:5] == grid.l0)
    covering = ps.OccupancyGrid2D.covering((-2, -1, 3, 4), 0.5)
    assert covering.shape == (10, 10) and covering.origin == (-2.0, -1.0)


@pytest.mark.parametrize("kwargs, name", [
    (dict(resolution=0.0, width=10, height=10), "resolution"),
    (dict(resolution=-1.0, width=10, height=10), "resolution"),
    (dict(resolution=np.nan, width=10, height=10), "resolution"),
    (dict(resolution=0.1, width=0, height=10), "width"),
    (dict(resolution=0.1, width=10, height=-3), "height"),
    (dict(resolution=0.1, width=10, height=10, origin=(np.nan, 0)), "origin"),
    (dict(resolution=0.1, width=10, height=10, origin=(0, 0, 0)), "origin"),
    (dict(resolution=0.1, width=10, height=10, p_prior=1.0), "p_prior"),
    (dict(resolution=0.1, width=10, height=10, clamp=(0.9, 0.1)), "clamp"),
    (dict(resolution=0.1, width=10, height=10, p_hit=1.5), "p_hit"),
])
def test_bad_grid_arguments(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ps.OccupancyGrid2D(**kwargs)


@pytest.mark.parametrize("call, err, name", [
    (lambda g: g.insert_rays([np.nan, 0, 0], [1.0], [0.0], 5.0), ValueError, "pose"),
    (lambda g: g.insert_rays([0, 0], [1.0], [0.0], 5.0), ValueError, "pose"),
    (lambda g: g.insert_rays("x", [1.0], [0.0], 5.0), TypeError, "pose"),
    (lambda g: g.insert_rays([0, 0, 0], [], [], 5.0), ValueError, "ranges"),
    (lambda g: g.insert_rays([0, 0, 0], [[1.0]], [0.0], 5.0), ValueError, "ranges"),
    (lambda g: g.insert_rays([0, 0, 0], [1.0, 2.0], [0.0], 5.0), ValueError, "angles"),
    (lambda g: g.insert_rays([0, 0, 0], [1.0], [np.nan], 5.0), ValueError, "angles"),
    (lambda g: g.insert_rays([0, 0, 0], [1.0], [0.0], 0.0), ValueError, "max_range"),
    (lambda g: g.insert_rays([0, 0, 0], [1.0], [0.0], np.inf), ValueError, "max_range"),
    (lambda g: g.insert_cone_scan([0, 0, 0], [1.0], [0.0], -1, 0.1, 0.1, 1, -1), ValueError, "z_max"),
    (lambda g: g.insert_cone_scan([0, 0, 0], [1.0], [0.0], 5, 0.1, -0.1, 1, -1), ValueError, "beta"),
    (lambda g: g.insert_cone_scan([0, 0, np.inf], [1.0], [0.0], 5, 0.1, 0.1, 1, -1), ValueError, "pose"),
    (lambda g: g.insert_scans(np.zeros((2, 3)), np.ones((3, 4)), np.zeros(4), 5.0), ValueError, "ranges"),
    (lambda g: g.insert_scans(np.zeros((2, 3)), np.ones((2, 4)), np.zeros(5), 5.0), ValueError, "angles"),
    (lambda g: g.clear_footprint([0, 0, 0], -1.0), ValueError, "radius"),
    (lambda g: g.grown((1, 0, 0, 1)), ValueError, "xmin"),
    (lambda g: ps.fuse_max([]), ValueError, "grids"),
    (lambda g: ps.fuse_max([g, ps.OccupancyGrid2D(0.2, 10, 10)]), ValueError, "grids"),
    (lambda g: ps.inverse_range_sensor_model(np.zeros((3, 3)), [0, 0, 0], [1.0], [0.0], 5, 0.1, 0.1, 0, 1, -1),
     ValueError, "cells_xy"),
])
def test_bad_scan_arguments_raise_and_leave_grid_unchanged(call, err, name):
    grid = ps.OccupancyGrid2D(0.1, 10, 10)
    before = grid.log_odds.copy()
    with pytest.raises(err, match=name):
        call(grid)
    np.testing.assert_array_equal(grid.log_odds, before)


def test_reference_walk_agrees_with_exact_crossing():
    """Sanity check of the pure-Python reference itself on a hand-worked ray."""
    cells = walk((0.05, 0.05), (0.35, 0.25), 0.0, 0.0, 0.1)
    # crossings at t = 1/6 (x), 1/4 (y), 1/2 (x), 3/4 (y); the end cell (3, 2) is excluded
    assert cells == [(0, 0), (1, 0), (1, 1), (2, 1), (2, 2)]


def test_add_log_odds_matches_a_clamped_numpy_loop():
    """add_log_odds against a plain loop: each delta added in order and clamped after each
    (repeated cells accumulate), other cells untouched."""
    grid = ps.OccupancyGrid2D(0.1, 5, 4)  # default clamp
    lo, hi = (float(ps.logit(p)) for p in grid.clamp)  # the clamp is given as probabilities
    rng = np.random.default_rng(2)
    cells = rng.integers(0, 20, 60)
    deltas = rng.normal(0.0, 2.0, 60)
    expected = grid.log_odds.copy().ravel()
    for c, d in zip(cells, deltas):
        expected[c] = min(max(expected[c] + d, lo), hi)
    assert grid.add_log_odds(cells, deltas) == 60
    np.testing.assert_allclose(grid.log_odds.ravel(), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("cells, deltas, err, name", [
    ([0, 20], [0.1, 0.1], ValueError, "cells"),
    ([0, -1], [0.1, 0.1], ValueError, "cells"),
    ([0.0, 1.0], [0.1, 0.1], TypeError, "cells"),
    ([0, 1], [0.1], ValueError, "deltas"),
    ([0, 1], [0.1, np.nan], ValueError, "deltas"),
    ([[0, 1]], [0.1, 0.1], ValueError, "cells"),
])
def test_add_log_odds_refuses_bad_input_and_changes_nothing(cells, deltas, err, name):
    grid = ps.OccupancyGrid2D(0.1, 5, 4)
    before = grid.log_odds.copy()
    with pytest.raises(err, match=f"^{name}"):
        grid.add_log_odds(np.asarray(cells), np.asarray(deltas))
    np.testing.assert_array_equal(grid.log_odds, before)
