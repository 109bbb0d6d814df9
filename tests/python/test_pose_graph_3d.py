"""PoseGraph3D against an independent dense Gauss-Newton of the same objective written here with
numpy and scipy's rotations (finite-difference Jacobians), and the chordal initialisation on
noise-free graphs."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import probslam
from se3_reference import between, chi2, dense_gauss_newton, from_row, retract, to_row

#: The issue's agreement: poses to 1e-8 (m, rad), marginals to 1e-6 relative.
POSE_TOLERANCE = 1e-8
MARGINAL_TOLERANCE = 1e-6
#: Exact data solved exactly: rounding in a few dozen operations per pose.
EXACT_TOLERANCE = 1e-9


def random_graph(seed, n=8, noise=0.05):
    rng = np.random.default_rng(seed)
    truth = [(Rotation.from_rotvec(rng.normal(size=3)), rng.normal(size=3))]
    for _ in range(1, n):
        step = (Rotation.from_rotvec(0.4 * rng.normal(size=3)), rng.normal(size=3))
        r, t = truth[-1]
        truth.append((r * step[0], t + r.apply(step[1])))
    pairs = [(i, i + 1) for i in range(n - 1)] + [(n - 1, 0), (0, 3), (2, 6), (1, 5)]
    edges = []
    for i, j in pairs:
        z = retract(between(truth[i], truth[j]), noise * rng.normal(size=6))
        a = rng.normal(size=(6, 6))
        edges.append((i, j, z, a @ a.T + 6 * np.eye(6)))
    return truth, edges


def build(poses, edges):
    g = probslam.PoseGraph3D()
    for k, (r, t) in enumerate(poses):
        g.add_pose(100 + k, to_row(r, t))
    for i, j, z, info in edges:
        g.add_pose_edge(100 + i, 100 + j, to_row(*z), info)
    return g


def test_optimum_and_marginals_match_a_dense_gauss_newton():
    truth, edges = random_graph(1)
    rng = np.random.default_rng(2)
    start = [truth[0]] + [retract(x, 0.1 * rng.normal(size=6)) for x in truth[1:]]
    expected, _, h = dense_gauss_newton(start, [], edges, [])
    g = build(start, edges)
    # Gauss-Newton converges linearly where residuals are not zero: the default stop on the
    # objective's relative change (1e-10) leaves steps of ~1e-8; stop on the step instead.
    report = probslam.optimize(g, relative_tolerance=0.0, step_tolerance=1e-12)
    assert report.converged, report.stop_reason
    for k, row in enumerate(g.poses):
        r, t = from_row(row)
        assert np.abs(t - expected[k][1]).max() < POSE_TOLERANCE
        assert (r.inv() * expected[k][0]).magnitude() < POSE_TOLERANCE
    reference_chi2 = chi2(expected, [], edges, [])
    assert report.chi2 == pytest.approx(reference_chi2, rel=1e-9)
    covariance = np.linalg.inv(h)
    marginals = probslam.marginal_covariances(g, [100, 101, 105])
    assert np.all(marginals[0] == 0.0)  # the held first pose
    for m, v in zip(marginals[1:], (1, 5)):
        block = covariance[6 * (v - 1):6 * v, 6 * (v - 1):6 * v]
        assert np.abs(m - block).max() < MARGINAL_TOLERANCE * np.abs(block).max()
    joint = probslam.joint_marginal_covariances(g, [[101, 105]])[0]
    cross = covariance[0:6, 24:30]
    assert np.abs(joint[:6, 6:] - cross).max() < MARGINAL_TOLERANCE * np.abs(covariance).max()


def test_levenberg_marquardt_reaches_the_same_optimum():
    truth, edges = random_graph(3)
    gn, lm = build(truth, edges), build(truth, edges)
    probslam.optimize(gn)
    report = probslam.optimize(lm, algorithm="levenberg-marquardt", callback=lambda i, chi2: True)
    assert report.converged
    assert np.abs(gn.poses - lm.poses).max() < 1e-7


def test_chordal_initialisation_recovers_the_rotations_of_a_noise_free_graph():
    truth, edges = random_graph(4, n=20, noise=0.0)
    rng = np.random.default_rng(5)
    start = [truth[0]] + [(Rotation.random(random_state=rng), 10 * rng.normal(size=3)) for _ in truth[1:]]
    g = build(start, edges)
    probslam.initialize_chordal(g)
    for k, row in enumerate(g.poses):
        r, t = from_row(row)
        assert (r.inv() * truth[k][0]).magnitude() < EXACT_TOLERANCE
        assert np.abs(t - truth[k][1]).max() < EXACT_TOLERANCE
    assert g.chi2() < 1e-16


def test_odometry_initialisation_and_an_exact_loop_reach_chi2_zero():
    truth, edges = random_graph(6, noise=0.0)
    rng = np.random.default_rng(7)
    g = build([truth[0]] + [(Rotation.random(random_state=rng), rng.normal(size=3)) for _ in truth[1:]], edges)
    probslam.initialize_odometry(g)
    assert g.chi2() < 1e-16
    g.set_poses(g.pose_ids[1:], [to_row(*retract(x, 0.2 * rng.normal(size=6))) for x in truth[1:]])
    assert g.chi2() > 1.0
    assert probslam.optimize(g).chi2 < 1e-18


def test_bad_input_is_refused_and_leaves_the_graph_unchanged():
    g = probslam.PoseGraph3D()
    identity = [0, 0, 0, 0, 0, 0, 1]
    g.add_pose(0, identity)
    g.add_pose(1, identity)
    g.add_pose_edge(0, 1, [1, 0, 0, 0, 0, 0, 1], np.eye(6))
    with pytest.raises(ValueError, match="id"):
        g.add_pose(1, identity)
    with pytest.raises(ValueError, match="pose.*norm 1"):
        g.add_pose(2, [0, 0, 0, 0, 0, 0, 1.1])
    with pytest.raises(ValueError, match="pose"):
        g.add_pose(2, [0, 0, 0, np.nan, 0, 0, 1])
    with pytest.raises(ValueError, match="pose"):
        g.add_pose(2, [0, 0, 0])
    with pytest.raises(ValueError, match="to"):
        g.add_pose_edge(0, 9, identity, np.eye(6))
    asymmetric = np.eye(6)
    asymmetric[0, 5] = 0.5
    for bad in (np.full((6, 6), np.nan), asymmetric, -np.eye(6), np.eye(3)):
        with pytest.raises(ValueError, match="information"):
            g.add_pose_edge(0, 1, identity, bad)
    with pytest.raises(ValueError, match="measurement"):
        g.add_pose_edge(0, 1, [0, 0, 0, 0, 0, 0, 2], np.eye(6))
    with pytest.raises(ValueError, match="poses"):
        g.set_poses([1], [[0, 0, 0, 0, 0, 0, 3]])
    assert (g.num_vertices, g.num_pose_edges) == (2, 1)
    g.add_pose(5, identity)
    before = g.poses
    with pytest.raises(ValueError, match="5"):
        probslam.optimize(g)
    with pytest.raises(ValueError, match="5"):
        probslam.initialize_chordal(g)
    assert np.array_equal(g.poses, before)
    assert "3 poses, 1 edges" in repr(g)


def test_incremental_optimisation_reaches_the_batch_optimum_from_dead_reckoning():
    """Poses join a few at a time, each seeded from its first edge to an earlier pose: the last
    step optimises the whole graph, so with a tight last step the result is the batch optimum."""
    truth, edges = random_graph(8, n=12)
    rng = np.random.default_rng(9)
    scrambled = [truth[0]] + [(Rotation.random(random_state=rng), rng.normal(size=3)) for _ in truth[1:]]
    batch = build(truth, edges)
    probslam.optimize(batch, relative_tolerance=0.0, step_tolerance=1e-12)
    g = build(scrambled, edges)
    report = probslam.optimize_incremental(g, poses_per_step=5, step=dict(max_iterations=50, relative_tolerance=0.0,
                                                step_tolerance=1e-12))
    assert report.steps == 3 and len(report.step_chi2) == 3  # 12 poses, 5 a step
    assert report.chi2 == pytest.approx(batch.chi2(), rel=1e-12)
    assert report.step_chi2[-1] == pytest.approx(report.chi2, rel=1e-12)
    assert np.abs(g.poses - batch.poses).max() < POSE_TOLERANCE


def test_incremental_optimisation_of_an_exact_graph_is_exact_and_refuses_bad_input():
    truth, edges = random_graph(10, n=9, noise=0.0)
    rng = np.random.default_rng(11)
    g = build([truth[0]] + [(Rotation.random(random_state=rng), rng.normal(size=3)) for _ in truth[1:]], edges)
    before = g.poses
    with pytest.raises(ValueError, match="poses_per_step"):
        probslam.optimize_incremental(g, poses_per_step=0)
    with pytest.raises(ValueError, match=r"^step\.algorithm"):
        probslam.optimize_incremental(g, step={"algorithm": "newton"})
    assert np.array_equal(g.poses, before)
    report = probslam.optimize_incremental(g, poses_per_step=2)
    assert report.steps == 5
    assert report.chi2 < 1e-16
    for k, row in enumerate(g.poses):
        r, t = from_row(row)
        assert (r.inv() * truth[k][0]).magnitude() < EXACT_TOLERANCE
        assert np.abs(t - truth[k][1]).max() < EXACT_TOLERANCE


def test_incremental_optimisation_with_a_prior_on_the_first_pose():
    """A prior on the first pose is no edge: its first step (the lone pose) is skipped, not
    handed to the optimiser, which refused it ("graph has no edges"); the steps after it hold
    the prior, and the end is the batch optimum."""
    truth, edges = random_graph(12, n=8, noise=0.05)
    g = build([truth[0]] * len(truth), edges)
    g.add_pose_prior(100, to_row(*truth[0]), np.eye(6))
    batch = g.copy()
    probslam.optimize(batch, relative_tolerance=0.0, step_tolerance=1e-12)
    report = probslam.optimize_incremental(g, poses_per_step=1, step=dict(max_iterations=50, relative_tolerance=0.0,
                                                step_tolerance=1e-12))
    assert report.steps == len(truth) - 1
    assert report.chi2 == pytest.approx(batch.chi2(), rel=1e-12)
    assert np.abs(g.poses - batch.poses).max() < POSE_TOLERANCE
