"""OccupancyGrid3D from Python: arguments, queries, .bt files. Agreement with OctoMap itself is
checked by the C++ cross-check (tests/cpp/test_octomap_crosscheck.cpp)."""

import bz2

import numpy as np
import pytest

import probslam

# The grid keeps float32 log-odds, as OctoMap does.
FLOAT32_TOL = 1e-6


def ray_cloud(rng, n=2000, extent=4.0):
    return rng.uniform(-extent, extent, size=(n, 3))


def test_defaults_are_octomaps():
    g = probslam.OccupancyGrid3D(0.1)
    assert g.log_odds_hit == pytest.approx(0.847298, abs=FLOAT32_TOL)
    assert g.log_odds_miss == pytest.approx(-0.405465, abs=FLOAT32_TOL)
    lo, hi = g.log_odds_clamp
    assert lo == pytest.approx(-2.000028, abs=FLOAT32_TOL) and hi == pytest.approx(3.511031, abs=FLOAT32_TOL)
    assert g.clamp == (0.1192, 0.971) and g.num_known_voxels == 0


@pytest.mark.parametrize("kwargs, name", [
    (dict(resolution=0.0), "resolution"),
    (dict(resolution=-1.0), "resolution"),
    (dict(resolution=float("nan")), "resolution"),
    (dict(resolution=0.1, p_hit=1.0), "p_hit"),
    (dict(resolution=0.1, p_hit=0.4), "p_hit"),
    (dict(resolution=0.1, p_miss=0.0), "p_miss"),
    (dict(resolution=0.1, p_miss=0.6), "p_miss"),
    (dict(resolution=0.1, clamp=(0.9, 0.2)), "clamp"),
    (dict(resolution=0.1, clamp=(0.12, 1.2)), "clamp"),
    (dict(resolution=0.1, clamp=(0.0, 0.9)), "clamp"),
    (dict(resolution=0.1, clamp=(0.1, 0.5, 0.9)), "clamp"),
    (dict(resolution=0.1, occupancy_threshold=0.0), "occupancy_threshold"),
])
def test_bad_parameters_raise_naming_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        probslam.OccupancyGrid3D(**kwargs)


def test_bad_scan_arguments_raise():
    g = probslam.OccupancyGrid3D(0.1)
    with pytest.raises(ValueError, match="points"):
        g.insert_point_cloud(np.zeros((5, 2)), (0, 0, 0))
    with pytest.raises(ValueError, match="points"):
        g.insert_point_cloud(np.zeros(6), (0, 0, 0))
    with pytest.raises(TypeError, match="points"):
        g.insert_point_cloud(None, (0, 0, 0))
    with pytest.raises(TypeError, match="points"):
        g.insert_point_cloud([["a", "b", "c"]], (0, 0, 0))
    with pytest.raises(ValueError, match="origin"):
        g.insert_point_cloud(np.ones((1, 3)), (0, 0))
    with pytest.raises(ValueError, match="origin"):
        g.insert_point_cloud(np.ones((1, 3)), (0, np.nan, 0))
    with pytest.raises(ValueError, match="max_range"):
        g.insert_point_cloud(np.ones((1, 3)), (0, 0, 0), max_range=float("nan"))
    with pytest.raises(ValueError, match="threads"):
        g.insert_point_cloud(np.ones((1, 3)), (0, 0, 0), threads=0)
    assert g.num_known_voxels == 0


def test_nonfinite_points_are_skipped_and_counted():
    g = probslam.OccupancyGrid3D(0.1)
    pts = np.array([[1.05, 0.05, 0.05], [np.nan, 0, 0], [0, np.inf, 0], [0, 0, -np.inf]])
    stats = g.insert_point_cloud(pts, (0.05, 0.05, 0.05))
    assert stats.points == 4 and stats.skipped_nonfinite == 3
    assert g.num_known_voxels == 11  # the one finite ray: 10 free voxels and its hit
    assert g.log_odds_at((1.05, 0.05, 0.05)) == pytest.approx(g.log_odds_hit)


def test_float32_input_is_used_in_place_and_equals_float64():
    rng = np.random.default_rng(0)
    pts = ray_cloud(rng)
    a, b = probslam.OccupancyGrid3D(0.1), probslam.OccupancyGrid3D(0.1)
    a.insert_point_cloud(pts, (0.1, 0.2, 0.3), max_range=3.0)
    b.insert_point_cloud(pts.astype(np.float32), (0.1, 0.2, 0.3), max_range=3.0)
    ca, la = a.known_voxels()
    cb, lb = b.known_voxels()
    assert np.array_equal(ca, cb) and np.array_equal(la, lb)


