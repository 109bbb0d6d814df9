"""PoseGraph3D with 3-D point landmarks (g2o EDGE_SE3_TRACKXYZ) against an independent dense
Gauss-Newton of the same objective written here with numpy and scipy's rotations
(finite-difference Jacobians); exact graphs; the g2o records read, written and read back; GTSAM's
shipped EDGE_SE3_TRACKXYZ examples; bad input refused with the graph unchanged."""

import glob
import os

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import probslam
from probslam import graph as pg
from g2o3d_text import parse as read_pose_graph_3d
from se3_reference import between, chi2, compose, dense_gauss_newton, from_row, observe, retract, to_row

#: The issue's agreement: poses and points to 1e-8 (m, rad), marginals to 1e-6 relative.
POSE_TOLERANCE = 1e-8
MARGINAL_TOLERANCE = 1e-6
#: Exact data solved exactly: rounding in a few dozen operations per vertex.
EXACT_TOLERANCE = 1e-9
IDENTITY = np.array([0, 0, 0, 0, 0, 0, 1.0])


def random_problem(seed, n=5, m=7, noise=0.03, with_offset=True):
    """A loop of n poses with a chord, m points each seen from three poses; noisy measurements."""
    rng = np.random.default_rng(seed)
    poses = [(Rotation.from_rotvec(rng.normal(size=3)), rng.normal(size=3))]
    for _ in range(1, n):
        poses.append(compose(poses[-1], (Rotation.from_rotvec(0.4 * rng.normal(size=3)), rng.normal(size=3))))
    points = [3 * rng.normal(size=3) for _ in range(m)]
    offset = (Rotation.from_rotvec(0.3 * rng.normal(size=3)), 0.2 * rng.normal(size=3)) if with_offset else (
        Rotation.identity(), np.zeros(3))
    pose_edges = []
    for i, j in [(i, i + 1) for i in range(n - 1)] + [(n - 1, 0), (0, 2)]:
        z = retract(between(poses[i], poses[j]), noise * rng.normal(size=6))
        a = rng.normal(size=(6, 6))
        pose_edges.append((i, j, z, a @ a.T + 6 * np.eye(6)))
    point_edges = []
    for k in range(m):
        for i in (k % n, (k + 1) % n, (k + 3) % n):
            a = rng.normal(size=(3, 3))
            point_edges.append((i, k, observe(poses[i], offset, points[k]) + noise * rng.normal(size=3),
                                a @ a.T + 3 * np.eye(3), offset))
    return poses, points, pose_edges, point_edges


def build(poses, points, pose_edges, point_edges):
    """Poses 0.., points 100..; the first point added between the poses (one id space, one list)."""
    g = probslam.PoseGraph3D()
    for k, x in enumerate(poses):
        g.add_pose(k, to_row(*x))
        if k == 0:
            for l, p in enumerate(points):
                g.add_point(100 + l, p)
    for i, j, z, info in pose_edges:
        g.add_pose_edge(i, j, to_row(*z), info)
    for i, k, z, info, offset in point_edges:
        g.add_point_edge(pose_id=i, point_id=100 + k, measurement=z, information=info, offset=to_row(*offset))
    return g


def start_of(poses, points, seed):
    rng = np.random.default_rng(seed)
    return ([poses[0]] + [retract(x, 0.1 * rng.normal(size=6)) for x in poses[1:]],
            [p + 0.2 * rng.normal(size=3) for p in points])


