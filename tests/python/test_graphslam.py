"""GraphSLAM in information form (Tables 11.1-11.5) against dense numpy references."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

import probslam
from eif_reference import construct, dense_gauss_newton, simulate
from ekf_reference import motion

R = np.diag([0.02, 0.02, 0.005]) ** 2
Q2 = np.diag([0.05, 0.01]) ** 2
Q3 = np.diag([0.05, 0.01, 0.1]) ** 2
# Agreement of two double-precision solves of systems with condition numbers about 1e6.
TIGHT = 1e-9


def problem(signatures=False, seed=0, steps=40):
    controls, dt, meas, truth, feats = simulate(steps=steps, signatures=signatures, seed=seed)
    Q = Q3 if signatures else Q2
    # A linearisation point near the truth, but not at it.
    rng = np.random.default_rng(seed + 1)
    poses = truth + rng.normal(0, [0.05, 0.05, 0.01], truth.shape)
    poses[0] = truth[0]
    d = meas[1].shape[1]
    features = np.column_stack([feats, np.arange(len(feats))]) if d == 3 else feats.copy()
    features = features + rng.normal(0, 0.1, features.shape)
    return controls, dt, meas, poses, features, Q


def test_initialize_chains_the_motion_model():
    controls, dt, _, _, _ = simulate()
    path = probslam.eif_initialize(controls, dt)
    expected = [np.zeros(3)]
    for u, h in zip(controls, dt):
        d, _, _ = motion(expected[-1], *u, h)
        expected.append(expected[-1] + d)
    np.testing.assert_allclose(path, np.array(expected), atol=1e-12)


@pytest.mark.parametrize("signatures", [False, True])
def test_construct_equals_dense_table_11_2(signatures):
    controls, dt, meas, poses, features, Q = problem(signatures)
    y = np.concatenate([poses.ravel(), features.ravel()])
    omega, xi = probslam.eif_construct(controls, dt, meas, y, R, Q)
    ref_omega, ref_xi = construct(controls, dt, meas, poses, features, R, Q)
    scale = np.abs(ref_omega).max()
    np.testing.assert_allclose(omega.toarray(), ref_omega, rtol=0, atol=TIGHT * scale)
    np.testing.assert_allclose(xi, ref_xi, rtol=0, atol=TIGHT * np.abs(ref_xi).max())


@pytest.mark.parametrize("signatures", [False, True])
def test_reduce_then_solve_equals_direct_sparse_and_dense_solves(signatures):
    controls, dt, meas, poses, features, Q = problem(signatures)
    y = np.concatenate([poses.ravel(), features.ravel()])
    omega, xi = probslam.eif_construct(controls, dt, meas, y, R, Q)
    num_poses = len(poses)
    d = features.shape[1]
    r_omega, r_xi = probslam.eif_reduce(omega, xi, num_poses, d)
    pairs = [(t, t) for t in range(num_poses)] + [(3, 10), (20, 5), (0, 7)]
    path, feats, blocks = probslam.eif_solve(r_omega, r_xi, omega, xi, num_poses, d, pairs)

    direct = spla.spsolve(omega.tocsc(), xi)
    dense = np.linalg.solve(omega.toarray(), xi)
    for reference in (direct, dense):
        ref_path = reference[:3 * num_poses].reshape(-1, 3)
        np.testing.assert_allclose(path[:, :2], ref_path[:, :2], atol=TIGHT * 100)
        np.testing.assert_allclose(np.angle(np.exp(1j * (path[:, 2] - ref_path[:, 2]))), 0, atol=TIGHT)
        np.testing.assert_allclose(feats.ravel(), reference[3 * num_poses:], atol=TIGHT * 100)

    # Path marginals against the dense inverse (x_0 is known exactly: zero covariance).
    sigma = np.linalg.inv(omega.toarray())
    for (s, t), block in zip(pairs, blocks):
        expected = np.zeros((3, 3)) if 0 in (s, t) else sigma[3 * s:3 * s + 3, 3 * t:3 * t + 3]
        np.testing.assert_allclose(block, expected, rtol=1e-7, atol=1e-14)

    # The dense Schur complement of Table 11.3.
    dense_omega = omega.toarray()
    p = 3 * num_poses
    ref_reduced = dense_omega[:p, :p] - dense_omega[:p, p:] @ np.linalg.solve(dense_omega[p:, p:], dense_omega[p:, :p])
    np.testing.assert_allclose(r_omega.toarray(), ref_reduced, atol=TIGHT * np.abs(ref_reduced).max())


@pytest.mark.parametrize("signatures", [False, True])
@pytest.mark.slow
def test_graph_slam_converges_to_the_dense_gauss_newton_minimum(signatures):
    controls, dt, meas, _, _, Q = problem(signatures, steps=16)  # small: the reference is slow
    result = probslam.graph_slam(controls, dt, meas, R, Q)
    assert result.converged and result.iterations < 15
    y0 = np.concatenate([result.poses.ravel(), result.features.ravel()])
    # Start the reference from the dead-reckoned guess, independently of our result.
    path = probslam.eif_initialize(controls, dt)
    feats = np.zeros_like(result.features)
    time, z, corr = meas
    for j in range(len(feats)):
        k = np.flatnonzero(corr == j)[0]
        pose = path[time[k]]
        feats[j, :2] = pose[:2] + z[k, 0] * np.array([np.cos(pose[2] + z[k, 1]), np.sin(pose[2] + z[k, 1])])
        if signatures:
            feats[j, 2] = z[k, 2]
    ref = dense_gauss_newton(np.concatenate([path.ravel(), feats.ravel()]), controls, dt, meas, R, Q)
    np.testing.assert_allclose(y0, ref, atol=1e-7)
    objective = probslam.eif_objective(controls, dt, meas, result.poses, result.features, R, Q)
    assert result.objective == pytest.approx(objective)
    # Eq. 11.11 is minimal: nudging any coordinate raises it.
    for i in (5, 40, y0.size - 1):
        nudged = y0.copy()
        nudged[i] += 1e-4
        n_poses = len(result.poses)
        assert probslam.eif_objective(controls, dt, meas, nudged[:3 * n_poses].reshape(-1, 3),
                                      nudged[3 * n_poses:].reshape(result.features.shape), R, Q) > objective
    # Covariances are symmetric positive definite (but x_0's).
    cov = result.pose_covariances
    assert np.all(cov[0] == 0)
    np.testing.assert_allclose(cov, np.transpose(cov, (0, 2, 1)), atol=1e-15)
    assert np.all(np.linalg.eigvalsh(cov[1:]) > 0)


def test_graph_slam_accepts_the_path_as_mu_and_scalar_dt():
    controls, dt, meas, poses, _, Q = problem()
    omega_a, xi_a = probslam.eif_construct(controls, 0.5, meas, poses, R, Q)
    feats = probslam._core._eif_initial_features(poses, *meas, int(meas[2].max()) + 1)
    omega_b, xi_b = probslam.eif_construct(controls, dt, meas, np.r_[poses.ravel(), feats.ravel()], R, Q)
    assert (omega_a != omega_b).nnz == 0
    np.testing.assert_array_equal(xi_a, xi_b)


def test_bad_input_raises_clear_errors():
    controls, dt, meas, poses, features, Q = problem()
    time, z, corr = meas
    y = np.r_[poses.ravel(), features.ravel()]
    with pytest.raises(ValueError, match="dt"):
        probslam.eif_initialize(controls, -dt)
    with pytest.raises(ValueError, match="controls"):
        probslam.eif_initialize(np.full((3, 2), np.nan), 0.1)
    with pytest.raises(ValueError, match="controls"):
        probslam.eif_initialize(np.zeros((3, 3)), 0.1)
    bad = z.copy()
    bad[0, 0] = -1
    with pytest.raises(ValueError, match="z"):
        probslam.eif_construct(controls, dt, (time, bad, corr), y, R, Q)
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="z"):
        probslam.graph_slam(controls, dt, (time, bad, corr), R, Q)
    with pytest.raises(ValueError, match="R"):
        probslam.graph_slam(controls, dt, meas, -R, Q)
    with pytest.raises(ValueError, match="Q"):
        probslam.graph_slam(controls, dt, meas, R, np.eye(3))
    with pytest.raises(ValueError, match="time"):
        probslam.graph_slam(controls, dt, (time + 1000, z, corr), R, Q)
    with pytest.raises(ValueError, match="feature 1 is never observed"):
        probslam.graph_slam(controls, dt, (time, z, np.where(corr == 1, 0, corr)), R, Q)
    with pytest.raises(ValueError, match="mu"):
        probslam.eif_construct(controls, dt, meas, y[:-1], R, Q)
    with pytest.raises(TypeError, match="omega"):
        probslam.eif_reduce(np.eye(3), np.zeros(3), 1)
    omega, xi = probslam.eif_construct(controls, dt, meas, y, R, Q)
    with pytest.raises(ValueError, match="xi"):
        probslam.eif_reduce(omega, xi[:-1], len(poses), 2)
    singular = omega.tolil()
    last = omega.shape[0] - 1
    singular[last, :] = 0
    singular[:, last] = 0
    with pytest.raises(ValueError, match="not positive definite"):
        probslam.eif_reduce(singular.tocsc(), xi, len(poses), 2)
