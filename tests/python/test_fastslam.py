"""FastSLAM 1.0 / 2.0 against independent numpy references: the landmark EKF, new landmarks and
weights of version 1, the proposal and weights of version 2, the resampler; map sharing,
threads, bad input, and simulated runs with known and unknown correspondences."""

import copy
import pickle

import numpy as np
import pytest

import probslam as ps
from probslam import _core
from reference import wrap

TWO_PI = 2 * np.pi


# ---- numpy references (written from the equations, not from the C++) ----------------------------
def arrays(landmarks):
    """(ids, means, covariances) of a Landmarks result."""
    return landmarks.ids, landmarks.means, landmarks.covariances


def h(x, m):
    d = m - x[:2]
    return np.array([np.hypot(*d), wrap(np.arctan2(d[1], d[0]) - x[2])])


def jac_landmark(x, m):
    d = m - x[:2]
    q = d @ d
    r = np.sqrt(q)
    return np.array([[d[0] / r, d[1] / r], [-d[1] / q, d[0] / q]])


def jac_pose(x, m):
    return np.hstack([-jac_landmark(x, m), [[0.0], [-1.0]]])


def log_gauss(nu, s):
    nu = np.atleast_1d(nu)
    s = np.atleast_2d(s)
    return float(-0.5 * (nu @ np.linalg.solve(s, nu) + np.log(np.linalg.det(TWO_PI * s))))


def innovation(z, zh):
    nu = np.asarray(z, float) - zh
    nu[1] = wrap(nu[1])
    return nu


def init_landmark(x, z, q):
    """Inverse model; Sigma = H^-1 Q H^-T."""
    r, phi = z
    a = x[2] + phi
    m = x[:2] + r * np.array([np.cos(a), np.sin(a)])
    hinv = np.linalg.inv(jac_landmark(x, m)) if r > 0 else None
    return m, hinv @ q @ hinv.T


def ekf_update(x, m, s, z, q):
    """Version 1's landmark update: returns (m, Sigma, log N(z - z_hat; 0, Q_j))."""
    hm = jac_landmark(x, m)
    qj = hm @ s @ hm.T + q
    k = s @ hm.T @ np.linalg.inv(qj)
    nu = innovation(z, h(x, m))
    return m + k @ nu, (np.eye(2) - k @ hm) @ s, log_gauss(nu, qj)


def proposal_information_form(x_hat, r, m, s, z, q):
    """Sigma_x = (G^T Q_j^-1 G + R^-1)^-1, mu = Sigma_x G^T Q_j^-1 (z - z_hat) + x_hat, weight
    N(z - z_hat; 0, G R G^T + Q_j)."""
    g = jac_pose(x_hat, m)
    hm = jac_landmark(x_hat, m)
    qj = hm @ s @ hm.T + q
    qinv = np.linalg.inv(qj)
    cov = np.linalg.inv(g.T @ qinv @ g + np.linalg.inv(r))
    nu = innovation(z, h(x_hat, m))
    mean = cov @ g.T @ qinv @ nu + x_hat
    return mean, cov, log_gauss(nu, g @ r @ g.T + qj)


def state(f):
    """Everything observable of a filter, to check that a refused call changed nothing."""
    out = [f.poses.copy(), f.log_weights.copy(), f.num_resamples]
    for k in range(f.num_particles):
        ids, means, covs = arrays(f.landmarks(k))
        out += [ids.copy(), means.copy(), covs.copy(), f.path(k).copy()]
    return out


def same_state(a, b):
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


def run_world(seed, landmarks=15, separation=2.5):
    return ps.sim.LandmarkWorld.random(landmarks, 10.0, np.random.default_rng(seed), min_separation=separation).landmarks


def sim_run(seed, steps=150, signatures=False, motion=np.diag([0.003, 0.0005]), clutter=0.0, landmarks=15,
            separation=2.5):
    rng = np.random.default_rng(seed)
    world = ps.sim.LandmarkWorld.random(landmarks, 10.0, rng, min_separation=separation)
    q = np.diag([0.05 ** 2, np.radians(1.0) ** 2] + ([0.05 ** 2] if signatures else []))
    sensor = ps.sim.Sensor(q, max_range=8.0, fov=np.radians(180), signatures=signatures, clutter_rate=clutter)
    run = ps.sim.simulate(world, ps.sim.circle_controls(steps, 1.0, 0.12), 0.2, sensor, motion, rng,
                          initial_pose=(0, -8.3, 0))
    return run, q


# ---- version 1 ------------------------------------------------------------------------------------
@pytest.mark.parametrize("signatures", [False, True])
def test_version1_one_particle_no_noise_equals_bank_of_ekfs(signatures):
    run, q = sim_run(1, steps=120, signatures=signatures, motion=np.zeros((3, 3)))
    p_new = 0.05
    f = ps.FastSlam(np.zeros((3, 3)), q, initial_pose=run.poses[0], num_particles=1, use_signatures=signatures,
                    p_new=p_new)
    bank = {}
    x = np.array(run.poses[0], float)
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        f.predict(v, w, run.dt)
        x = ps.velocity_motion(x, v, w, run.dt)
        np.testing.assert_array_equal(f.poses[0], x)
        np.testing.assert_allclose(x, run.poses[len(f.path(0)) - 1], atol=1e-12)  # the true path
        f.update(z, ids)
        ll = 0.0
        for zi, i in zip(z, ids):
            if i not in bank:
                m, s = init_landmark(x, zi[:2], q[:2, :2])
                bank[i] = [m, s, zi[2] if signatures else 0.0, q[2, 2] if signatures else 0.0]
                ll += np.log(p_new)
            else:
                m, s, sig, sig_var = bank[i]
                m, s, step = ekf_update(x, m, s, zi[:2], q[:2, :2])
                ll += step
                if signatures:
                    ll += log_gauss(zi[2] - sig, sig_var + q[2, 2])
                    gain = sig_var / (sig_var + q[2, 2])
                    sig, sig_var = sig + gain * (zi[2] - sig), (1 - gain) * sig_var
                bank[i] = [m, s, sig, sig_var]
        np.testing.assert_allclose(f.last_log_likelihoods[0], ll, rtol=1e-12, atol=1e-9)
        ids_f, means, covs = arrays(f.landmarks(0))
        assert list(ids_f) == sorted(bank)
        for i, m, s in zip(ids_f, means, covs):
            np.testing.assert_allclose(m, bank[i][0], atol=1e-12, rtol=0)
            np.testing.assert_allclose(s, bank[i][1], atol=1e-12, rtol=1e-12)
            assert np.array_equal(s, s.T)
        if signatures:
            details = f.landmark_details(0)
            np.testing.assert_allclose(details.signature, [bank[i][2] for i in ids_f], atol=1e-12)
            np.testing.assert_allclose(details.signature_var, [bank[i][3] for i in ids_f], atol=1e-15)
    assert len(bank) >= 8