def test_optimum_and_marginals_match_a_dense_gauss_newton():
    poses, points, pose_edges, point_edges = random_problem(1)
    start_poses, start_points = start_of(poses, points, 2)
    exp_poses, exp_points, h = dense_gauss_newton(start_poses, start_points, pose_edges, point_edges)
    g = build(start_poses, start_points, pose_edges, point_edges)
    assert (g.num_vertices, g.num_points, g.num_point_edges) == (12, 7, 21)
    # Gauss-Newton converges linearly where residuals are not zero: stop on the step.
    report = probslam.optimize(g, relative_tolerance=0.0, step_tolerance=1e-12)
    assert report.converged, report.stop_reason
    assert list(g.pose_ids) == list(range(5)) and list(g.point_ids) == list(range(100, 107))
    for k, row in enumerate(g.poses):
        r, t = from_row(row)
        assert np.abs(t - exp_poses[k][1]).max() < POSE_TOLERANCE
        assert (r.inv() * exp_poses[k][0]).magnitude() < POSE_TOLERANCE
    assert np.abs(g.points - np.array(exp_points)).max() < POSE_TOLERANCE
    reference_chi2 = chi2(exp_poses, exp_points, pose_edges, point_edges)
    assert reference_chi2 > 0.1  # noisy: the optimum is not exact (chi2 0.27 here)
    assert report.chi2 == pytest.approx(reference_chi2, rel=1e-9)
    assert g.edge_chi2().shape == (6 + 21,)
    assert g.edge_chi2().sum() == pytest.approx(reference_chi2, rel=1e-9)
    covariance = np.linalg.inv(h)
    marginals = probslam.marginal_covariances(g, [0, 3, 100, 106])
    assert np.all(marginals[0] == 0.0) and marginals[0].shape == (6, 6)  # the held first pose
    expected = [covariance[12:18, 12:18], covariance[24:27, 24:27], covariance[42:45, 42:45]]
    for got, block in zip(marginals[1:], expected):
        assert got.shape == block.shape
        assert np.abs(got - block).max() < MARGINAL_TOLERANCE * np.abs(block).max()
    joint = probslam.joint_marginal_covariances(g, [[3, 106]])[0]
    assert joint.shape == (9, 9)
    cross = covariance[12:18, 42:45]
    assert np.abs(joint[:6, 6:] - cross).max() < MARGINAL_TOLERANCE * np.abs(covariance).max()


@pytest.mark.parametrize("kernel", ["none", "huber", "cauchy"])
def test_levenberg_marquardt_and_kernels_agree_with_gauss_newton_where_they_should(kernel):
    problem = random_problem(3)
    start = start_of(*problem[:2], 4)
    gn, lm = build(*start, *problem[2:]), build(*start, *problem[2:])
    options = dict(kernel=kernel, kernel_width=100.0, relative_tolerance=0.0, step_tolerance=1e-12)
    probslam.optimize(gn, **options)
    report = probslam.optimize(lm, algorithm="levenberg-marquardt", **options)
    assert report.converged
    # Gauss-Newton and Levenberg-Marquardt reach the same optimum of each objective.
    assert np.abs(gn.poses - lm.poses).max() < 1e-7
    assert np.abs(gn.points - lm.points).max() < 1e-7


def test_an_exact_graph_reaches_chi2_zero_from_a_perturbed_start_and_from_the_initialisers():
    poses, points, pose_edges, point_edges = random_problem(5, noise=0.0)
    g = build(poses, points, pose_edges, point_edges)
    assert g.chi2() < 1e-20
    start_poses, start_points = start_of(poses, points, 6)
    g.set_poses(g.pose_ids[1:], [to_row(*x) for x in start_poses[1:]])
    g.set_points(g.point_ids, start_points)
    assert g.chi2() > 1.0
    for algorithm in ("gauss-newton", "levenberg-marquardt"):
        h = g.copy()
        assert probslam.optimize(h, algorithm=algorithm).chi2 < 1e-18
        assert np.abs(h.points - np.array(points)).max() < EXACT_TOLERANCE
    for initialise in (probslam.initialize_odometry, probslam.initialize_chordal):
        h = g.copy()
        h.set_points(h.point_ids, np.full((len(points), 3), 50.0))
        initialise(h)
        assert h.chi2() < 1e-16
        assert np.abs(h.points - np.array(points)).max() < EXACT_TOLERANCE


def test_incremental_optimisation_with_points_reaches_the_batch_optimum():
    """Poses join two at a time, each point with the earliest pose that sees it (placed from that
    pose): the last step optimises the whole graph, so with a tight last step the result is the
    batch optimum."""
    poses, points, pose_edges, point_edges = random_problem(9, n=7, m=8)
    rng = np.random.default_rng(10)
    batch = build(poses, points, pose_edges, point_edges)
    probslam.optimize(batch, relative_tolerance=0.0, step_tolerance=1e-12)
    scrambled = [poses[0]] + [(Rotation.random(random_state=rng), rng.normal(size=3)) for _ in poses[1:]]
    g = build(scrambled, [50 * np.ones(3)] * len(points), pose_edges, point_edges)
    report = probslam.optimize_incremental(g, poses_per_step=2, step=dict(max_iterations=50, relative_tolerance=0.0,
                                                step_tolerance=1e-12))
    assert report.steps == 4  # 7 poses, 2 a step
    assert report.chi2 == pytest.approx(batch.chi2(), rel=1e-12)
    assert np.abs(g.poses - batch.poses).max() < POSE_TOLERANCE
    assert np.abs(g.points - batch.points).max() < POSE_TOLERANCE