def test_threads_give_an_identical_map():
    rng = np.random.default_rng(1)
    one, two = probslam.OccupancyGrid3D(0.1), probslam.OccupancyGrid3D(0.1)
    for s in range(3):
        pts = ray_cloud(rng, 20000, 6.0)
        one.insert_point_cloud(pts, (0.3 * s, 0, 0), max_range=5.0)
        two.insert_point_cloud(pts, (0.3 * s, 0, 0), max_range=5.0, threads=2)
    c1, l1 = one.known_voxels()
    assert np.array_equal(l1, two.log_odds_at(c1)) and two.num_known_voxels == one.num_known_voxels


def test_queries():
    g = probslam.OccupancyGrid3D(0.1)
    g.insert_point_cloud([[2.05, 0.05, 0.05], [0.05, 2.05, 0.05]], (0.05, 0.05, 0.05))
    centres, lo = g.occupied_voxels()
    assert centres.shape == (2, 3) and lo.dtype == np.float32
    assert g.is_occupied(centres).all()
    assert np.isnan(g.log_odds_at([[9.0, 9.0, 9.0]])).all()
    assert not g.is_occupied((9.0, 9.0, 9.0))
    hit = g.cast_ray((0.05, 0.05, 0.05), (1, 0, 0), 10.0)
    assert hit == pytest.approx([2.05, 0.05, 0.05])
    assert g.cast_ray((0.05, 0.05, 0.05), (0, 0, 1), 10.0) is None
    with pytest.raises(ValueError, match="direction"):
        g.cast_ray((0, 0, 0), (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="points"):
        g.log_odds_at(np.zeros((3, 4)))
    known, _ = g.known_voxels()
    assert len(known) == g.num_known_voxels and g.memory_bytes > 0


def test_projection_into_a_2d_grid():
    g = probslam.OccupancyGrid3D(0.1)
    g.insert_point_cloud([[2.05, 0.05, 1.05]], (0.05, 0.05, 1.05))
    flat = g.project_2d(0.0, 2.0)
    assert isinstance(flat, probslam.OccupancyGrid2D) and flat.resolution == 0.1
    row, col = flat.cell_of([[2.05, 0.05]])[0]
    assert flat.log_odds[row, col] == pytest.approx(g.log_odds_hit)
    assert (flat.log_odds < 0).sum() == 20  # the ray's free voxels


def test_bt_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    g = probslam.OccupancyGrid3D(0.2)
    for _ in range(3):
        g.insert_point_cloud(ray_cloud(rng), (0.1, 0.1, 0.1))
    path = tmp_path / "map.bt"
    assert g.write_bt(str(path)) > 0
    assert path.read_bytes().startswith(b"# Octomap OcTree binary file\n")
    r = probslam.OccupancyGrid3D.read_bt(str(path))
    assert r.resolution == 0.2 and r.num_known_voxels == g.num_known_voxels
    centres, lo = g.known_voxels()
    expected = np.where(lo >= 0, r.log_odds_clamp[1], r.log_odds_clamp[0]).astype(np.float32)
    assert np.array_equal(r.log_odds_at(centres), expected)
    # pathlib paths as well as strings, both ways
    assert g.write_bt(tmp_path / "again.bt") > 0
    assert probslam.OccupancyGrid3D.read_bt(tmp_path / "again.bt").num_known_voxels == g.num_known_voxels


@pytest.mark.parametrize("content", [
    b"",
    b"not an octree\n",
    b"# Octomap OcTree binary file\nid OcTree\nsize 3\nres 0.1\ndata\n\x03",
    b"# Octomap OcTree binary file\nid OcTree\nsize 3\nres 0.1\ndata\n" + b"\x03\x00" * 20,
    b"# Octomap OcTree binary file\nid ColorOcTree\nsize 1\nres 0.1\ndata\n\x00\x00",
    b"# Octomap OcTree binary file\nid OcTree\nsize 1\nres abc\ndata\n\x00\x00",
])
def test_corrupt_bt_raises(tmp_path, content):
    path = tmp_path / "bad.bt"
    path.write_bytes(content)
    with pytest.raises(ValueError):
        probslam.OccupancyGrid3D.read_bt(str(path))


def test_missing_bt_raises(tmp_path):
    with pytest.raises(FileNotFoundError, match="none.bt"):
        probslam.OccupancyGrid3D.read_bt(str(tmp_path / "none.bt"))


def test_octomap_sample_data(shared_data):
    folder = shared_data / "scans_3d" / "octomap_samples"
    if not (folder / "scan.dat.bz2").exists():
        pytest.skip("OctoMap sample data not present")
    pts = np.loadtxt(bz2.open(folder / "scan.dat.bz2", "rt"), dtype=np.float32)
    assert pts.shape == (88206, 3)
    g = probslam.OccupancyGrid3D(0.2)
    stats = g.insert_point_cloud(pts, (0, 0, 0), max_range=15.0)
    assert stats.skipped_nonfinite == 0 and stats.max_range_cut > 0
    assert g.num_occupied_voxels > 1000
    geb = probslam.OccupancyGrid3D.read_bt(str(folder / "geb079.bt"))
    assert geb.resolution == 0.08 and geb.num_occupied_voxels > 10000