@pytest.mark.slow
def test_version1_weights_of_every_particle():
    run, q = sim_run(2, steps=40)
    r = np.diag([0.01, 0.01, 0.002])
    f = ps.FastSlam(r, q, num_particles=30, initial_pose=run.poses[0], resample_threshold=0.0, seed=3)
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        f.predict(v, w, run.dt)
        before = [arrays(f.landmarks(k)) for k in range(f.num_particles)]
        poses, lw = f.poses.copy(), f.log_weights.copy()
        f.update(z, ids)
        for k in range(f.num_particles):
            lm = {i: (m, s) for i, m, s in zip(*before[k])}
            ll = 0.0
            for zi, i in zip(z, ids):
                if i in lm:
                    m, s, step = ekf_update(poses[k], *lm[i], zi, q)
                    lm[i] = (m, s)
                    ll += step
                else:
                    lm[i] = init_landmark(poses[k], zi, q)
                    ll += np.log(0.01)
            np.testing.assert_allclose(f.last_log_likelihoods[k], ll, rtol=1e-10, atol=1e-9)
            _, means, covs = arrays(f.landmarks(k))
            np.testing.assert_allclose(means, [lm[i][0] for i in sorted(lm)], atol=1e-10)
        expected = lw + f.last_log_likelihoods
        expected -= np.logaddexp.reduce(expected)
        np.testing.assert_allclose(f.log_weights, expected, atol=1e-9)
    assert f.num_resamples == 0


# ---- outlier model (known correspondences) --------------------------------------------------------
@pytest.mark.parametrize("density", [1e-3, 0.05])
def test_outlier_mixture_version1_against_numpy(density):
    """Weight factor N(nu; Q_j) + c per measurement; the landmark is updated only where the
    Gaussian term is the larger one. Every 7th measurement is moved 3 m in range (a gross
    outlier), so both branches are taken."""
    run, q = sim_run(4, steps=80, motion=np.zeros((3, 3)))
    f = ps.FastSlam(np.zeros((3, 3)), q, initial_pose=run.poses[0], num_particles=1, p_new=0.02,
                    outlier_density=density)
    bank, x, count, rejected = {}, np.array(run.poses[0], float), 0, 0
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        f.predict(v, w, run.dt)
        x = ps.velocity_motion(x, v, w, run.dt)
        z = np.array(z, float)
        for j in range(len(z)):
            count += 1
            if count % 7 == 0:
                z[j, 0] += 3.0
        f.update(z, ids)
        ll = 0.0
        for zi, i in zip(z, ids):
            if i not in bank:
                bank[i] = init_landmark(x, zi, q)
                ll += np.log(0.02)
                continue
            m, s, step = ekf_update(x, *bank[i], zi, q)
            ll += np.logaddexp(step, np.log(density))
            if step >= np.log(density):
                bank[i] = (m, s)
            else:
                rejected += 1
        np.testing.assert_allclose(f.last_log_likelihoods[0], ll, rtol=1e-12, atol=1e-9)
        ids_f, means, covs = arrays(f.landmarks(0))
        for i, m, s in zip(ids_f, means, covs):
            np.testing.assert_allclose(m, bank[i][0], atol=1e-12, rtol=0)
            np.testing.assert_allclose(s, bank[i][1], atol=1e-12, rtol=1e-12)
    assert rejected > 0 and count > 2 * rejected


def test_outlier_density_zero_is_the_plain_filter():
    run, q = sim_run(6, steps=30)
    a = ps.FastSlam(np.diag([0.01, 0.01, 0.002]), q, num_particles=20, initial_pose=run.poses[0], seed=2)
    b = ps.FastSlam(np.diag([0.01, 0.01, 0.002]), q, num_particles=20, initial_pose=run.poses[0], seed=2,
                    outlier_density=0.0)
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        for f in (a, b):
            f.predict(v, w, run.dt)
            f.update(z, ids)
    assert same_state(state(a), state(b))


def test_outlier_mixture_version2_leaves_the_proposal_alone():
    """Version 2: a measurement the outlier density explains better at the prior (marginal
    likelihood N(nu; G R G^T + Q_j) < c) neither moves the proposal nor its landmark; its
    weight factor is the mixture of the marginal likelihood and c."""
    q = np.diag([0.05 ** 2, 0.02 ** 2])
    r = np.diag([0.02, 0.02, 0.001])
    density = 1e-2
    for shift, outlier in [(0.0, False), (2.0, True)]:
        f = ps.FastSlam(np.zeros((3, 3)), q, num_particles=1, version=2, outlier_density=density, seed=1)
        f.update([[4.0, 0.3]], [0])
        _, means, covs = arrays(f.landmarks(0))
        delta = np.array([0.5, 0.0, 0.05])
        f.predict_odometry(delta, r)
        x_hat = delta  # from the origin: x (+) delta
        z = h(x_hat, means[0]) + np.array([0.03 + shift, 0.01])
        sampled = f.poses[0].copy()
        f.update([z], [0])
        mean, cov, ll = proposal_information_form(x_hat, r, means[0], covs[0], z, q)
        np.testing.assert_allclose(f.last_log_likelihoods[0], np.logaddexp(ll, np.log(density)), rtol=1e-10)
        assert (ll < np.log(density)) == outlier
        _, after, _ = arrays(f.landmarks(0))
        if outlier:
            np.testing.assert_array_equal(f.poses[0], sampled)  # the motion sample stays
            np.testing.assert_array_equal(after, means)
        else:
            assert not np.array_equal(after, means)


def test_ancestors_follow_resampling():
    run, q = sim_run(3, steps=5)
    f = ps.FastSlam(np.diag([0.05, 0.05, 0.01]), q, num_particles=12, initial_pose=run.poses[0], seed=4)
    (v, w), z, ids = run.controls[0], run.measurements[0], run.ids[0]
    f.predict(v, w, run.dt)
    assert len(f.ancestors) == 0
    f.update(z, ids)
    before = f.poses.copy()
    f.resample()
    a = f.ancestors
    assert a.shape == (12,) and np.all((a >= 0) & (a < 12))
    np.testing.assert_array_equal(f.poses, before[a])
    f.predict(v, w, run.dt)
    assert len(f.ancestors) == 0