def test_bad_input_is_refused_and_leaves_the_graph_unchanged():
    g = probslam.PoseGraph3D()
    g.add_pose(0, IDENTITY)
    g.add_pose(1, IDENTITY)
    g.add_point(7, [1, 2, 3])
    g.add_point_edge(0, 7, [1, 2, 3], np.eye(3))
    before = (g.poses, g.points, g.point_edges())

    def same():
        now = (g.poses, g.points, g.point_edges())
        return (g.num_vertices, g.num_points, g.num_point_edges, g.num_pose_edges) == (3, 1, 1, 0) and all(
            np.array_equal(a, b) for a, b in zip(before[:2], now[:2])) and all(
            np.array_equal(a, b) for a, b in zip(before[2], now[2]))

    with pytest.raises(ValueError, match="id"):
        g.add_point(0, [0, 0, 0])  # a pose's id
    with pytest.raises(ValueError, match="id"):
        g.add_pose(7, IDENTITY)  # a point's id
    with pytest.raises(ValueError, match="point"):
        g.add_point(8, [0, np.nan, 0])
    with pytest.raises(ValueError, match="point"):
        g.add_point(8, [0, 0])
    with pytest.raises(ValueError, match="pose_id"):
        g.add_point_edge(9, 7, [0, 0, 0], np.eye(3))
    with pytest.raises(ValueError, match="point_id"):
        g.add_point_edge(0, 9, [0, 0, 0], np.eye(3))
    with pytest.raises(ValueError, match="pose_id.*point, not a pose"):
        g.add_point_edge(7, 7, [0, 0, 0], np.eye(3))
    with pytest.raises(ValueError, match="point_id.*pose, not a point"):
        g.add_point_edge(0, 1, [0, 0, 0], np.eye(3))
    with pytest.raises(ValueError, match="to.*point, not a pose"):
        g.add_pose_edge(0, 7, IDENTITY, np.eye(6))
    with pytest.raises(ValueError, match="id.*point, not a pose"):
        g.add_pose_prior(7, IDENTITY, np.eye(6))
    with pytest.raises(ValueError, match="measurement"):
        g.add_point_edge(0, 7, [0, np.inf, 0], np.eye(3))
    asymmetric = np.eye(3)
    asymmetric[0, 2] = 0.5
    for bad in (np.full((3, 3), np.nan), asymmetric, -np.eye(3), np.diag([1.0, 1.0, 0.0]), np.eye(6)):
        with pytest.raises(ValueError, match="information"):
            g.add_point_edge(0, 7, [0, 0, 0], bad)
    with pytest.raises(ValueError, match="offset"):
        g.add_point_edge(0, 7, [0, 0, 0], np.eye(3), offset=[0, 0, 0, 0, 0, 0, 2])
    with pytest.raises(ValueError, match="ids"):
        g.set_points([0], [[0, 0, 0]])
    with pytest.raises(ValueError, match="ids"):
        g.set_poses([7], [IDENTITY])
    with pytest.raises(ValueError, match="points"):
        g.set_points([7], [[0, np.nan, 0]])
    assert same()
    assert "2 poses, 1 points, 1 edges" in repr(g)


def test_a_point_cannot_hold_the_gauge_and_a_floating_part_is_named():
    g = probslam.PoseGraph3D()
    g.add_point(7, [1, 2, 3])  # first in the list: still the first pose holds the gauge
    g.add_pose(0, IDENTITY)
    g.add_pose(9, IDENTITY)
    g.add_point(8, [0, 0, 0])
    g.add_point_edge(0, 7, [1, 2, 3], np.eye(3))
    g.add_point_edge(9, 8, [0, 0, 0], np.eye(3))
    with pytest.raises(ValueError, match="vertices 9, 8 form a part"):
        probslam.optimize(g)


# --- g2o records ------------------------------------------------------------------------------

