"""Save / load and pickle of every stateful class (docs/file_format.md): round trips are bit for
bit (np.array_equal, not allclose), a run saved part way and resumed equals one that never
stopped, and damaged files are refused naming the path."""

import dataclasses
import gzip
import pickle

import numpy as np
import pytest

import probslam as ps
from probslam import _core, cli, io
from probslam.ekf import EkfSlam, MultiHypothesisEkfSlam
from probslam.slam import default_options, load_run, run_slam
from probslam.data import path as data_path

LANDMARKS = np.array([[6 * np.cos(0.5 * k), 6 * np.sin(0.5 * k)] for k in range(12)])


def scans(steps, seed=11):
    """(pose, z, ids) of a robot circling inside a ring of landmarks, with measurement noise."""
    rng = np.random.default_rng(seed)
    out = []
    for t in range(steps):
        x = np.array([3 * np.cos(0.1 * t), 3 * np.sin(0.1 * t), 0.1 * t + np.pi / 2])
        d = LANDMARKS - x[:2]
        r = np.hypot(d[:, 0], d[:, 1])
        b = np.arctan2(d[:, 1], d[:, 0]) - x[2]
        b = (b + np.pi) % (2 * np.pi) - np.pi
        seen = r < 7.0
        z = np.column_stack([r[seen] + rng.normal(0, 0.05, seen.sum()), b[seen] + rng.normal(0, 0.005, seen.sum())])
        out.append((z, np.flatnonzero(seen)))
    return out


def state_bytes(obj) -> bytes:
    """The C++ state of obj (the Python EKF classes wrap theirs)."""
    s = obj.__getstate__()
    return s if isinstance(s, bytes) else next(iter(s.values())).__getstate__()