# ---- version 2 ------------------------------------------------------------------------------------
def test_proposal_function_equals_information_form():
    rng = np.random.default_rng(5)
    for _ in range(50):
        x = np.array([*rng.uniform(-5, 5, 2), rng.uniform(-np.pi, np.pi)])
        a = rng.normal(size=(3, 3))
        r = a @ a.T * 0.01 + np.eye(3) * 1e-3
        m = x[:2] + rng.uniform(1, 6) * np.array([np.cos(t := rng.uniform(0, TWO_PI)), np.sin(t)])
        b = rng.normal(size=(2, 2))
        s = b @ b.T * 0.05 + np.eye(2) * 1e-3
        q = np.diag([rng.uniform(0.001, 0.05), rng.uniform(1e-4, 1e-2)])
        z = h(x, m) + rng.normal(size=2) * [0.1, 0.05]
        z[0] = abs(z[0])
        mean, cov, ll = _core.fastslam2_proposal(x, r, m, s, z, q)
        ref_mean, ref_cov, ref_ll = proposal_information_form(x, r, m, s, z, q)
        np.testing.assert_allclose(mean[:2], ref_mean[:2], atol=1e-10)
        assert abs(wrap(mean[2] - ref_mean[2])) < 1e-10
        np.testing.assert_allclose(cov, ref_cov, atol=1e-10)
        assert ll == pytest.approx(ref_ll, abs=1e-9)


@pytest.mark.parametrize("two_landmarks", [False, True])
def test_version2_samples_from_the_proposal(two_landmarks):
    """All particles share one prior and map, so they sample one proposal: its mean and covariance
    are checked statistically; the weight (equal for all) exactly."""
    q = np.diag([0.05 ** 2, 0.02 ** 2])
    r = np.diag([0.04, 0.02, 0.01])
    m_count = 4000
    f = ps.FastSlam(r, q, num_particles=m_count, version=2, seed=11, resample_threshold=0.0)
    x0 = np.zeros(3)
    landmarks = np.array([[3.0, 1.0], [1.0, -4.0]])
    z0 = np.array([h(x0, lm) for lm in landmarks])
    f.update(z0, [0, 1])  # no prior yet: landmarks initialised at x0 in every particle
    s0 = [init_landmark(x0, z, q)[1] for z in z0]
    f.predict(1.0, 0.3, 1.0)
    x_hat = ps.velocity_motion(x0, 1.0, 0.3, 1.0)
    z = np.array([[3.0, 0.35], [4.1, -1.6]])[: 2 if two_landmarks else 1]
    f.update(z, [0, 1][: len(z)])
    mean, cov, ll = proposal_information_form(x_hat, r, landmarks[0], s0[0], z[0], q)
    if two_landmarks:  # the first proposal is the prior of the second
        mean, cov, ll2 = proposal_information_form(mean, cov, landmarks[1], s0[1], z[1], q)
        ll += ll2
    np.testing.assert_allclose(f.last_log_likelihoods, ll, atol=1e-9)
    poses = f.poses
    e = poses - mean
    e[:, 2] = wrap(e[:, 2])
    sigma = np.sqrt(np.diag(cov))
    assert np.all(np.abs(e.mean(axis=0)) < 4 * sigma / np.sqrt(m_count))
    np.testing.assert_allclose(np.cov(e.T), cov, atol=0.08 * np.max(np.diag(cov)), rtol=0.1)
    # Landmark updates happen at each particle's sampled pose.
    for k in (0, 1, 2):
        m0, s, _ = ekf_update(poses[k], landmarks[0], s0[0], z[0], q)
        np.testing.assert_allclose(f.landmarks(k).means[0], m0, atol=1e-10)
        np.testing.assert_allclose(f.landmarks(k).covariances[0], s, atol=1e-10)
    # The path's last entry is the proposal sample, not the motion sample.
    np.testing.assert_array_equal(f.path(0)[-1], poses[0])
    assert len(f.path(0)) == 2


def compose(a, d):
    c, s = np.cos(a[2]), np.sin(a[2])
    return np.array([a[0] + c * d[0] - s * d[1], a[1] + s * d[0] + c * d[1], wrap(a[2] + d[2])])


def numeric_jacobian(fn, x, eps=1e-6):
    """Central differences of fn at x (columns: d fn / d x_i), headings wrapped."""
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = eps
        d = np.asarray(fn(x + e)) - np.asarray(fn(x - e))
        if len(d) == 3:
            d[2] = wrap(d[2])
        cols.append(d / (2 * eps))
    return np.array(cols).T


@pytest.mark.parametrize("motion", ["velocity", "odometry"])
def test_version2_proposal_covers_every_motion_since_the_last_update(motion):
    """Several motions between two updates (MRCLAM: ~25 odometry rows per camera frame): the
    proposal's prior is the motions composed from the pose of the last update, with the
    covariance propagated through each (Montemerlo 2003's p(s_t | s_{t-n}, u_{t-n+1..t}, z_t)),
    not the last motion's alone. Checked against a numpy composition with numeric Jacobians: the
    weight exactly, the sampled poses statistically, and the path: the poses since the last update
    are the prior's means bridged linearly to the sample."""
    q = np.diag([0.05 ** 2, 0.02 ** 2])
    r = np.diag([0.004, 0.002, 0.003])
    m_count = 4000
    f = ps.FastSlam(r, q, num_particles=m_count, version=2, seed=5, resample_threshold=0.0)
    x0 = np.zeros(3)
    lm = np.array([4.0, 1.5])
    f.update([h(x0, lm)], [0])  # every particle places the landmark from x0
    s0 = init_landmark(x0, h(x0, lm), q)[1]
    mean, cov, chain = x0.copy(), np.zeros((3, 3)), []
    for k in range(5):
        if motion == "velocity":
            v, w, dt = 0.4, 0.1 * (k - 2), 0.5
            f.predict(v, w, dt)
            step = lambda x: ps.velocity_motion(x, v, w, dt)  # noqa: E731
            g, noise = numeric_jacobian(step, mean), r
        else:
            delta = np.array([0.3, 0.02, 0.05 * (k - 2)])
            f.predict_odometry(delta, r)
            step = lambda x: compose(x, delta)  # noqa: E731
            jd = numeric_jacobian(lambda d: compose(mean, d), delta)
            g, noise = numeric_jacobian(step, mean), jd @ r @ jd.T
        mean, cov = np.asarray(step(mean)), g @ cov @ g.T + noise
        chain.append(mean)
    z = h(mean, lm) + np.array([0.05, -0.03])
    f.update([z], [0])
    post_mean, post_cov, ll = proposal_information_form(mean, cov, lm, s0, z, q)
    np.testing.assert_allclose(f.last_log_likelihoods, ll, atol=1e-9)
    e = f.poses - post_mean
    e[:, 2] = wrap(e[:, 2])
    sigma = np.sqrt(np.diag(post_cov))
    assert np.all(np.abs(e.mean(axis=0)) < 4 * sigma / np.sqrt(m_count))
    np.testing.assert_allclose(np.cov(e.T), post_cov, atol=0.08 * np.max(np.diag(post_cov)), rtol=0.1)
    for k in (0, 7):
        path, x = f.path(k), f.poses[k]
        shift = x - chain[-1]
        shift[2] = wrap(shift[2])
        bridged = np.array([c + shift * (i + 1) / len(chain) for i, c in enumerate(chain)])
        bridged[:, 2] = wrap(bridged[:, 2])
        np.testing.assert_allclose(path[0], x0, atol=0)
        np.testing.assert_allclose(path[1:], bridged, atol=1e-9)