TEXT = """VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1
VERTEX_SE3:QUAT 1 1 0 0 0 0 0.38941834230865052 0.92106099400288510
VERTEX_TRACKXYZ 5 1 2 3.25
VERTEX_TRACKXYZ 6 -1 0.5 2
FIX 0 6
PARAMS_SE3OFFSET 0 0 0 0 0 0 0 1
PARAMS_SE3OFFSET 3 0.1 0 0.2 0 0 0.70710678118654752 0.70710678118654752
EDGE_SE3:QUAT 0 1 1 0 0 0 0 0.38941834230865052 0.92106099400288510 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1
EDGE_SE3_TRACKXYZ 0 5 0 1 2 3.25 4 0.5 0 4 0 4
EDGE_SE3_TRACKXYZ 1 5 3 0.5 1 2 9 0 0 9 0 9
EDGE_SE3_TRACKXYZ 1 6 3 -1 0 1 1 0 0 1 0 1
"""


def write_text(tmp_path, text, name="g.g2o"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_g2o_points_read_into_the_graph_and_round_trip_bit_for_bit(tmp_path):
    path = write_text(tmp_path, TEXT)
    f = read_pose_graph_3d(path)
    assert list(f.point_ids) == [5, 6] and list(f.point_fixed) == [False, True]
    np.testing.assert_array_equal(f.points, [[1, 2, 3.25], [-1, 0.5, 2]])
    np.testing.assert_array_equal(f.point_edges, [[0, 5], [1, 5], [1, 6]])
    np.testing.assert_array_equal(f.point_information[0], [[4, 0.5, 0], [0.5, 4, 0], [0, 0, 4]])
    np.testing.assert_array_equal(f.point_offset_translations[1], [0.1, 0, 0.2])
    np.testing.assert_array_equal(f.point_offset_quaternions[0], [0, 0, 0, 1])
    g = pg.read_pose_graph_3d(path)
    assert (g.num_vertices, g.num_points, g.num_point_edges) == (4, 2, 3)
    assert g.is_fixed(0) and g.is_fixed(6) and not g.is_fixed(5)
    # The chi2 written out independently: edge 0 is exact; the others by hand with scipy.
    x1 = (Rotation.from_quat([0, 0, 0.38941834230865052, 0.92106099400288510]), np.array([1.0, 0, 0]))
    off = (Rotation.from_quat([0, 0, 0.70710678118654752, 0.70710678118654752]), np.array([0.1, 0, 0.2]))
    e1 = observe(x1, off, np.array([1, 2, 3.25])) - [0.5, 1, 2]
    e2 = observe(x1, off, np.array([-1, 0.5, 2])) - [-1, 0, 1]
    assert g.chi2() == pytest.approx(9 * e1 @ e1 + e2 @ e2, rel=1e-12)
    ids, z, info, offsets = g.point_edges()
    np.testing.assert_array_equal(ids, [[0, 5], [1, 5], [1, 6]])
    np.testing.assert_array_equal(offsets[0], IDENTITY)
    # What the reader built is what the text says, number for number (a plain-Python parse).
    ref = read_pose_graph_3d(path)
    np.testing.assert_array_equal(g.point_ids, ref.point_ids)
    np.testing.assert_array_equal(g.points, ref.points)
    for a, b in zip(g.point_edges(), (ref.point_edges, ref.point_measurements, ref.point_information)):
        np.testing.assert_array_equal(a, b)
    probslam.optimize(g)
    pg.write_g2o_3d(g, tmp_path / "g.g2o")
    back = pg.read_pose_graph_3d(tmp_path / "g.g2o")
    np.testing.assert_array_equal(back.poses, g.poses)
    np.testing.assert_array_equal(back.points, g.points)
    for a, b in zip(back.point_edges(), g.point_edges()):
        np.testing.assert_array_equal(a, b)
    assert back.is_fixed(6) and back.chi2() == g.chi2()
    assert pg.pose_graph_dimension(write_text(tmp_path, "VERTEX_TRACKXYZ 1 0 0 0\n", "p.g2o")) == 3


@pytest.mark.parametrize("text, message", [
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_TRACKXYZ 0 1 2 3\n", r":2: vertex 0 given twice"),
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_TRACKXYZ 1 1 2 3\nPARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\n"
     "EDGE_SE3_TRACKXYZ 1 0 0 1 2 3 1 0 0 1 0 1\n", r":4: vertex 1 is a point"),
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\nPARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\n"
     "EDGE_SE3_TRACKXYZ 0 1 0 1 2 3 1 0 0 1 0 1\n", r":4: vertex 1 is a pose, not a point"),
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_TRACKXYZ 1 1 2 3\nVERTEX_SE3:QUAT 2 0 0 0 0 0 0 1\n"
     "EDGE_SE3:QUAT 0 1 0 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n", r":4: vertex 1 is a point"),
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_TRACKXYZ 1 1 2 3\n"
     "EDGE_SE3_TRACKXYZ 0 1 4 1 2 3 1 0 0 1 0 1\n", r":3: .*parameter 4"),
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_TRACKXYZ 1 1 2 3\nPARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\n"
     "EDGE_SE3_TRACKXYZ 0 1 0 1 2 3 -1 0 0 -1 0 -1\n", r":4: information"),
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_TRACKXYZ 1 1 nan 3\n", r":2: point"),
    ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_TRACKXYZ 1 1 2 3\nPARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\n"
     "EDGE_SE3_TRACKXYZ 0 1 0 1 2 3 1 0 0 1 0\n", r":4:"),
])
def test_bad_point_records_are_refused_by_line(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        pg.read_pose_graph_3d(write_text(tmp_path, text))


def test_a_truncated_last_point_edge_is_skipped_and_reported(tmp_path):
    # Enough records that one bad one stays within MAX_BAD_ROW_FRACTION.
    text = TEXT + 120 * "EDGE_SE3_TRACKXYZ 0 5 0 1 2 3.25 4 0.5 0 4 0 4\n" + "EDGE_SE3_TRACKXYZ 1 6 3 -1 0\n"
    read = pg.read_pose_graph_3d_with_report(write_text(tmp_path, text))
    assert read.graph.num_point_edges == 123
    assert list(read.report.skipped_lines) == [11 + 120 + 1]
    with pytest.raises(ValueError, match=":132:"):
        pg.read_pose_graph_3d(write_text(tmp_path, text))


def gtsam_example(name):
    """GTSAM's shipped EDGE_SE3_TRACKXYZ examples, from its wheel when installed."""
    try:
        import gtsam
    except ImportError:
        pytest.skip("gtsam is not installed (a peer for comparison, not a dependency)")
    paths = glob.glob(os.path.join(os.path.dirname(gtsam.__file__), "Data", f"edge_se3_trackxyz_{name}.g2o"))
    if not paths:
        pytest.skip(f"gtsam's wheel ships no edge_se3_trackxyz_{name}.g2o")
    return gtsam, paths[0]


def test_gtsam_trackxyz_example_reads_to_the_same_zero_error():
    gtsam, path = gtsam_example("example")
    g = pg.read_pose_graph_3d(path)
    assert (len(g.pose_ids), g.num_points, g.num_point_edges) == (1, 1, 1)
    # The point (0, 0, 3.5) seen from x = (1, -2, 0.5), yaw 90 degrees, at z = (2, 1, 3): exact.
    assert g.chi2() < 1e-20
    graph, values = gtsam.readG2o(path, True)
    assert graph.error(values) < 1e-20


def test_gtsam_trackxyz_missing_vertex_names_the_line():
    _, path = gtsam_example("missing_vertex")
    with pytest.raises(ValueError, match=r":3: unknown point vertex 9"):
        pg.read_pose_graph_3d(path)


def test_gtsam_trackxyz_nonidentity_offset_applies_the_offset():
    # GTSAM's readG2o refuses a non-identity offset; g2o applies it, and so does this reader: the
    # sensor 0.1 m along the pose's x (the world's y after the 90 degree yaw) sees the point at
    # (1.9, 1, 3), 0.1 m short of z = (2, 1, 3) along x: chi2 = 0.01 * information[0, 0].
    _, path = gtsam_example("nonidentity_offset")
    g = pg.read_pose_graph_3d(path)
    np.testing.assert_array_equal(g.point_edges()[3][0], [0.1, 0, 0, 0, 0, 0, 1])
    assert g.chi2() == pytest.approx(0.01 * 72.57142857142857, rel=1e-12)


def test_gtsam_trackxyz_zero_range_is_an_ordinary_point_edge():
    # GTSAM's bearing-range conversion cannot take a zero range; the Cartesian error can.
    _, path = gtsam_example("zero_range")
    g = pg.read_pose_graph_3d(path)
    assert g.chi2() == 0.0
    np.testing.assert_array_equal(g.point_edges()[2][0], np.eye(3))


def test_probslam_optimize_reads_optimises_writes_and_draws_the_points(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from probslam import cli
    from probslam.plot import pose_graph_3d

    poses, points, pose_edges, point_edges = random_problem(7)
    g = build(*start_of(poses, points, 8), pose_edges, point_edges)
    pg.write_g2o_3d(g, tmp_path / "in.g2o")
    assert cli.main(["optimize", str(tmp_path / "in.g2o"), "--init", "file", "--no-progress",
                     "-o", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "3-D, 5 poses, 6 edges, 7 points, 21 point edges, 0 priors" in out
    assert (tmp_path / "o.png").read_bytes()[:4] == b"\x89PNG"
    result = pg.read_pose_graph_3d(tmp_path / "o.g2o")
    probslam.optimize(g)
    np.testing.assert_allclose(result.points, g.points, atol=1e-9)
    # The picture: the points as dots at their (x, y) in the top view and (x, z) in the side view.
    fig, (top, side) = plt.subplots(1, 2)
    pose_graph_3d(top, side, result, edges=True)
    for ax, columns in ((top, [0, 1]), (side, [0, 2])):
        (dots,) = [c for c in ax.collections if c.get_label() == "points"]
        np.testing.assert_allclose(dots.get_offsets(), result.points[:, columns])
    plt.close(fig)


def test_many_distinct_offsets_round_trip_each_to_its_edge(tmp_path):
    # Issue 48: the writer searched the offsets written so far for every point edge
    # (O(edges x distinct offsets)); now a lookup. Each edge must still get its own offset's
    # parameter, equal offsets sharing one, checked against the edges' offsets directly.
    rng = np.random.default_rng(7)
    g = probslam.PoseGraph3D()
    g.add_pose(0, IDENTITY)
    distinct = [to_row(Rotation.from_rotvec(0.5 * rng.normal(size=3)), rng.normal(size=3)) for _ in range(60)]
    distinct[5] = np.array([0.0, -0.0, 0.0, 0.0, 0.0, 0.0, 1.0])  # the identity, written as parameter 0
    chosen = rng.integers(0, len(distinct), 400)
    for k, c in enumerate(chosen):
        g.add_point(1 + k, rng.normal(size=3))
        g.add_point_edge(0, 1 + k, rng.normal(size=3), np.eye(3), offset=distinct[c])
    path = tmp_path / "offsets.g2o"
    pg.write_g2o_3d(g, path)
    params = [line.split() for line in path.read_text().splitlines() if line.startswith("PARAMS_SE3OFFSET")]
    assert len(params) == len({c for c in chosen if c != 5}) + 1  # one per distinct offset, identity first
    assert [float(x) for x in params[0][2:]] == [0, 0, 0, 0, 0, 0, 1]
    back = pg.read_pose_graph_3d(path)
    np.testing.assert_array_equal(back.point_edges()[3], g.point_edges()[3])
    np.testing.assert_array_equal(back.point_edges()[0], g.point_edges()[0])


@pytest.mark.parametrize("what", ["empty", "points only"])
def test_a_graph_without_poses_round_trips(tmp_path, what):
    # Issue 48: write_g2o_3d of an empty graph wrote a file the reader refused.
    g = probslam.PoseGraph3D()
    if what == "points only":
        g.add_point(3, [1.0, 2.0, 3.0])
    path = tmp_path / "g.g2o"
    pg.write_g2o_3d(g, path)
    back = pg.read_pose_graph_3d(path)
    assert back.num_vertices == g.num_vertices and back.num_points == g.num_points
    np.testing.assert_array_equal(back.points, g.points)
    arrays = read_pose_graph_3d(path)
    assert arrays.vertex_ids.shape == (0,)
    two = tmp_path / "two.g2o"
    pg.write_g2o(probslam.PoseGraph2D(), two)
    assert pg.read_pose_graph(two).num_vertices == 0


def test_edge_ids_are_every_edge_as_in_2d(tmp_path):
    """PoseGraph3D.edge_ids, as PoseGraph2D's: the pose edges, then the point edges (pose, point),
    one row per entry of edge_chi2 (it listed the pose edges only)."""
    g = pg.read_pose_graph_3d(write_text(tmp_path, TEXT))
    ids = g.edge_ids()
    np.testing.assert_array_equal(ids, np.vstack([g.pose_edges()[0], g.point_edges()[0]]))
    assert len(ids) == len(g.edge_chi2()) == g.num_pose_edges + g.num_point_edges