def round_trip(obj, cls, tmp_path):
    """pickle and save/load give objects whose state bytes equal obj's."""
    before = state_bytes(obj)
    p = tmp_path / "state.psl"
    obj.save(p)
    a = cls.load(p)
    b = pickle.loads(pickle.dumps(obj))
    assert state_bytes(a) == before and state_bytes(b) == before
    # A damaged file is refused naming the path; obj is unchanged.
    data = p.read_bytes()
    for bad, what in [(data[:len(data) // 2], "truncated"), (data[:-1] + bytes([data[-1] ^ 1]), "checksum"),
                      (b"nonsense", "not a probslam state file")]:
        p.write_bytes(bad)
        with pytest.raises(ValueError, match=what) as e:
            cls.load(p)
        assert str(e.value).startswith(str(p))
    with pytest.raises(FileNotFoundError):
        cls.load(tmp_path / "missing.psl")
    with pytest.raises(TypeError, match="path"):
        obj.save(3)
    assert state_bytes(obj) == before
    return a


def test_incremental_scan_matcher_resumed_equals_uninterrupted(tmp_path):
    """A scan matcher saved part way and loaded (its likelihood field cache included) matches the
    remaining scans as the one that never stopped, bit for bit; a copy does too."""
    from test_incremental_scan_matching import ANGLES, drive
    true, odo, ranges = drive(40)
    t = np.arange(len(true), dtype=float)

    def make():
        return ps.IncrementalScanMatcher(filter={"max_range": 30.0}, submap_distance=2.0)

    straight = make()
    straight.add_scans(ranges, ANGLES, odo, t)
    first = make()
    first.add_scans(ranges[:20], ANGLES, odo[:20], t[:20])
    twin = first.copy()
    resumed = round_trip(first, ps.IncrementalScanMatcher, tmp_path)
    for m in (resumed, twin):
        m.add_scans(ranges[20:], ANGLES, odo[20:], t[20:])
        assert state_bytes(m) == state_bytes(straight)
        assert np.array_equal(m.scan_poses, straight.scan_poses) and m.num_submaps == straight.num_submaps > 1


def test_grid_and_graph_round_trip(tmp_path):
    g = ps.OccupancyGrid2D(0.1, 40, 30, origin=(-2.0, -1.5))
    g.insert_rays(np.array([0.1, 0.2, 0.3]), np.full(90, 1.2), np.linspace(-1.5, 1.5, 90), 3.0)
    h = round_trip(g, ps.OccupancyGrid2D, tmp_path)
    assert np.array_equal(h.log_odds, g.log_odds) and h.same_geometry(g)
    graph = ps.read_pose_graph(ps.data.path("intel_400.g2o"))
    ps.optimize(graph)
    h = round_trip(graph, ps.PoseGraph2D, tmp_path)
    assert np.array_equal(h.poses, graph.poses) and np.array_equal(h.pose_ids, graph.pose_ids)
    assert h.chi2() == graph.chi2()
    # The wrong class is refused by name.
    g.save(tmp_path / "grid.psl")
    with pytest.raises(ValueError, match="holds a OccupancyGrid2D, not a PoseGraph2D"):
        ps.PoseGraph2D.load(tmp_path / "grid.psl")


def fastslam_steps(f, data, known, start=0):
    for t, (z, ids) in enumerate(data):
        if t < start:
            continue
        f.predict(0.3, 0.1, 1.0)
        f.predict(0.05, 0.0, 1.0)
        if t % 3 == 2:
            continue  # no update: version 2's prior composes over several moves
        if known:
            f.update(z, ids)
        else:
            f.update_unknown(z)


@pytest.mark.parametrize("version", [1, 2])
@pytest.mark.parametrize("known", [True, False])
def test_fastslam_resumed_equals_uninterrupted(tmp_path, version, known):
    data = scans(30)
    make = lambda: ps.FastSlam(np.diag([0.01, 0.01, 0.002]), np.diag([0.0025, 0.0001]), num_particles=20,
                               version=version, seed=3)
    straight, first = make(), make()
    fastslam_steps(straight, data, known)
    fastslam_steps(first, data[:14], known)
    resumed = round_trip(first, ps.FastSlam, tmp_path)
    fastslam_steps(resumed, data, known, start=14)
    assert resumed.__getstate__() == straight.__getstate__()
    assert np.array_equal(resumed.poses, straight.poses) and np.array_equal(resumed.log_weights, straight.log_weights)
    for k in range(straight.num_particles):
        assert np.array_equal(resumed.path(k), straight.path(k))
        a, b = resumed.landmarks(k), straight.landmarks(k)
        assert np.array_equal(a.ids, b.ids) and np.array_equal(a.means, b.means) and np.array_equal(a.covariances, b.covariances)


def resumed_run(make, cls, step, data, tmp_path):
    """(a filter saved after scan 10, loaded and run on; one run straight through; the saved one):
    each scan z is predict(0.3, 0.1, 1.0), then step(filter, z)."""
    straight, first = make(), make()
    for f, part in ((straight, data), (first, data[:10])):
        for z, _ in part:
            f.predict(0.3, 0.1, 1.0)
            step(f, z)
    out = round_trip(first, cls, tmp_path)
    for z, _ in data[10:]:
        out.predict(0.3, 0.1, 1.0)
        step(out, z)
    return out, straight, first


def ekf_resumed(make, data, tmp_path):
    return resumed_run(make, EkfSlam, lambda f, z: f.update_unknown(z), data, tmp_path)


def test_ekf_and_mht_resumed_equal_uninterrupted(tmp_path):
    data = scans(24)
    make = lambda: EkfSlam(np.diag([0.01, 0.01, 0.002]), np.diag([0.0025, 0.0001]), initial_pose=(3, 0, np.pi / 2))
    resumed, straight, _ = ekf_resumed(make, data, tmp_path)
    assert np.array_equal(resumed.mean, straight.mean) and np.array_equal(resumed.covariance, straight.covariance)

    mht, straight, _ = resumed_run(lambda: MultiHypothesisEkfSlam(make()), MultiHypothesisEkfSlam,
                                   lambda f, z: f.update(z), data, tmp_path)
    assert np.array_equal(mht.costs, straight.costs) and np.array_equal(mht.best.mean, straight.best.mean)
    assert state_bytes(mht) == state_bytes(straight)


def test_ekf_with_signatures_resumed_equals_uninterrupted(tmp_path):
    """The signatures, kept apart from the dense state, travel with the file."""
    data = [(np.column_stack([z, 0.3 + 0.01 * ids]), ids) for z, ids in scans(24)]
    make = lambda: EkfSlam(np.diag([0.01, 0.01, 0.002]), np.diag([0.0025, 0.0001, 0.01]), use_signatures=True,
                           initial_pose=(3, 0, np.pi / 2))
    resumed, straight, first = ekf_resumed(make, data, tmp_path)
    assert len(first.signatures) == first.num_landmarks > 0
    assert state_bytes(resumed) == state_bytes(straight)
    assert np.array_equal(resumed.signatures, straight.signatures)


def head(log_scans, n):
    return dataclasses.replace(log_scans, **{f.name: getattr(log_scans, f.name)[:n]
                                             for f in dataclasses.fields(log_scans)})


@pytest.mark.slow  # a whole log through SLAM twice
@pytest.mark.parametrize("method,fields", [("graph", {}), ("rbpf", {"num_particles": 3})])
def test_run_slam_resumed_equals_uninterrupted(tmp_path, method, fields):
    log = io.read_carmen_log(data_path(cli.BUNDLED_RAW_LOG)).scans
    n = 250 if method == "graph" else 120
    full = log if method == "graph" else head(log, 240)
    options = default_options(full, method).replace(**fields)
    straight = run_slam(full, method=method, progress=False, options=options)
    run_slam(head(full, n), method=method, progress=False, save=tmp_path / "run.psl", options=options)
    saved = load_run(tmp_path / "run.psl")
    assert saved.method == method and saved.scans_done == n
    mapper = _core.SubmapSlam2D if method == "graph" else _core.GridFastSlam
    assert isinstance(saved.mapper, mapper)
    # The run file holds the options object (in the object's state), the one the run ran with.
    assert saved.options == straight.options and isinstance(saved.options, type(options))
    resumed = run_slam(full, resume=tmp_path / "run.psl", progress=False)
    assert resumed.method == method
    assert np.array_equal(resumed.timestamps, straight.timestamps) and np.array_equal(resumed.poses, straight.poses)
    assert np.array_equal(resumed.grid.log_odds, straight.grid.log_odds)
    # A state that does not fit the log is refused by name.
    with pytest.raises(ValueError, match="not the log the run was made from"):
        run_slam(head(full, n - 1), resume=tmp_path / "run.psl", progress=False)
    with pytest.raises(ValueError, match="holds a"):
        run_slam(full, method="rbpf" if method == "graph" else "graph", resume=tmp_path / "run.psl", progress=False)
    data = (tmp_path / "run.psl").read_bytes()
    (tmp_path / "bad.psl").write_bytes(data[:-10])
    with pytest.raises(ValueError, match="bad.psl"):
        run_slam(full, resume=tmp_path / "bad.psl", progress=False)


@pytest.mark.slow  # a whole log through SLAM twice
def test_cli_slam_save_then_resume_equals_one_run(tmp_path, capsys):
    lines = gzip.decompress(open(data_path(cli.BUNDLED_RAW_LOG), "rb").read()).decode().splitlines(True)
    params = [s for s in lines if not s.startswith("FLASER")]
    lasers = [s for s in lines if s.startswith("FLASER")]
    (tmp_path / "part.log").write_text("".join(params + lasers[:300]))
    full = data_path(cli.BUNDLED_RAW_LOG)
    opts = ["--no-progress", "--no-plot"]
    assert cli.main(["slam", full, "-o", str(tmp_path / "one")] + opts) == 0
    assert cli.main(["slam", str(tmp_path / "part.log"), "-o", str(tmp_path / "part"), "--save",
                     str(tmp_path / "run.psl")] + opts) == 0
    assert cli.main(["slam", full, "-o", str(tmp_path / "two"), "--resume", str(tmp_path / "run.psl")] + opts) == 0
    out = capsys.readouterr().out
    assert "resumed:" in out
    assert (tmp_path / "one_trajectory.tum").read_bytes() == (tmp_path / "two_trajectory.tum").read_bytes()
    assert (tmp_path / "one.pgm").read_bytes() == (tmp_path / "two.pgm").read_bytes()
    # The wrong log: one line, exit 2.
    assert cli.main(["slam", str(tmp_path / "part.log"), "--resume", str(tmp_path / "one.yaml"),
                     "-o", str(tmp_path / "x")] + opts) == 2


def test_grid3d_round_trip(tmp_path):
    g = ps.OccupancyGrid3D(0.2, p_hit=0.75, clamp=(0.1, 0.95))
    rng = np.random.default_rng(4)
    g.insert_point_cloud(rng.uniform(-3, 3, (300, 3)), (0.1, 0.0, 0.2))
    h = round_trip(g, ps.OccupancyGrid3D, tmp_path)
    for a, b in zip(h.known_voxels(), g.known_voxels()):
        assert np.array_equal(a, b)
    assert (h.p_hit, h.clamp, h.num_blocks) == (g.p_hit, g.clamp, g.num_blocks)
    # Both continue alike.
    more = rng.uniform(-3, 3, (300, 3))
    g.insert_point_cloud(more, (0.0, 0.0, 0.0))
    h.insert_point_cloud(more, (0.0, 0.0, 0.0))
    assert state_bytes(h) == state_bytes(g)


def test_pose_graph_3d_round_trip(tmp_path):
    g = ps.PoseGraph3D()
    rng = np.random.default_rng(2)
    for k in range(5):
        q = rng.normal(size=4)
        g.add_pose(k, np.concatenate([rng.normal(size=3), q / np.linalg.norm(q)]))
    g.add_point(20, (1.0, -2.0, 0.5))
    for k in range(4):
        g.add_pose_edge(k, k + 1, (1.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0), np.eye(6) * (k + 1))
    g.add_pose_prior(0, (0, 0, 0, 0, 0, 0, 1), np.eye(6))
    g.add_point_edge(3, 20, (0.5, 0.5, 0.5), np.eye(3))
    g.set_fixed(2)
    h = round_trip(g, ps.PoseGraph3D, tmp_path)
    assert np.array_equal(h.poses, g.poses) and h.is_fixed(2) and h.chi2() == g.chi2()
    for a, b in zip(h.point_edges(), g.point_edges()):
        assert np.array_equal(a, b)
    # Both continue alike.
    for graph in (g, h):
        ps.optimize(graph, max_iterations=3)
    assert state_bytes(h) == state_bytes(g)


def test_monte_carlo_localization_resumed_equals_uninterrupted(tmp_path):
    grid = ps.OccupancyGrid2D(0.1, 80, 60, origin=(-4.0, -3.0))
    grid.log_odds[:] = -3.0
    grid.log_odds[[0, -1], :] = grid.log_odds[:, [0, -1]] = 3.0
    grid.log_odds[20:25, 30:35] = 3.0
    angles = np.linspace(-1.5, 1.5, 30)
    rng = np.random.default_rng(6)
    scans = [np.clip(rng.uniform(0.5, 4.0, 30), 0, None) for _ in range(8)]

    def steps(f, part):
        for z in part:
            f.predict_odometry((0.25, 0.0, 0.05))
            f.update(z, angles)

    make = lambda: ps.MonteCarloLocalization(grid, initial_pose=(0.0, 0.0, 0.0), min_particles=60,
                                             max_particles=300, seed=4)
    straight, first = make(), make()
    steps(straight, scans)
    steps(first, scans[:4])
    resumed = round_trip(first, ps.MonteCarloLocalization, tmp_path)
    assert np.array_equal(resumed.poses, first.poses) and np.array_equal(resumed.weights, first.weights)
    # The estimate's share of the weight (what 'converged' reads) travels with the state.
    assert 0.0 < first.cluster_weight <= 1.0 and resumed.cluster_weight == first.cluster_weight
    steps(resumed, scans[4:])
    assert state_bytes(resumed) == state_bytes(straight)
    assert np.array_equal(resumed.pose, straight.pose) and resumed.num_updates == straight.num_updates