def test_version2_control_noise_prior_is_singular_but_works():
    q = np.diag([0.05 ** 2, 0.02 ** 2])
    mctl = np.diag([0.01, 0.004])
    f = ps.FastSlam(mctl, q, num_particles=500, version=2, seed=2, resample_threshold=0.0)
    f.update([[3.0, 0.3]], [0])
    f.predict(1.0, 0.2, 1.0)
    f.update([[2.2, 0.15]], [0])
    assert np.all(np.isfinite(f.poses)) and np.all(np.isfinite(f.last_log_likelihoods))
    x0 = np.zeros(3)
    v = ps.velocity_motion_control_jacobian(x0, 1.0, 0.2, 1.0)
    r = v @ mctl @ v.T
    m, s = init_landmark(x0, [3.0, 0.3], q)
    g = jac_pose(ps.velocity_motion(x0, 1.0, 0.2, 1.0), m)
    hm = jac_landmark(ps.velocity_motion(x0, 1.0, 0.2, 1.0), m)
    nu = innovation([2.2, 0.15], h(ps.velocity_motion(x0, 1.0, 0.2, 1.0), m))
    np.testing.assert_allclose(f.last_log_likelihoods, log_gauss(nu, g @ r @ g.T + hm @ s @ hm.T + q), atol=1e-9)


# ---- resampling and map sharing ---------------------------------------------------------------------
def test_resampler_counts_floor_or_ceil():
    rng = np.random.default_rng(0)
    for m in [1, 2, 7, 50, 333]:
        for _ in range(20):
            w = rng.random(m) ** 4
            w /= w.sum()
            idx = _core.low_variance_resample(w, rng.random())
            counts = np.bincount(idx, minlength=m)
            assert counts.sum() == m
            assert np.all(counts >= np.floor(m * w - 1e-9)) and np.all(counts <= np.ceil(m * w + 1e-9))
    with pytest.raises(ValueError, match="^offset"):
        _core.low_variance_resample([0.5, 0.5], 1.0)
    with pytest.raises(ValueError, match="^weights"):
        _core.low_variance_resample([np.nan, 0.5], 0.2)


def test_resampling_copies_maps_in_constant_time():
    run, q = sim_run(3, steps=60)
    f = ps.FastSlam(np.diag([0.01, 0.01, 0.002]), q, num_particles=100, initial_pose=run.poses[0], seed=1)
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        f.predict(v, w, run.dt)
        f.update(z, ids)
    assert f.num_resamples > 0
    sharing = f.map_sharing
    assert sharing.total_nodes == 2 * sharing.landmarks
    assert sharing.distinct_nodes < sharing.total_nodes / 2  # resampled particles share nodes
    nodes = _core._persistent_tree_nodes()
    f.resample()
    assert _core._persistent_tree_nodes() <= nodes  # copies allocate no node
    # No particle sees another's change: update one particle's landmarks, compare the others.
    before = [arrays(f.landmarks(k)) for k in range(f.num_particles)]
    g = f.copy()
    g.predict(1.0, 0.1, 0.2)
    g.update(run.measurements[-1], run.ids[-1])
    after = [arrays(f.landmarks(k)) for k in range(f.num_particles)]
    for a, b in zip(before, after):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


def test_ancestors_follow_the_resampling():
    run, q = sim_run(3, steps=40)
    f = ps.FastSlam(np.diag([0.01, 0.01, 0.002]), q, num_particles=50, initial_pose=run.poses[0], seed=4)
    seen = 0
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        f.predict(v, w, run.dt)
        before = f.poses
        f.update(z, ids)
        a = f.ancestors
        if not f.resampled:
            assert a.shape == (0,)
            continue
        seen += 1
        assert a.shape == (50,) and a.min() >= 0 and a.max() < 50 and np.all(np.diff(a) >= 0)
        # Known correspondences in version 1 leave the poses alone: each particle is its ancestor's.
        np.testing.assert_array_equal(f.poses, before[a])
    assert seen > 0
    weights = f.weights
    f.resample()
    assert f.resampled and f.ancestors.shape == (50,)
    counts = np.bincount(f.ancestors, minlength=50)
    assert np.all(np.abs(counts - 50 * weights) < 1.0 + 1e-9)  # floor or ceil of M w


@pytest.mark.slow
def test_threads_give_identical_results():
    run, q = sim_run(4, steps=80, clutter=0.3)
    results = []
    for threads in (1, 2, 3):
        f = ps.FastSlam(np.diag([0.003, 0.0005]), q, num_particles=64, version=2, threads=threads, seed=9,
                        initial_pose=run.poses[0], negative_information=True, sensor_range=8.0,
                        sensor_fov=np.radians(180))
        assoc = []
        for t, ((v, w), z) in enumerate(zip(run.controls, run.measurements)):
            f.predict(v, w, run.dt)
            assoc.append(f.update_unknown(z).ids)
            if t % 20 == 19:
                f.resample()  # the explicit resampling, on the workers too
        results.append((state(f), assoc))
    assert results[0][0][2] > 0  # it resampled
    for other in results[1:]:
        assert same_state(results[0][0], other[0])
        assert all(np.array_equal(a, b) for a, b in zip(results[0][1], other[1]))


