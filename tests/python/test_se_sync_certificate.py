"""probslam.certificate: SE-Sync's objective against a per-edge loop, its Newton system
against finite differences, the certificate's eigenvalues against a dense numpy eigvalsh of the same
S, the optimum certified and a wrong local minimum not (GTSAM's pose3example graphs and a synthetic
loop)."""

import importlib.util
import pathlib
import sys

import numpy as np
import pytest

pytest.importorskip("scipy.sparse")
import scipy.linalg  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

import probslam  # noqa: E402

import probslam.certificate as sc  # noqa: E402

#: F and tr(X M X^T) sum the same ~10^2 products in another order: double rounding.
ROUNDING = 1e-12
#: Eigenvalues of the same S from a sparse shift-invert Lanczos and a dense QR algorithm agree to
#: rounding in S's scale (||S||_inf), each backward stable to ~1e-15 of it.
EIGENVALUE_AGREEMENT = 1e-11
#: Eigenvalues past the null space come from solves with S + eta I, whose condition ~1 / ETA_RELATIVE
#: = 1e10 leaves them good to ~1e-6 relative (measured: 2e-7 on pose3example).
GAP_RELATIVE = 1e-5
#: Central differences with step h: the error is O(h^2) times third derivatives of order the
#: weights; relative to the derivative itself about 1e-7 at this h.
FD_STEP = 1e-5
FD_RELATIVE = 1e-6
#: Second differences divide F's rounding (1e-16 F, F ~ 1e2) by h^2: ~1e-4 absolute against second
#: derivatives ~1e3.
FD_HESSIAN_RELATIVE = 1e-5
#: A refined critical point: the gradient (weights ~1e2, lengths ~5) is this far below its scale.
CRITICAL_GRADIENT = 1e-6


def ring(n=10, noise=0.05, seed=0):
    """A loop of n poses on a circle of radius 5 (heading along it, a small vertical wave), edges
    i -> i+1 and the closure, measurements of the true relative poses with Gaussian noise (rotation
    vector and translation, `noise` each), information diag(10 I, 100 I): (problem, R, t, pose
    ids, edge ids, measurements, informations)."""
    rng = np.random.default_rng(seed)
    angle = 2 * np.pi * np.arange(n) / n
    R = Rotation.from_euler("z", angle[:, None]).as_matrix()
    t = np.stack([5 * np.cos(angle), 5 * np.sin(angle), 0.3 * np.sin(3 * angle)], axis=1)
    i = np.arange(n)
    j = (i + 1) % n
    Rm = np.einsum("eba,ebc->eac", R[i], R[j]) @ Rotation.from_rotvec(rng.normal(size=(n, 3)) * noise).as_matrix()
    tm = np.einsum("eba,eb->ea", R[i], t[j] - t[i]) + rng.normal(size=(n, 3)) * noise
    measurements = np.hstack([tm, Rotation.from_matrix(Rm).as_quat()])
    information = np.tile(np.diag([10.0, 10, 10, 100, 100, 100]), (n, 1, 1))
    edges = np.stack([i, j], axis=1)
    return sc.problem_from_arrays(i, edges, measurements, information), R, t, i, edges, measurements, information


def gtsam_data(name):
    spec = importlib.util.find_spec("gtsam")
    if spec is None or spec.origin is None:
        pytest.skip("gtsam (its Data folder) not installed")
    path = pathlib.Path(spec.origin).parent / "Data" / name
    if not path.is_file():
        pytest.skip(f"not in gtsam's Data: {path}")
    return path


def optimum_of_file(path):
    """(problem, R, t) at probslam's optimum of the file (from the file's values), then refined in
    SE-Sync's objective."""
    graph = probslam.graph.read_pose_graph_3d(path)
    probslam.graph.optimize(graph)
    p, R, t = sc.problem_from_graph(graph)
    refined = sc.refine(p, R, t)
    return p, refined


@pytest.fixture(params=["pose3example.txt", "pose3example-grid.txt"])
def gtsam_graph(request, shared_data):
    shared = shared_data / "pose_graphs" / "gtsam_examples" / request.param
    return optimum_of_file(shared if shared.is_file() else gtsam_data(request.param))


