"""The reliability policy (docs/reliability.md, issue 12) for the 2-D and 3-D occupancy grids:
threads, worker-thread limits, bounded walks, bounded sizes, all-or-nothing updates, cell indices
that never wrap, and property tests of the whole public grid API."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import policy
import probslam as ps
from reference import cone_update, rays_update

# The public grid calls the property tests below exercise (cited by docs/reliability.md's table).
COVERED = (
    "OccupancyGrid2D(resolution, width, height, origin, p_prior, clamp, p_hit, p_miss)",
    "OccupancyGrid2D.covering",
    "OccupancyGrid2D.insert_rays",
    "OccupancyGrid2D.insert_scans",
    "OccupancyGrid2D.insert_cone_scan",
    "OccupancyGrid2D.clear_footprint",
    "OccupancyGrid2D.cell_of",
    "OccupancyGrid2D.probability",
    "OccupancyGrid2D.grown",
    "fuse_max",
    "OccupancyGrid3D(resolution, p_hit, p_miss, clamp, occupancy_threshold)",
    "OccupancyGrid3D.insert_point_cloud",
    "OccupancyGrid3D.log_odds_at",
    "OccupancyGrid3D.is_occupied",
    "OccupancyGrid3D.cast_ray",
    "OccupancyGrid3D.project_2d",
)

PROPERTY = policy.PROPERTY
HIT, MISS = ps.logit(0.7), ps.logit(0.4)


class VoxelMap:
    """Every known voxel's centre and log-odds, sorted by centre: equal maps compare equal
    whatever their block order."""

    def __init__(self, grid):
        centres, values = grid.known_voxels()
        order = np.lexsort(centres.T[::-1])
        self.centres, self.values = centres[order], values[order]

    def __eq__(self, other):
        return np.array_equal(self.centres, other.centres) and np.array_equal(self.values, other.values)

    def __repr__(self):
        return f"VoxelMap({len(self.values)} voxels)"


def voxel_map(grid):
    return VoxelMap(grid)


def cloud(rng, n, centre, spread):
    return np.asarray(centre) + rng.uniform(-spread, spread, size=(n, 3))


# --- Threads -------------------------------------------------------------------------------------

def test_3d_two_threads_on_one_grid_equal_the_serial_inserts():
    """Two overlapping scans on a fresh grid commute exactly (one update each per voxel, all sums
    inside the clamp, float addition commutative), so any serialisation equals the serial map."""
    rng = np.random.default_rng(3)
    for round_ in range(6):
        a, b = cloud(rng, 3000, (0, 0, 0), 3.0), cloud(rng, 3000, (0.5, 0, 0), 3.0)
        oa, ob = (0.05, 0.05, 0.05), (0.55, 0.15, 0.05)
        serial, reverse = ps.OccupancyGrid3D(0.1), ps.OccupancyGrid3D(0.1)
        serial.insert_point_cloud(a, oa)
        serial.insert_point_cloud(b, ob)
        reverse.insert_point_cloud(b, ob)
        reverse.insert_point_cloud(a, oa)
        assert voxel_map(serial) == voxel_map(reverse)  # the premise of the check
        shared = ps.OccupancyGrid3D(0.1)
        errors = policy.run_threads([lambda: shared.insert_point_cloud(a, oa, threads=1 + round_ % 2),
                                     lambda: shared.insert_point_cloud(b, ob, threads=2)])
        assert errors == []
        assert voxel_map(shared) == voxel_map(serial)
        assert shared.num_known_voxels == serial.num_known_voxels


def test_3d_many_inserts_from_two_threads_equal_the_serial_map():
    """Two threads insert overlapping scans many times. Every point lies beyond max_range, so a
    scan only clears: each voxel's value depends only on how many scans crossed it, not on their
    order, and the map must equal the serial one exactly."""
    rng = np.random.default_rng(4)

    def far_cloud(n):  # directions to points 4-6 m away, cut at max_range 3 m
        d = rng.normal(size=(n, 3))
        return d / np.linalg.norm(d, axis=1)[:, None] * rng.uniform(4, 6, (n, 1))

    left = [far_cloud(3000) + (-0.5, 0, 0) for _ in range(12)]
    right = [far_cloud(3000) + (0.5, 0, 0) for _ in range(12)]
    serial, shared = ps.OccupancyGrid3D(0.1), ps.OccupancyGrid3D(0.1)
    for pts in left:
        serial.insert_point_cloud(pts, (-0.5, 0, 0), max_range=3.0)
    for pts in right:
        serial.insert_point_cloud(pts, (0.5, 0, 0), max_range=3.0)

    def run(clouds, origin, threads):
        return lambda: [shared.insert_point_cloud(p, origin, max_range=3.0, threads=threads) for p in clouds]

    assert policy.run_threads([run(left, (-0.5, 0, 0), 2), run(right, (0.5, 0, 0), 1)]) == []
    assert voxel_map(shared) == voxel_map(serial)
    assert shared.num_known_voxels == serial.num_known_voxels


def test_3d_queries_during_inserts_see_consistent_maps():
    rng = np.random.default_rng(5)
    clouds = [cloud(rng, 2000, (0, 0, 0), 3.0) for _ in range(10)]
    grid, serial = ps.OccupancyGrid3D(0.1), ps.OccupancyGrid3D(0.1)
    for pts in clouds:
        serial.insert_point_cloud(pts, (0.05, 0.05, 0.05))
    lo, hi = grid.log_odds_clamp
    seen_counts = []
    probes = rng.uniform(-3, 3, size=(500, 3))

    def insert():
        for pts in clouds:
            grid.insert_point_cloud(pts, (0.05, 0.05, 0.05), threads=2)

    def query():
        for _ in range(40):
            centres, values = grid.known_voxels()
            assert len(centres) == len(values)
            assert np.all((values >= lo) & (values <= hi))
            seen_counts.append(len(values))
            l = grid.log_odds_at(probes)
            assert np.all(np.isnan(l) | ((l >= lo) & (l <= hi)))
            grid.is_occupied(probes)
            grid.cast_ray((0.05, 0.05, 0.05), (1, 0.3, 0.1), 1e3)
            grid.project_2d(-1.0, 1.0)
            assert grid.num_known_voxels >= 0 and grid.memory_bytes > 0

    assert policy.run_threads([insert, query]) == []
    assert seen_counts == sorted(seen_counts)  # inserts only ever add known voxels
    assert voxel_map(grid) == voxel_map(serial)


def test_2d_insert_rays_and_scans_from_two_threads_equal_the_serial_map():
    """Two threads scan disjoint halves of one grid (rays never reach the other half) with
    insert_rays and insert_scans, many times: the map equals the serial one exactly."""
    rng = np.random.default_rng(6)
    angles = np.linspace(-np.pi, np.pi, 720, endpoint=False)

    def scans(x0):
        poses = np.column_stack([rng.uniform(x0 - 1, x0 + 1, 8), rng.uniform(4, 6, 8), rng.uniform(-3, 3, 8)])
        return poses, rng.uniform(0.5, 2.5, (8, 720))

    work = {"left": [scans(5.0) for _ in range(10)], "right": [scans(15.0) for _ in range(10)]}

    def apply(grid, batches):
        for k, (poses, ranges) in enumerate(batches):
            if k % 2:
                grid.insert_scans(poses, ranges, angles, 3.0)
            else:
                for p, r in zip(poses, ranges):
                    grid.insert_rays(p, r, angles, 3.0)

    serial = ps.OccupancyGrid2D(0.01, 2000, 1000)
    apply(serial, work["left"])
    apply(serial, work["right"])
    shared = ps.OccupancyGrid2D(0.01, 2000, 1000)
    errors = policy.run_threads([lambda: apply(shared, work["left"]), lambda: apply(shared, work["right"])])
    assert errors == []
    np.testing.assert_array_equal(shared.log_odds, serial.log_odds)


def test_2d_reads_during_updates_see_whole_scans():
    """Each insert_rays adds one miss to every cell of row 0 (clamp off): a copy, fusion, growth
    or probability taken while another thread updates must see a whole number of scans, i.e. a
    constant row, never a scan half applied."""
    grid = ps.OccupancyGrid2D(0.1, 200000, 1, clamp=None)
    row = lambda log_odds: np.asarray(log_odds)[0, :200000]  # noqa: E731
    seen = []

    def update():
        for _ in range(50):
            grid.insert_rays((0.05, 0.05, 0.0), [30000.0], [0.0], 30000.0)

    def read():
        for _ in range(50):
            seen.append(row(grid.copy().log_odds))
            seen.append(row(ps.fuse_max([grid, grid]).log_odds))
            seen.append(row(grid.grown((-1.0, 0.0, 20000.0, 0.1)).log_odds)[10:])
            seen.append(ps.logit(row(grid.probability())))

    assert policy.run_threads([update, read]) == []
    for r in seen:
        np.testing.assert_allclose(r, r[0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(row(grid.log_odds), 50 * MISS, rtol=1e-12)
    assert grid.cell_of([[1.0, 0.05]]).tolist() == [[0, 10]] and grid.shape == (1, 200000)

# --- Worker threads ------------------------------------------------------------------------------

def test_thread_count_beyond_the_named_limit_is_refused_before_anything_changes():
    grid = ps.OccupancyGrid3D(0.1)
    pts = np.random.default_rng(7).uniform(-2, 2, (3000, 3))
    with pytest.raises(ValueError, match=r"threads.*256"):
        grid.insert_point_cloud(pts, (0, 0, 0), threads=10**6)
    assert grid.num_known_voxels == 0
    grid.insert_point_cloud(pts, (0, 0, 0), threads=256)  # the limit itself is accepted
    one = ps.OccupancyGrid3D(0.1)
    one.insert_point_cloud(pts, (0, 0, 0))
    assert voxel_map(grid) == voxel_map(one)


@pytest.mark.parametrize("successes", [0, 1, 2])
def test_a_refused_worker_thread_raises_runtime_error_and_leaves_the_grid_unchanged(successes):
    """RLIMIT_NPROC does not bind root (CI), so the failure is injected where threads start."""
    rng = np.random.default_rng(10)
    first, second = rng.uniform(-3, 3, (4000, 3)), rng.uniform(-3, 3, (4000, 3))
    grid, serial = ps.OccupancyGrid3D(0.1), ps.OccupancyGrid3D(0.1)
    grid.insert_point_cloud(first, (0, 0, 0))
    serial.insert_point_cloud(first, (0, 0, 0))
    before = grid3d_state(grid)
    ps._core._fail_worker_thread_start_after(successes)
    try:
        with pytest.raises(RuntimeError, match="worker thread"):
            grid.insert_point_cloud(second, (0, 0, 0), threads=4)
    finally:
        ps._core._fail_worker_thread_start_after(-1)
    assert policy.same_state(grid3d_state(grid), before)
    grid.insert_point_cloud(second, (0, 0, 0), threads=4)  # no stale per-scan marks
    serial.insert_point_cloud(second, (0, 0, 0))
    assert voxel_map(grid) == voxel_map(serial)


# --- Bounded walks -------------------------------------------------------------------------------

def first_occupied_brute_force(grid, origin, direction, max_range):
    """Centre of the occupied voxel whose box the ray enters first (exact slab test over all
    occupied voxels), or None: an independent reference for cast_ray."""
    centres, _ = grid.occupied_voxels()
    h = grid.resolution / 2
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    o = np.asarray(origin, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (centres - h - o) / d, (centres + h - o) / d
    near = np.where(d == 0, np.where((o >= centres - h) & (o < centres + h), -np.inf, np.inf), np.minimum(a, b))
    far = np.where(d == 0, np.where((o >= centres - h) & (o < centres + h), np.inf, -np.inf), np.maximum(a, b))
    t0, t1 = np.max(near, axis=1), np.min(far, axis=1)
    hit = (t0 < t1) & (t1 > 0) & (t0 <= max_range)
    if not hit.any():
        return None
    return centres[np.argmin(np.where(hit, np.maximum(t0, 0), np.inf))]


def test_cast_ray_with_a_huge_max_range_is_clipped_to_the_key_range():
    grid = ps.OccupancyGrid3D(0.1)
    grid.insert_point_cloud([[2.05, 0.05, 0.05], [0.05, 2.05, 0.05]], (0.05, 0.05, 0.05))
    assert grid.cast_ray((0.05, 0.05, 0.05), (1, 0, 0), 1e12) == pytest.approx([2.05, 0.05, 0.05])
    assert grid.cast_ray((0.05, 0.05, 0.05), (0, 0, 1), 1e12) is None
    assert grid.cast_ray((0.05, 0.05, 0.05), (0, 0, 1), 1e308) is None
    assert grid.cast_ray((0.05, 0.05, 0.05), (0, 1, 0), np.finfo(float).max) == pytest.approx([0.05, 2.05, 0.05])


def test_cast_ray_agrees_with_short_rays_and_a_brute_force_reference():
    rng = np.random.default_rng(8)
    grid = ps.OccupancyGrid3D(0.1)
    for _ in range(3):
        grid.insert_point_cloud(rng.uniform(-3, 3, (400, 3)), rng.uniform(-0.5, 0.5, 3))
    for _ in range(150):
        origin = rng.uniform(-3, 3, 3)
        direction = rng.normal(size=3)
        short = grid.cast_ray(origin, direction, 12.0)
        far = grid.cast_ray(origin, direction, 1e12)
        expected = first_occupied_brute_force(grid, origin, direction, 12.0)
        if expected is None:
            assert short is None
            assert far is None or np.linalg.norm(far - origin) > 12.0
        else:
            np.testing.assert_allclose(short, expected, atol=1e-9)
            np.testing.assert_allclose(far, expected, atol=1e-9)


def test_cast_ray_from_outside_the_key_range_enters_it():
    """The key range at 0.1 m is +-3276.8 m: a ray from 5 km away walks from where it enters."""
    grid = ps.OccupancyGrid3D(0.1)
    grid.insert_point_cloud([[2.05, 0.05, 0.05]], (0.05, 0.05, 0.05))
    for origin, direction in [((5000.0, 0.05, 0.05), (-1, 0, 0)), ((-5000.0, 0.05, 0.05), (1, 0, 0)),
                              ((5000.0, 5000.0, 0.05), (-1, -1, 0)), ((1e12, 0.05, 0.05), (-1, 0, 0))]:
        expected = first_occupied_brute_force(grid, origin, direction, 2e12)
        hit = grid.cast_ray(origin, direction, 2e12)
        if expected is None:
            assert hit is None
        else:
            np.testing.assert_allclose(hit, expected, atol=1e-9)
    assert grid.cast_ray((5000.0, 0.05, 0.05), (1, 0, 0), 1e12) is None  # pointing away


def test_2d_rays_that_never_enter_the_grid_cost_nothing():
    """Before clipping, each of these rays was walked cell by cell for 5e7 cells (minutes)."""
    grid = ps.OccupancyGrid2D(0.1, 10, 10)
    angles = np.linspace(np.pi / 2 + 0.1, np.pi - 0.1, 100)  # up and left, away from the grid
    assert grid.insert_rays((-100.0, 100.0, 0.0), np.full(100, 5e6), angles, 1e7) == 0
    assert grid.insert_scans(np.array([[-100.0, 100.0, 0.0]] * 3), np.full((3, 100), 5e6), angles, 1e7) == 0
    assert grid.insert_cone_scan((-100.0, 100.0, 0.0), np.full(100, 5e6), angles, 1e7, 0.2, 0.05, 1.0, -1.0) == 0
    assert np.all(grid.log_odds == 0.0)


def test_2d_huge_max_range_is_walked_only_inside_the_grid():
    grid = ps.OccupancyGrid2D(0.1, 40, 10)
    # Refused before as "spans too many cells": now the ray is cut at the grid's edge.
    assert grid.insert_rays((0.05, 0.55, 0.0), [1e11], [0.0], 1e12) == 40
    assert np.all(grid.log_odds[5] == MISS) and np.count_nonzero(grid.log_odds) == 40
    same = ps.OccupancyGrid2D(0.1, 40, 10)
    same.insert_rays((0.05, 0.55, 0.0), [50.0], [0.0], 60.0)
    np.testing.assert_array_equal(grid.log_odds, same.log_odds)
    assert grid.insert_rays((0.05, 0.55, 0.0), [1e300], [1.0], np.finfo(float).max) > 0
    assert np.all(np.isfinite(grid.log_odds))


@pytest.mark.parametrize("seed", range(4))
def test_2d_clipped_walks_equal_the_unclipped_reference(seed):
    """Sensors up to 60 m outside the grid, rays entering, crossing and missing it: equal to the
    pure-Python reference that walks every ray from the sensor, cell by cell."""
    rng = np.random.default_rng(200 + seed)
    grid = ps.OccupancyGrid2D(0.1, 60, 40, origin=(-3.0, -2.0), clamp=None)
    expected = grid.log_odds.copy()
    for _ in range(3):
        side = rng.integers(4)
        far = rng.uniform(5, 60)
        pose = [(-3 - far, rng.uniform(-3, 3)), (3 + far, rng.uniform(-3, 3)),
                (rng.uniform(-4, 4), -2 - far), (rng.uniform(-4, 4), 2 + far)][side]
        centre_bearing = math.atan2(-pose[1], -pose[0])
        pose = np.array([pose[0], pose[1], centre_bearing])
        angles = rng.uniform(-0.3, 0.3, 60)
        ranges = rng.uniform(far - 2, far + 8, 60)
        grid.insert_rays(pose, ranges, angles, far + 6)
        expected = rays_update(expected, grid.origin, 0.1, pose, ranges, angles, far + 6)
        np.testing.assert_array_equal(grid.log_odds, expected)


def test_3d_points_beyond_the_key_range_are_dropped_at_once():
    grid = ps.OccupancyGrid3D(0.1)
    stats = grid.insert_point_cloud([[1e12, 0, 0], [0, -1e12, 3], [1.05, 0.05, 0.05]], (0.05, 0.05, 0.05))
    assert stats.out_of_bounds == 2 and grid.num_known_voxels == 11


# --- Bounded sizes -------------------------------------------------------------------------------

def test_project_2d_of_distant_voxels_is_refused_before_allocating():
    grid = ps.OccupancyGrid3D(0.1)
    for p in ([3000.0, 3000.0, 0.0], [-3000.0, -3000.0, 0.0]):
        grid.insert_point_cloud([p], p)  # a hit only: the point is its own origin
    assert grid.num_known_voxels == 2
    with pytest.raises(ValueError, match=r"max_cells"):
        grid.project_2d(-1.0, 1.0)
    assert grid.num_known_voxels == 2


@pytest.mark.parametrize("make", [
    lambda: ps.OccupancyGrid2D(0.1, 60000, 60000),
    lambda: ps.OccupancyGrid2D.covering((0, 0, 6000, 6000), 0.1),
    lambda: ps.OccupancyGrid2D(0.1, 10, 10).grown((-3000, -3000, 3000, 3000)),
    lambda: ps.OccupancyGrid2D(1e-300, 10, 10),
    lambda: ps.OccupancyGrid2D(1e307, 100, 10),
    lambda: ps.OccupancyGrid2D(1e-3, 10, 10, origin=(1e12, 0)),
])
def test_grids_sized_beyond_the_named_limit_are_refused(make):
    with pytest.raises(ValueError, match=r"max_cells|resolution|origin"):
        make()


def test_the_cell_limit_is_public_and_the_limit_itself_is_named():
    assert ps.OccupancyGrid2D.max_cells == 2**28
    with pytest.raises(ValueError, match=str(2**28)):
        ps.OccupancyGrid2D(1.0, 2**15, 2**13 + 1)


# --- All or nothing ------------------------------------------------------------------------------

@pytest.mark.parametrize("bad_row", [1, 2])
def test_insert_scans_with_a_bad_pose_applies_no_row(bad_row):
    grid = ps.OccupancyGrid2D(0.1, 50, 50)
    poses = np.array([[2.5, 2.5, 0.0], [2.0, 2.0, 1.0], [3.0, 3.0, 2.0]])
    poses[bad_row, 1] = np.nan
    angles = np.linspace(-1, 1, 20)
    with pytest.raises(ValueError, match="poses"):
        grid.insert_scans(poses, np.full((3, 20), 1.5), angles, 3.0)
    assert np.all(grid.log_odds == 0.0)
    poses[bad_row, 1] = np.inf
    with pytest.raises(ValueError, match="poses"):
        grid.insert_scans(poses, np.full((3, 20), 1.5), angles, 3.0)
    assert np.all(grid.log_odds == 0.0)


# --- Cell indices that never wrap ----------------------------------------------------------------

def test_cell_of_beyond_the_int_range_is_exact_or_refused():
    grid = ps.OccupancyGrid2D(1.0, 10, 10)
    cells = grid.cell_of([[3e9 + 0.5, -5e9 - 0.5], [2.5, 3.5]])
    np.testing.assert_array_equal(cells, [[-5_000_000_001, 3_000_000_000], [3, 2]])
    with pytest.raises(ValueError, match="points"):
        grid.cell_of([[1e300, 0.0]])


def test_footprint_far_beyond_the_int_range_covers_the_grid():
    """Cell indices of +-1e10 overflowed int: the clipped loop was empty and 0 cells changed."""
    grid = ps.OccupancyGrid2D(1.0, 10, 10, clamp=None)
    assert grid.clear_footprint((1e10, 5.0, 0.0), 2e10, l_free=-1.0) == 100
    assert np.all(grid.log_odds == -1.0)


def test_cone_scan_from_beyond_the_int_range_equals_the_dense_reference():
    grid = ps.OccupancyGrid2D(1.0, 10, 10, clamp=None)
    pose = np.array([-3e9, 4.5, 0.0])
    ranges, angles = np.array([3e9 + 6.0]), np.array([0.0])
    params = dict(z_max=1e10, alpha=2.0, beta=1e-9, l_occ=1.0, l_free=-1.0)
    changed = grid.insert_cone_scan(pose, ranges, angles, **params)
    expected = cone_update(np.zeros((10, 10)), grid.origin, 1.0, pose, ranges, angles, l0=0.0, **params)
    assert changed == np.count_nonzero(expected) > 0
    np.testing.assert_array_equal(grid.log_odds, expected)


# --- Property tests ------------------------------------------------------------------------------

def grid2d_state(grid):
    return policy.state_of(grid, "log_odds", "shape", "origin", "clamp", "p_hit", "p_miss")


def grid3d_state(grid):
    centres, values = grid.known_voxels()
    return {"centres": centres, "values": values, "blocks": grid.num_blocks}


def small_grid():
    grid = ps.OccupancyGrid2D(0.1, 30, 20, origin=(-1.0, -1.0))
    grid.insert_rays((0.5, 0.0, 0.3), np.linspace(0.5, 2.0, 12), np.linspace(-1, 1, 12), 3.0)
    return grid


def small_grid3d():
    grid = ps.OccupancyGrid3D(0.1)
    grid.insert_point_cloud(np.random.default_rng(0).uniform(-1, 1, (200, 3)), (0.05, 0.05, 0.05))
    return grid


@PROPERTY
@given(resolution=policy.floats(), width=st.integers(-3, 50) | st.sampled_from([2**31 - 1, 2**31, 2**29]),
       height=st.integers(-3, 50) | st.sampled_from([2**31 - 1, 2**31, 2**29]), origin=policy.arrays(max_side=3),
       p_prior=policy.floats(), clamp=st.none() | policy.arrays(max_side=3))
def test_property_grid2d_constructor(resolution, width, height, origin, p_prior, clamp):
    raised, grid = policy.check_call(lambda: ps.OccupancyGrid2D(resolution, width, height, origin, p_prior, clamp))
    if not raised:
        assert grid.shape == (height, width)
        assert np.all(np.isfinite(grid.cell_centers())) and np.all(np.isfinite(grid.log_odds))


@PROPERTY
@given(bounds=policy.arrays(max_side=5), resolution=policy.floats())
def test_property_covering_and_grown(bounds, resolution):
    raised, grid = policy.check_call(lambda: ps.OccupancyGrid2D.covering(bounds, resolution))
    if not raised:
        assert grid.width * grid.height <= ps.OccupancyGrid2D.max_cells
        assert np.all(np.isfinite(grid.cell_centers()))
    base = small_grid()
    raised, grown = policy.check_call(lambda: base.grown(bounds), snapshot=lambda: grid2d_state(base))
    if not raised:
        assert grown.width >= base.width and grown.height >= base.height
        assert np.all(np.isfinite(grown.log_odds))


@PROPERTY
@given(pose=policy.arrays(), ranges=policy.arrays(max_dims=2), angles=policy.arrays(max_dims=2),
       max_range=policy.floats())
def test_property_insert_rays_and_scans(pose, ranges, angles, max_range):
    grid = small_grid()
    snapshot = lambda: grid2d_state(grid)  # noqa: E731
    policy.check_call(lambda: grid.insert_rays(pose, ranges, angles, max_range), snapshot)
    policy.check_call(lambda: grid.insert_scans(pose, ranges, angles, max_range), snapshot)
    assert np.all(np.isfinite(grid.log_odds))


def near_values():
    """Values around small_grid() (so that updates do change it) mixed with the special ones."""
    return st.one_of(st.floats(-2, 3), st.sampled_from(policy.SPECIAL_FLOATS))


def near_arrays(shape):
    """Arrays of near_values in float64 or float32, C or Fortran order, or as a strided view."""
    def layouts(a):
        with np.errstate(over="ignore"):
            return st.sampled_from([a, np.asfortranarray(a), np.repeat(a, 2, axis=-1)[..., ::2], a.astype(np.float32)])
    return hnp.arrays(np.float64, shape, elements=near_values()).flatmap(layouts)


@settings(max_examples=150, deadline=None)
@given(poses=near_arrays((3, 3)), ranges=near_arrays((3, 4)), angles=near_arrays((4,)),
       max_range=near_values())
@pytest.mark.slow
def test_property_insert_scans_all_or_nothing(poses, ranges, angles, max_range):
    grid = small_grid()
    raised, _ = policy.check_call(lambda: grid.insert_scans(poses, ranges, angles, max_range),
                                  lambda: grid2d_state(grid))
    if not raised:
        assert np.all(np.isfinite(grid.log_odds))


@PROPERTY
@given(pose=policy.arrays(shape=(3,)), ranges=policy.arrays(max_dims=1), angles=policy.arrays(max_dims=1),
       z_max=policy.floats(), alpha=policy.floats(), beta=policy.floats(), l_occ=policy.floats(),
       l_free=policy.floats())
def test_property_insert_cone_scan(pose, ranges, angles, z_max, alpha, beta, l_occ, l_free):
    grid = small_grid()
    policy.check_call(lambda: grid.insert_cone_scan(pose, ranges, angles, z_max, alpha, beta, l_occ, l_free),
                      lambda: grid2d_state(grid))
    assert np.all(np.isfinite(grid.log_odds))


@PROPERTY
@given(pose=policy.arrays(), radius=policy.floats(), l_free=st.none() | policy.floats(),
       points=policy.arrays(max_dims=2) | policy.odd_objects())
def test_property_footprint_and_queries(pose, radius, l_free, points):
    grid = small_grid()
    policy.check_call(lambda: grid.clear_footprint(pose, radius, l_free), lambda: grid2d_state(grid))
    assert np.all(np.isfinite(grid.log_odds))
    raised, cells = policy.check_call(lambda: grid.cell_of(points), lambda: grid2d_state(grid))
    if not raised:
        assert cells.shape == (len(points), 2) and cells.dtype.kind == "i"
    policy.check_call(grid.probability)


@PROPERTY
@given(clamp=st.none() | policy.arrays(shape=(2,)), p_hit=policy.floats(), other=st.sampled_from(["same", "other", "none"]))
def test_property_setters_and_fuse_max(clamp, p_hit, other):
    grid = small_grid()
    snapshot = lambda: grid2d_state(grid)  # noqa: E731
    policy.check_call(lambda: setattr(grid, "clamp", clamp), snapshot)
    policy.check_call(lambda: setattr(grid, "p_hit", p_hit), snapshot)
    partner = {"same": grid, "other": ps.OccupancyGrid2D(0.2, 3, 3), "none": None}[other]
    raised, fused = policy.check_call(lambda: ps.fuse_max([grid, partner]), snapshot)
    assert raised == (other != "same")
    if not raised:
        np.testing.assert_array_equal(fused.log_odds, grid.log_odds)


@PROPERTY
@given(resolution=policy.floats(), p=st.lists(policy.floats(), min_size=5, max_size=5))
def test_property_grid3d_constructor(resolution, p):
    raised, grid = policy.check_call(lambda: ps.OccupancyGrid3D(resolution, p[0], p[1], (p[2], p[3]), p[4]))
    if not raised:
        grid.insert_point_cloud([[1.0, 2.0, 3.0]], (0.0, 0.0, 0.0))
        centres, values = grid.known_voxels()
        assert np.all(np.isfinite(centres)) and np.all(np.isfinite(values))


@PROPERTY
@given(points=policy.arrays(max_dims=2) | policy.odd_objects(), origin=policy.arrays(max_dims=1),
       max_range=policy.floats(), threads=st.integers(-2, 4) | st.sampled_from([257, 2**40]))
def test_property_insert_point_cloud(points, origin, max_range, threads):
    grid = small_grid3d()
    raised, stats = policy.check_call(lambda: grid.insert_point_cloud(points, origin, max_range, threads),
                                      lambda: grid3d_state(grid))
    if not raised:
        assert stats.points == len(points)
        centres, values = grid.known_voxels()
        assert np.all(np.isfinite(centres)) and np.all(np.isfinite(values))


@PROPERTY
@given(points=policy.arrays(max_dims=2) | policy.odd_objects(), origin=policy.arrays(max_dims=1),
       direction=policy.arrays(max_dims=1), max_range=policy.floats(), z=st.tuples(policy.floats(), policy.floats()))
def test_property_grid3d_queries(points, origin, direction, max_range, z):
    grid = small_grid3d()
    snapshot = lambda: grid3d_state(grid)  # noqa: E731
    raised, values = policy.check_call(lambda: grid.log_odds_at(points), snapshot, finite=False)
    if not raised:  # NaN means unknown; a known voxel's log-odds is finite
        assert np.all(np.isnan(values) | np.isfinite(values))
    policy.check_call(lambda: grid.is_occupied(points), snapshot)
    policy.check_call(lambda: grid.cast_ray(origin, direction, max_range), snapshot)
    raised, flat = policy.check_call(lambda: grid.project_2d(*z), snapshot)
    if not raised:
        assert np.all(np.isfinite(flat.log_odds)) and np.all(np.isfinite(flat.cell_centers()))


# --- map_laser_log -------------------------------------------------------------------------------

def laser_scans(n=5, beams=30):
    from probslam.io.carmen import LaserScans
    rng = np.random.default_rng(9)
    poses = np.column_stack([np.linspace(0, 2, n), np.zeros(n), np.zeros(n)])
    return LaserScans(ranges=rng.uniform(1, 3, (n, beams)), laser_poses=poses, robot_poses=poses.copy(),
                      start_angles=np.full(n, -np.pi / 2), angular_resolutions=np.full(n, np.pi / beams),
                      max_ranges=np.full(n, np.nan), num_beams=np.full(n, beams), timestamps=np.arange(n, dtype=float))


@pytest.mark.parametrize("field, row, name", [("laser_poses", 4, "laser_poses"), ("robot_poses", 3, "robot_poses"),
                                              ("start_angles", 4, "start_angles")])
def test_map_laser_log_checks_every_scan_before_mapping(field, row, name):
    scans = laser_scans()
    given = ps.OccupancyGrid2D(0.1, 10, 10)
    before = given.log_odds.copy()
    getattr(scans, field)[row] = np.nan
    with pytest.raises(ValueError, match=name):
        ps.map_laser_log(scans, resolution=0.1, robot_radius=0.3, grid=given, chunk=2, progress=False)
    np.testing.assert_array_equal(given.log_odds, before)
    good = laser_scans()
    summary = ps.map_laser_log(good, resolution=0.1, robot_radius=0.3, chunk=2, progress=False)
    grid = summary.grid
    assert summary.scans == 5 and np.all(np.isfinite(grid.log_odds))


# --- Finite log-odds -----------------------------------------------------------------------------

@pytest.mark.parametrize("update, name", [
    (lambda g, l: g.insert_cone_scan((0.55, 0.55, 0.0), [0.3], [0.0], 1.0, 0.1, 0.5, l, -1.0), "l_occ"),
    (lambda g, l: g.insert_cone_scan((0.55, 0.55, 0.0), [0.3], [0.0], 1.0, 0.1, 0.5, 1.0, -l), "l_free"),
    (lambda g, l: g.clear_footprint((0.5, 0.5, 0.0), 0.3, l_free=-l), "l_free"),
])
def test_unclamped_updates_cannot_overflow_to_inf(update, name):
    """Two updates by 1e308 made an unclamped cell inf; such model values are refused by name."""
    grid = ps.OccupancyGrid2D(0.1, 10, 10, clamp=None)
    with pytest.raises(ValueError, match=name):
        update(grid, 1e308)
    assert np.all(grid.log_odds == 0.0)
    for _ in range(2):
        update(grid, 1e6)  # the limit itself is accepted
    assert np.all(np.isfinite(grid.log_odds)) and np.abs(grid.log_odds).max() == 2e6