# ---- simulated runs ---------------------------------------------------------------------------------
@pytest.mark.parametrize("version", [1, 2])
@pytest.mark.parametrize("unknown", [False, True])
def test_simulated_run_tracks_the_true_pose(version, unknown):
    run, q = sim_run(6, steps=250, landmarks=25, separation=2.0)
    m = np.diag([0.003, 0.0005])
    ekf = ps.EkfSlam(m, q, use_signatures=False, initial_pose=run.poses[0])
    f = ps.FastSlam(m, q, num_particles=100, version=version, seed=5, initial_pose=run.poses[0], p_new=1e-3)
    errors, sigmas, ekf_errors = [], [], []
    for t, ((v, w), z, ids) in enumerate(zip(run.controls, run.measurements, run.ids)):
        f.predict(v, w, run.dt)
        ekf.predict(v, w, run.dt)
        ekf.update(z, ids)
        if unknown:
            got = f.update_unknown(z).ids
            assert all(len(set(row)) == len(row) for row in got)  # one measurement per landmark
        else:
            f.update(z, ids)
        errors.append(ps.sim.pose_error(f.mean_pose, run.poses[t + 1]))
        sigmas.append(np.sqrt(np.diag(f.pose_covariance)))
        ekf_errors.append(ps.sim.pose_error(ekf.pose, run.poses[t + 1]))
    errors, sigmas, ekf_errors = np.abs(np.array(errors)), np.array(sigmas), np.abs(np.array(ekf_errors))
    # Within a few sigma (plus a floor: 100 particles collapse after resampling), and as close to
    # the truth as EKF SLAM on the same run (both share the map's unobservable drift).
    inside = np.all(errors <= 4 * sigmas + np.array([0.05, 0.05, 0.01]), axis=1)
    assert inside.mean() > 0.85, inside.mean()
    rms = np.sqrt(np.mean(errors[:, :2] ** 2))
    assert rms < 2 * np.sqrt(np.mean(ekf_errors[:, :2] ** 2)) + 0.05, rms
    assert np.max(errors[:, :2]) < 0.4
    # The best particle's map: one landmark per landmark seen, each near its true position.
    seen = sorted({i for ids in run.ids for i in ids})
    ids, means, _ = arrays(f.landmarks(f.best_index))
    assert len(ids) == len(seen)
    world = run_world(6, 25, 2.0)
    nearest = [int(np.argmin(np.hypot(*(world - mean).T))) for mean in means]
    assert sorted(nearest) == seen
    assert max(np.min(np.hypot(*(world - mean).T)) for mean in means) < 0.4
    path = f.path()
    assert path.shape == (len(run.controls) + 1, 3)
    assert np.max(np.hypot(*(path[:, :2] - run.poses[:, :2]).T)) < 0.6


def test_version2_one_particle_localises_where_version1_drifts():
    """Large motion noise, an accurate sensor: one particle of FastSLAM 2.0 follows the
    measurements (its proposal is an EKF step), one of FastSLAM 1.0 is a random walk."""
    rms = {1: [], 2: []}
    for seed in range(4):
        rng = np.random.default_rng(seed)
        world = ps.sim.LandmarkWorld.random(25, 10.0, rng, min_separation=2.0)
        q = np.diag([0.02 ** 2, np.radians(0.5) ** 2])
        r = np.diag([0.05 ** 2, 0.05 ** 2, 0.03 ** 2])
        sensor = ps.sim.Sensor(q, max_range=8.0, fov=np.radians(180))
        run = ps.sim.simulate(world, ps.sim.circle_controls(100, 1.0, 0.12), 0.2, sensor, r, rng,
                              initial_pose=(0, -8.3, 0))
        for version in (1, 2):
            f = ps.FastSlam(r, q, num_particles=1, version=version, seed=seed, initial_pose=run.poses[0])
            errors = []
            for t, ((v, w), z, ids) in enumerate(zip(run.controls, run.measurements, run.ids)):
                f.predict(v, w, run.dt)
                f.update(z, ids)
                errors.append(ps.sim.pose_error(f.poses[0], run.poses[t + 1]))
            rms[version].append(np.sqrt(np.mean(np.array(errors)[:, :2] ** 2)))
    assert np.mean(rms[2]) < 0.5 and np.mean(rms[1]) > 3 * np.mean(rms[2]), rms


def test_negative_information_removes_a_spurious_landmark():
    q = np.diag([0.05 ** 2, 0.02 ** 2])
    f = ps.FastSlam(np.zeros((3, 3)), q, num_particles=5, negative_information=True, sensor_range=10.0,
                    sensor_fov=np.radians(180), p_new=1e-3)
    real = [[4.0, 0.0]]
    f.update_unknown(np.array(real + [[5.0, 0.8]]))  # the second is clutter
    assert len(f.landmarks(0)) == 2
    removed = f.update_unknown(np.array(real)).removed
    assert len(f.landmarks(0)) == 2 and removed.shape == (0, 2)  # existence 1 -> 0
    r = f.update_unknown(np.array(real))
    assert len(f.landmarks(0)) == 1 and r.removed.tolist() == [[j, 1] for j in range(5)]
    assert list(r.ids[:, 0]) == [0] * 5 and not r.is_new.any()
    np.testing.assert_array_equal(f.landmark_details(0).existence, [3.0])
    # A landmark behind the robot (outside the field of view) is not penalised.
    g = ps.FastSlam(np.zeros((3, 3)), q, num_particles=1, negative_information=True, sensor_range=10.0,
                    sensor_fov=np.radians(180))
    g.update_unknown(np.array([[3.0, 3.0]]))
    for _ in range(3):
        g.update_unknown(np.empty((0, 2)))
    assert g.num_landmarks == len(g.landmarks(0)) == 1


def test_unknown_association_takes_one_measurement_per_landmark():
    q = np.diag([0.05 ** 2, 0.02 ** 2])
    f = ps.FastSlam(np.zeros((3, 3)), q, num_particles=3, p_new=1e-4)
    f.update_unknown(np.array([[4.0, 0.0]]))
    r = f.update_unknown(np.array([[4.01, 0.0], [4.0, 0.001]]))
    ids, is_new = r.ids, r.is_new
    # The closer measurement takes landmark 0; the other cannot and becomes new.
    assert list(ids[0]) == [1, 0] and list(is_new[0]) == [True, False]



def brute_force_association(x, p, landmarks, z, q, log_p_new):
    """Every assignment of the scan's measurements to distinct landmarks (those whose marginal
    log-likelihood at the prior exceeds log p_new) or to new ones, scored as the filter defines
    it: version 2 (p != 0) by the chain rule, measurements taken in order of their best marginal
    (the proposal of each the prior of the next, proposal_information_form); version 1 (p = 0) by
    the sum of the independent terms. Returns (best ids with -1 for new, best score)."""
    import itertools
    means, covs = landmarks
    marginal = np.full((len(z), len(means)), -np.inf)
    for i, zi in enumerate(z):
        for j, (m, s) in enumerate(zip(means, covs)):
            hm, g = jac_landmark(x, m), jac_pose(x, m)
            marginal[i, j] = log_gauss(innovation(zi, h(x, m)), hm @ s @ hm.T + q + g @ p @ g.T)
    options = [[-1] + [j for j in range(len(means)) if marginal[i, j] > log_p_new] for i in range(len(z))]
    best_first = np.array([max([log_p_new] + [marginal[i, j] for j in options[i][1:]]) for i in range(len(z))])
    order = sorted(range(len(z)), key=lambda i: -best_first[i])  # stable, as the filter's
    best, best_score = None, -np.inf
    for choice in itertools.product(*options):
        used = [j for j in choice if j >= 0]
        if len(used) != len(set(used)):
            continue
        mean, cov, score = x.copy(), p.copy(), 0.0
        for i in order:
            j = choice[i]
            if j < 0:
                score += log_p_new
            elif not p.any():
                score += marginal[i, j]
            else:
                mean, cov, ll = proposal_information_form(mean, cov, means[j], covs[j], z[i], q)
                score += ll
        if score > best_score + 1e-12:
            best, best_score = choice, score
    return list(best), best_score