def brute_force_objective(pose_ids, edges, measurements, information, R, t):
    """SE-Sync's F edge by edge, the weights from each 6x6 information's diagonal blocks."""
    index = {int(k): n for n, k in enumerate(pose_ids)}
    total = 0.0
    for (a, b), z, info in zip(edges, measurements, information):
        i, j = index[int(a)], index[int(b)]
        tau = 3.0 / np.trace(np.linalg.inv(info[:3, :3]))
        kappa = 3.0 / (2.0 * np.trace(np.linalg.inv(info[3:, 3:])))
        Rz = Rotation.from_quat(z[3:]).as_matrix()
        total += kappa * np.sum((R[j] - R[i] @ Rz) ** 2) + tau * np.sum((t[j] - t[i] - R[i] @ z[:3]) ** 2)
    return total


def test_objective_against_a_per_edge_loop_and_the_data_matrix():
    p, R, t, ids, edges, z, info = ring()
    rng = np.random.default_rng(1)
    R = R @ Rotation.from_rotvec(rng.normal(size=(len(R), 3)) * 0.2).as_matrix()  # away from the optimum
    t = t + rng.normal(size=t.shape) * 0.2
    F = sc.objective(p, R, t)
    assert F == pytest.approx(brute_force_objective(ids, edges, z, info, R, t), rel=ROUNDING)
    X = sc.stacked(R, t)
    assert np.trace(X @ (sc.data_matrix(p) @ X.T)) == pytest.approx(F, rel=ROUNDING)


def test_weights_of_an_anisotropic_information():
    """tau = 3 / tr(I_t^-1), kappa = 3 / (2 tr(I_R^-1)) (SE-Sync's g2o reader)."""
    info = np.diag([1.0, 2.0, 4.0, 10.0, 20.0, 40.0])[None]
    kappa, tau = sc.se_sync_weights(info)
    assert tau[0] == pytest.approx(3.0 / (1 + 0.5 + 0.25))
    assert kappa[0] == pytest.approx(3.0 / (2 * (0.1 + 0.05 + 0.025)))


def test_an_edge_to_an_unknown_vertex_is_refused():
    _, _, _, ids, edges, z, info = ring(n=4)
    with pytest.raises(ValueError, match="edge_ids"):
        sc.problem_from_arrays(ids[:3], edges, z, info)


def test_newton_system_against_finite_differences():
    """The gradient and the exact second derivative of F(R_i Exp(w_i), t_i + v_i) at 0."""
    p, R, t, *_ = ring(n=5)
    rng = np.random.default_rng(2)
    R = R @ Rotation.from_rotvec(rng.normal(size=(5, 3)) * 0.3).as_matrix()
    t = t + rng.normal(size=t.shape) * 0.3
    J, r = sc._jacobian(p, R, t)
    H, g = sc._newton_system(p, R, t, sc.data_matrix(p), J, r)
    H = H.toarray()

    def F(step):
        return sc.objective(p, *sc._retract(R, t, step))

    N = 6 * p.n
    e = np.eye(N) * FD_STEP
    g_fd = np.array([(F(e[k]) - F(-e[k])) / (2 * FD_STEP) for k in range(N)])
    np.testing.assert_allclose(g, g_fd, rtol=0, atol=FD_RELATIVE * np.abs(g).max())
    H_fd = np.array([[(F(e[a] + e[b]) - F(e[a] - e[b]) - F(e[b] - e[a]) + F(-e[a] - e[b])) / (4 * FD_STEP ** 2)
                      for b in range(N)] for a in range(N)])
    np.testing.assert_allclose(H, H_fd, rtol=0, atol=FD_HESSIAN_RELATIVE * np.abs(H).max())


def check_certificate_against_dense(p, R, t):
    """The sparse certificate's eigenvalues and inertia are those of a dense eigvalsh of the same S;
    S annihilates X^T and the global translation. Returns the certificate."""
    S = sc.certificate_matrix(p, R, t)
    dense = np.linalg.eigvalsh(S.toarray())
    c = sc.certify(p, R, t)
    scale = c.norm
    assert c.lambda_min == pytest.approx(dense[0], abs=EIGENVALUE_AGREEMENT * scale)
    # lambda_gap against the dense spectrum of S on the complement of X^T and the translation.
    B = np.hstack([sc.stacked(R, t).T, np.r_[np.ones(p.n), np.zeros(3 * p.n)][:, None]])
    complement = scipy.linalg.null_space(B.T)
    assert c.lambda_gap == pytest.approx(np.linalg.eigvalsh(complement.T @ S.toarray() @ complement)[0],
                                         rel=GAP_RELATIVE, abs=EIGENVALUE_AGREEMENT * scale)
    # Inertia at shifts well clear of any eigenvalue: -eta and the midpoints of the widest gaps
    # among the twelve smallest.
    widest = np.argsort(np.diff(dense[:12]))[-3:]
    for shift in [-c.eta] + [0.5 * (dense[m] + dense[m + 1]) for m in widest]:
        assert sc.negative_eigenvalues(S, shift) == np.count_nonzero(dense < shift)
    assert c.certified == bool(dense[0] >= -c.eta)
    return c, dense