def clustered_scan(rng, landmarks, x, q, k):
    """k measurements of landmarks drawn (with repeats: two sightings may claim one landmark)
    from a cluster, with the sensor's noise doubled so that assignments conflict."""
    picks = rng.choice(len(landmarks), size=k)
    return np.array([h(x, landmarks[j]) + 2 * rng.normal(size=2) * np.sqrt(np.diag(q)) for j in picks])


@pytest.mark.parametrize("version", [1, 2])
def test_joint_association_is_the_brute_force_optimum(version):
    """update_unknown's joint association against an exhaustive search written from its
    definition: on scans of a tight cluster (landmarks 0.2 m apart, three to five sightings, some
    of one landmark) the ids chosen and the weight factor equal the brute-force optimum's; the
    greedy association (best pairs first) differs on some of them, so the test can tell."""
    q = np.diag([0.1 ** 2, 0.03 ** 2])
    r = np.diag([0.01, 0.01, 0.002])
    log_p_new = np.log(1e-2)
    rng = np.random.default_rng(4)
    cluster = np.array([[4.0, 0.0], [4.0, 0.2], [4.2, 0.1], [3.8, -0.2], [4.3, -0.15]])
    x0 = np.zeros(3)
    differs = 0
    for trial in range(25):
        made = []
        for joint in (True, False):
            f = ps.FastSlam(r if version == 2 else np.zeros((3, 3)), q, num_particles=1, version=version, seed=trial,
                            p_new=1e-2, joint_association=joint)
            f.update_unknown(np.array([h(x0, m) for m in cluster]))  # ids 0-4 at the cluster, exactly
            if version == 2:
                f.predict(0.0, 0.0, 1.0)  # the prior N(x0, r): the proposal's uncertainty
            made.append(f)
        lm = made[0].landmarks()
        z = clustered_scan(rng, cluster, x0, q, int(rng.integers(3, 6)))
        results = [g.update_unknown(z) for g in made]
        ids, score = brute_force_association(x0, r if version == 2 else np.zeros((3, 3)), (lm.means, lm.covariances),
                                             z, q, log_p_new)
        got = [int(i) if not new else -1 for i, new in zip(results[0].ids[0], results[0].is_new[0])]
        assert got == ids, trial
        # The weight factor: the matched sightings' log-likelihood (version 2: the chain's) plus
        # log p_new per new landmark.
        np.testing.assert_allclose(made[0].last_log_likelihoods[0], score, atol=1e-9)
        greedy = [int(i) if not new else -1 for i, new in zip(results[1].ids[0], results[1].is_new[0])]
        differs += greedy != ids
    assert differs >= 3, differs


# ---- bad input --------------------------------------------------------------------------------------
def make_filter():
    run, q = sim_run(7, steps=8)
    f = ps.FastSlam(np.diag([0.01, 0.01, 0.002]), q, num_particles=6, version=2, initial_pose=run.poses[0])
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        f.predict(v, w, run.dt)
        f.update(z, ids)
    return f


@pytest.mark.parametrize("kwargs, err, name", [
    (dict(num_particles=0), ValueError, "num_particles"),
    (dict(num_particles=-4), ValueError, "num_particles"),
    (dict(motion_noise=-np.eye(3)), ValueError, "motion_noise"),
    (dict(motion_noise=np.eye(4)), ValueError, "motion_noise"),
    (dict(motion_noise=np.full((3, 3), np.nan)), ValueError, "motion_noise"),
    (dict(measurement_noise=np.zeros((2, 2))), ValueError, "measurement_noise"),
    (dict(measurement_noise=np.eye(3)), ValueError, "measurement_noise"),
    (dict(version=3), ValueError, "version"),
    (dict(version=0), ValueError, "version"),
    (dict(threads=0), ValueError, "threads"),
    (dict(seed=-1), ValueError, "seed"),
    (dict(p_new=0.0), ValueError, "p_new"),
    (dict(p_new=np.inf), ValueError, "p_new"),
    (dict(outlier_density=-1e-3), ValueError, "outlier_density"),
    (dict(outlier_density=np.nan), ValueError, "outlier_density"),
    (dict(outlier_density=np.inf), ValueError, "outlier_density"),
    (dict(initial_pose=(0, np.nan, 0)), ValueError, "initial_pose"),
    (dict(initial_pose=(0, 0)), ValueError, "initial_pose"),
    (dict(resample_threshold=-0.1), ValueError, "resample_threshold"),
    (dict(cell_size=0.0), ValueError, "cell_size"),
    (dict(negative_information=True), ValueError, "sensor_range"),
    (dict(version="1"), TypeError, "version"),
    (dict(use_signatures=1), TypeError, "use_signatures"),
    (dict(bogus=1), TypeError, "FastSlam\\(\\) got an unexpected keyword argument 'bogus'"),
    (dict(bearing_offset_sigma=-0.01), ValueError, "bearing_offset_sigma"),
    (dict(bearing_offset_sigma=np.nan), ValueError, "bearing_offset_sigma"),
    (dict(bearing_offset_sigma=4.0), ValueError, "bearing_offset_sigma"),
    (dict(bearing_offset_correlation=1.0), ValueError, "bearing_offset_correlation"),
    (dict(bearing_offset_correlation=-0.1), ValueError, "bearing_offset_correlation"),
    (dict(bearing_offset_correlation=np.inf), ValueError, "bearing_offset_correlation"),
])
def test_bad_construction(kwargs, err, name):
    args = dict(num_particles=4, motion_noise=np.eye(3) * 0.01, measurement_noise=np.eye(2) * 0.01)
    args.update(kwargs)
    with pytest.raises(err, match="^" + name):
        ps.FastSlam(args.pop("motion_noise"), args.pop("measurement_noise"), **args)
    fields = {k: v for k, v in kwargs.items() if k not in ("motion_noise", "measurement_noise", "initial_pose")}
    if fields and "bogus" not in fields:
        # The same refusal by the options object alone, and by a filter given it: the field's name.
        with pytest.raises(err, match="^" + name):
            ps.FastSlamOptions(**fields)
        options = ps.FastSlamOptions()
        with pytest.raises(err, match="^" + name):
            for field, value in fields.items():
                setattr(options, field, value)  # types (and a seed's sign) as set, ranges by validate()
            ps.FastSlam(np.eye(3) * 0.01, np.eye(2) * 0.01, options=options)