def test_gtsam_examples_are_certified_at_their_optimum(gtsam_graph):
    p, refined = gtsam_graph
    assert refined.gradient_norm < CRITICAL_GRADIENT * max(1.0, refined.objective)
    c, dense = check_certificate_against_dense(p, refined.R, refined.t)
    assert c.certified
    assert dense[4] > 1e3 * c.eta  # strictly positive past the null space: not a marginal verdict
    S = sc.certificate_matrix(p, refined.R, refined.t)
    X = sc.stacked(refined.R, refined.t)
    assert np.linalg.norm(S @ X.T) < EIGENVALUE_AGREEMENT * c.norm * np.linalg.norm(X)
    ones = np.r_[np.ones(p.n), np.zeros(3 * p.n)]
    assert np.linalg.norm(S @ ones) < EIGENVALUE_AGREEMENT * c.norm


def test_loop_optimum_certified_and_a_wrong_local_minimum_not():
    """From the true poses the loop's refined optimum is certified. A start with one full 2 pi
    twist about the heading spread along the loop (each pose turned by 2 pi k / n about its x
    axis: a loop in SO(3) that cannot be untwisted continuously) refines to a critical point whose
    exact Hessian (first pose held) is positive definite: a strict local minimum, of a far higher F,
    and the certificate refuses it with a clearly negative lambda_min. (One pose flipped by pi is
    no such trap: the damped Newton leaves it for the optimum, certified too.)"""
    p, R, t, *_ = ring()
    best = sc.refine(p, R, t)
    assert best.gradient_norm < CRITICAL_GRADIENT
    c_best, _ = check_certificate_against_dense(p, best.R, best.t)
    assert c_best.certified

    flipped = R.copy()
    flipped[5] = flipped[5] @ Rotation.from_euler("x", np.pi).as_matrix()
    back = sc.refine(p, flipped, t)
    assert back.objective == pytest.approx(best.objective, rel=1e-9)
    assert sc.certify(p, back.R, back.t).certified

    twisted = R @ Rotation.from_euler("x", (2 * np.pi * np.arange(p.n) / p.n)[:, None]).as_matrix()
    wrong = sc.refine(p, twisted, t)
    assert wrong.gradient_norm < CRITICAL_GRADIENT
    assert wrong.objective > 10 * best.objective
    J, r = sc._jacobian(p, wrong.R, wrong.t)
    H, _ = sc._newton_system(p, wrong.R, wrong.t, sc.data_matrix(p), J, r)
    assert np.linalg.eigvalsh(H.toarray()[6:, 6:])[0] > 0  # a local minimum, not a saddle
    c_wrong, dense = check_certificate_against_dense(p, wrong.R, wrong.t)
    assert not c_wrong.certified
    assert c_wrong.lambda_min < -1e6 * c_wrong.eta


def test_poses_rows_round_trip():
    _, R, t, *_ = ring(n=4)
    rows = sc.poses_rows(R, t)
    np.testing.assert_allclose(sc.quaternion_to_rotation(rows[:, 3:]), R, atol=ROUNDING)
    np.testing.assert_allclose(rows[:, :3], t)


def test_benchmark_certifies_pose3example_and_the_rerun_returns(shared_data):
    """bench_pose_graph_3d.py --certify's per-graph step on the smallest shipped graph."""
    path = shared_data / "pose_graphs" / "gtsam_examples" / "pose3example.txt"
    if not path.is_file():
        pytest.skip(f"dataset not present: {path}")
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "benchmarks"))
    import bench_pose_graph_3d as bench

    r = bench.certify_graph(path)
    assert r["cert"].certified
    assert r["F"] <= r["F_ours"]
    assert r["chi2_rerun"] == pytest.approx(r["chi2"], rel=bench.SAME_OPTIMUM)