@pytest.mark.parametrize("call, err, name", [
    (lambda f: f.predict(1.0, 0.0, 0.0), ValueError, "dt"),
    (lambda f: f.predict(np.nan, 0.0, 1.0), ValueError, "v"),
    (lambda f: f.predict(1.0, np.inf, 1.0), ValueError, "w"),
    (lambda f: f.predict(2e9, 0.0, 1.0), ValueError, "v"),
    (lambda f: f.predict_odometry([1.0, 0.0, np.nan], np.eye(3)), ValueError, "delta"),
    (lambda f: f.predict_odometry([1.0, 0.0], np.eye(3)), ValueError, "delta"),
    (lambda f: f.predict_odometry([1.0, 0.0, 0.0], -np.eye(3)), ValueError, "noise"),
    (lambda f: f.predict_odometry([1.0, 0.0, 0.0], np.eye(2)), ValueError, "noise"),
    (lambda f: f.update([[-1.0, 0.0]], [0]), ValueError, "z"),
    (lambda f: f.update([[np.nan, 0.0]], [0]), ValueError, "z"),
    (lambda f: f.update([[1.0, np.inf]], [0]), ValueError, "z"),
    (lambda f: f.update([[1.0, 0.0, 1.0]], [0]), ValueError, "z"),
    (lambda f: f.update([[1.0, 0.0], [2.0, 0.0]], [0]), ValueError, "ids"),
    (lambda f: f.update([[1.0, 0.0]], [-3]), ValueError, "ids"),
    (lambda f: f.update([[1.0, 0.0]], [1.5]), TypeError, "ids"),
    (lambda f: f.update([[1e10, 0.0]], [0]), ValueError, "z"),
    (lambda f: f.update_unknown([[1.0, 0.0], [-2.0, 0.0]]), ValueError, "z"),
    (lambda f: f.update_unknown([[1.0, 0.0]], p_new=-1.0), ValueError, "p_new"),
    (lambda f: f.update_unknown(None), TypeError, "z"),
    (lambda f: f.path(6), ValueError, "particle"),
    (lambda f: f.landmarks(-1), ValueError, "particle"),
    (lambda f: f.landmarks(1.0), TypeError, "particle"),
    (lambda f: f.landmark_details(2**70), ValueError, "particle"),
])
def test_bad_calls_raise_and_change_nothing(call, err, name):
    f = make_filter()
    before = state(f)
    with pytest.raises(err, match="^" + name):
        call(f)
    assert same_state(before, state(f))


# ---- the scan's bearing offset (bearing_offset_sigma) --------------------------------------------
def test_bearing_offset_corrects_each_particles_bearings():
    """A new landmark is the inverse model of the bearing minus the particle's own offset, its
    weight and covariance those of the corrected measurement (numpy reference)."""
    q = np.diag([0.05 ** 2, 0.01 ** 2])
    x0 = np.array([1.0, -2.0, 0.4])
    f = ps.FastSlam(np.zeros((3, 3)), q, num_particles=50, initial_pose=x0, seed=3, resample_threshold=0.0,
                    bearing_offset_sigma=0.05)
    first = f.bearing_offsets.copy()
    assert np.all(first != 0.0) and len(set(first)) == 50  # each particle its own stationary draw
    z = np.array([[3.0, 0.3], [2.0, -0.8]])
    f.update(z, [7, 8])
    b = f.bearing_offsets
    for k in range(50):
        ids, means, covs = arrays(f.landmarks(k))
        for row, i in enumerate(ids):
            zc = np.array([z[i - 7, 0], wrap(z[i - 7, 1] - b[k])])
            m, s = init_landmark(x0, zc, q)
            assert np.allclose(means[row], m, atol=1e-12) and np.allclose(covs[row], s, atol=1e-12)
    # A second scan of the same landmarks: each particle's weight is the likelihood of its own
    # corrected bearings against its landmarks (version 1's weight, numpy).
    f.update(z + [[0.02, 0.01], [0.0, 0.012]], [7, 8])
    assert np.all(f.bearing_offsets != b)  # a new offset per scan (correlation 0)


def test_bearing_offset_follows_its_ar1_transition():
    """Stationary N(0, sigma^2) and lag-one correlation rho from one update to the next, over
    4000 particles (no resampling): the sample moments within 5 standard errors."""
    sigma, rho, m = 0.03, 0.8, 4000
    f = ps.FastSlam(np.zeros((3, 3)), np.diag([0.1, 0.1]), num_particles=m, seed=5, resample_threshold=0.0,
                    bearing_offset_sigma=sigma, bearing_offset_correlation=rho)
    prev = f.bearing_offsets.copy()
    f.update([[2.0, 0.0]], [0])
    now = f.bearing_offsets
    se = 1.0 / np.sqrt(m)
    assert abs(np.std(now) / sigma - 1.0) < 5 * se
    assert abs(np.corrcoef(prev, now)[0, 1] - rho) < 5 * se
    g = ps.FastSlam(np.zeros((3, 3)), np.diag([0.1, 0.1]), num_particles=4, seed=5)
    g.update([[2.0, 0.0]], [0])
    assert np.all(g.bearing_offsets == 0.0)  # without the model: no offset, no random draw


@pytest.mark.slow
def test_bearing_offset_is_tracked_and_improves_the_map():
    """A robot turning on the spot sees 6 landmarks; every scan's bearings share an AR(1) offset
    (0.03 rad, rho 0.9) on top of 0.002 rad noise. With the model the particles' weighted
    offset follows the truth (relative to the first scan's, which the map absorbs), and the
    heading estimate is better than that of a filter that treats the offset as noise."""
    rng = np.random.default_rng(11)
    marks = np.array([[4.0, 0.0], [0.0, 3.0], [-3.5, 0.5], [0.5, -4.0], [2.5, 2.5], [-2.0, -2.5]])
    sigma_b, rho, sigma_phi, steps = 0.03, 0.9, 0.002, 150
    truth_b = [rng.normal(0.0, sigma_b)]
    for _ in range(steps - 1):
        truth_b.append(rho * truth_b[-1] + np.sqrt(1 - rho ** 2) * sigma_b * rng.normal())
    motion = np.diag([1e-6, 1e-6, 0.002 ** 2])
    q_model = np.diag([0.01 ** 2, sigma_phi ** 2])
    q_plain = np.diag([0.01 ** 2, sigma_phi ** 2 + sigma_b ** 2])
    with_model = ps.FastSlam(motion, q_model, num_particles=300, version=2, seed=1, bearing_offset_sigma=sigma_b,
                             bearing_offset_correlation=rho)
    plain = ps.FastSlam(motion, q_plain, num_particles=300, version=2, seed=1)
    heading, est_b, err = 0.0, [], {id(with_model): [], id(plain): []}
    for t in range(steps):
        heading = wrap(heading + 0.05)
        z = np.array([h(np.array([0.0, 0.0, heading]), mk) for mk in marks])
        z[:, 0] += rng.normal(0.0, 0.01, len(z))
        z[:, 1] = wrap(z[:, 1] + truth_b[t] + rng.normal(0.0, sigma_phi, len(z)))
        for f in (with_model, plain):
            if t:
                f.predict_odometry([0.0, 0.0, 0.05], motion)
            f.update(z, np.arange(len(marks)))
            err[id(f)].append(wrap(f.mean_pose[2] - heading))
        est_b.append(float(np.sum(with_model.weights * with_model.bearing_offsets)))
    # The map is built in the first scan's frame, so offsets and headings are known up to a
    # constant: compare their changes (the de-meaned heading errors, the offsets relative to the
    # first scan's).
    rel_truth = np.array(truth_b[10:]) - truth_b[0]
    rel_est = np.array(est_b[10:]) - est_b[0]
    assert np.corrcoef(rel_truth, rel_est)[0, 1] > 0.8  # 0.89 - 0.97 over seeds 11 - 14
    e_model, e_plain = (np.array(err[id(f)][10:]) for f in (with_model, plain))
    assert np.std(e_model) < 0.7 * np.std(e_plain)  # 0.46 - 0.51 over seeds 11 - 14


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("version", [1, 2])
def test_a_motion_some_particles_cannot_take_changes_nothing(threads, version):
    """Particles move in place; when one particle's sample would leave the +-1e9 m world, the call
    raises and every particle already moved is put back (pose, prior, random stream, path): the
    filter then continues exactly as an untouched copy does. Several seeds, so that particles
    before the first refused one have moved (with one thread, the first particle may be it)."""
    edge = 1e9 - 0.5
    for seed in range(4, 10):
        f = ps.FastSlam(np.eye(3) * 1e-4, np.diag([0.01, 0.001]), num_particles=64, version=version, threads=threads,
                        initial_pose=(edge, 0.0, 0.0), seed=seed)
        f.predict_odometry([0.1, 0.0, 0.0], np.diag([1e-4, 1e-4, 1e-4]))
        g = f.copy()
        with pytest.raises(ValueError, match="^delta.*beyond"):
            f.predict_odometry([0.3, 0.0, 0.0], np.diag([0.09, 1e-4, 1e-4]))  # about half cross the edge
        with pytest.raises(ValueError, match="^v.*beyond"):
            f.predict(0.4, 0.0, 1.0)  # additive pose noise 1e-2 m: some particles cross, some do not
        for h in (f, g):
            h.predict_odometry([-0.2, 0.0, 0.01], np.diag([1e-4, 1e-4, 1e-4]))
            h.update([[5.0, 0.2]], [3])
        assert same_state(state(f), state(g)), seed


def test_python_threads_sharing_one_filter_lose_no_call():
    """Four Python threads call one filter (with its own two workers) at once: every call is
    serialised by the filter's lock, so each particle's path holds exactly one pose per motion
    and the weights stay normalised; reads in between see whole states."""
    import threading
    f = ps.FastSlam(np.diag([0.003, 0.0005]), np.diag([0.05 ** 2, 0.01 ** 2]), num_particles=40, threads=2, seed=3)
    errors, motions = [], 40

    def work(t):
        try:
            rng = np.random.default_rng(t)
            for _ in range(motions):
                f.predict(1.0, 0.1, 0.1)
                z = np.column_stack([rng.uniform(1, 8, 2), rng.uniform(-1, 1, 2)])
                if t % 2:
                    f.update(z, [10 * t, 10 * t + 1])
                else:
                    f.update_unknown(z)
                poses, lw = f.poses, f.log_weights
                assert poses.shape == (40, 3) and np.isclose(np.logaddexp.reduce(lw), 0.0)
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(repr(e))

    threads = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert all(len(f.path(k)) == 1 + 4 * motions for k in range(40))
    assert np.isclose(np.logaddexp.reduce(f.log_weights), 0.0)


def test_options_object_keywords_and_state_agree(tmp_path):
    """One FastSlamOptions, three ways in: the **fields sugar, the object, and the object with a
    keyword replacing one of its fields give the same filter (options, bytes, run); .options
    returns it typed, and save / load and pickle keep it with the noise and the start pose."""
    r, q, x0 = np.diag([0.01, 0.01, 0.002]), np.diag([0.01, 0.001]), (1.0, 2.0, 0.5)
    fields = dict(num_particles=12, version=2, seed=9, p_new=2e-3, min_sightings=2, provisional_max_age=5,
                  association_radius=1.5, cell_size=1.5, joint_association=False, resample_threshold=0.8)
    options = ps.FastSlamOptions(**fields)
    by_fields = ps.FastSlam(r, q, initial_pose=x0, **fields)
    by_object = ps.FastSlam(r, q, initial_pose=x0, options=options)
    replaced = ps.FastSlam(r, q, initial_pose=x0, options=options.replace(seed=1), seed=9)
    assert options.seed == 9  # replace() and the keyword leave the given object alone
    for f in (by_fields, by_object, replaced):
        assert isinstance(f.options, ps.FastSlamOptions) and f.options == options
        assert f.num_particles == 12 and f.version == 2
    default = ps.FastSlam(r, q)
    assert default.options == ps.FastSlamOptions() and default.options != options
    assert default.num_particles == ps.FastSlamOptions().num_particles == 100
    z = np.array([[5.0, 0.1], [3.0, -0.5]])
    for f in (by_fields, by_object, replaced):
        for _ in range(4):
            f.predict(1.0, 0.1, 0.5)
            f.update_unknown(z + 0.01)
    assert by_fields.__getstate__() == by_object.__getstate__() == replaced.__getstate__()

    by_fields.save(tmp_path / "f.psl")
    for back in (ps.FastSlam.load(tmp_path / "f.psl"), pickle.loads(pickle.dumps(by_fields))):
        assert back.options == options
        assert np.array_equal(back.motion_noise, r) and np.array_equal(back.measurement_noise, q)
        assert np.array_equal(back.initial_pose, x0)
        assert back.__getstate__() == by_fields.__getstate__()
    assert pickle.loads(pickle.dumps(options)) == options
    assert copy.deepcopy(options) == options and options.copy() is not options
