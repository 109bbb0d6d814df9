"""EKF SLAM: equality with a dense numpy Table 10.1, structure, association, bad input."""

import numpy as np
import pytest

import probslam as ps
from ekf_reference import DenseEkfSlam, full_state
from reference import wrap

EXACT = 1e-9  # the sparse and dense forms differ only by rounding


def random_sequence(rng, signatures, steps=40, n_landmarks=12):
    world = ps.sim.LandmarkWorld.random(n_landmarks, 8.0, rng)
    q = np.diag([0.05 ** 2, 0.02 ** 2] + ([0.1 ** 2] if signatures else []))
    sensor = ps.sim.Sensor(q, max_range=9.0, fov=np.radians(240), signatures=signatures)
    controls = np.column_stack([rng.uniform(0.2, 1.5, steps), rng.uniform(-0.6, 0.6, steps)])
    controls[::7, 1] = 0.0  # straight segments too
    run = ps.sim.simulate(world, controls, 0.3, sensor, np.diag([0.02, 0.01]), rng, initial_pose=(0, 0, 0.3))
    return run, q


@pytest.mark.parametrize("signatures", [False, True])
@pytest.mark.parametrize("noise", ["pose", "control"])
@pytest.mark.parametrize("seed", range(3))
def test_filter_equals_dense_numpy_table_10_1(signatures, noise, seed):
    rng = np.random.default_rng(seed)
    run, q = random_sequence(rng, signatures)
    r = np.diag([0.01, 0.01, 0.004]) if noise == "pose" else np.diag([0.03, 0.02])
    p0 = np.diag([0.01, 0.02, 0.003])
    ekf = ps.EkfSlam(r, q, use_signatures=signatures, initial_pose=(0, 0, 0.3), initial_pose_cov=p0)
    ref = DenseEkfSlam(r, q, signatures, pose=(0, 0, 0.3), pose_cov=p0)
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        ekf.predict(v, w, run.dt)
        ref.predict(v, w, run.dt)
        np.testing.assert_allclose(full_state(ekf)[0], ref.mu, atol=EXACT, rtol=0)
        if len(z):
            ekf.update(z, ids)
            ref.update(z, ids)
        mean, cov = full_state(ekf)
        np.testing.assert_allclose(mean, ref.mu, atol=EXACT, rtol=0)
        np.testing.assert_allclose(cov, ref.sigma, atol=EXACT, rtol=0)
        if signatures:  # the full state's signature rows: uncorrelated with the rest, to the bit
            sig = np.zeros(len(ref.mu), bool)
            sig[5::3] = True
            assert not ref.sigma[np.ix_(sig, ~sig)].any()
    assert list(ekf.landmarks().ids) == ref.ids
    assert np.array_equal(ekf.covariance, ekf.covariance.T)  # symmetric to the bit


def test_first_sighting_never_moves_the_robot_and_augments_exactly():
    ekf = ps.EkfSlam(np.diag([0.01, 0.01, 0.001]), np.diag([0.01, 0.001]), use_signatures=False,
                     initial_pose_cov=np.diag([0.1, 0.2, 0.05]))
    ekf.predict(1.0, 0.2, 1.0)
    ekf.update([[3.0, 0.5]], [42])
    before_mean, before_cov = ekf.mean.copy(), ekf.covariance.copy()
    ekf.update([[2.0, -0.4], [4.0, 1.0]], [7, 8])
    np.testing.assert_array_equal(ekf.mean[:5], before_mean)
    np.testing.assert_array_equal(ekf.covariance[:5, :5], before_cov)
    np.testing.assert_allclose(ekf.landmark(7), ps.landmark_from_range_bearing(ekf.pose, [2.0, -0.4]))
    jp, jz = ps.landmark_from_range_bearing_jacobians(ekf.pose, [2.0, -0.4])
    expected = jp @ before_cov[:3, :3] @ jp.T + jz @ np.diag([0.01, 0.001]) @ jz.T
    np.testing.assert_allclose(ekf.landmark_covariance(7), expected, atol=1e-15)


def test_predict_touches_only_robot_rows_and_columns():
    rng = np.random.default_rng(2)
    run, q = random_sequence(rng, False, steps=10)
    ekf = ps.EkfSlam(np.diag([0.01, 0.01, 0.004]), q, use_signatures=False)
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        ekf.predict(v, w, run.dt)
        ekf.update(z, ids)
    before = ekf.covariance.copy()
    ekf.predict(1.0, 0.3, 0.5)
    np.testing.assert_array_equal(ekf.covariance[3:, 3:], before[3:, 3:])


def test_views_are_zero_copy_and_survive_growth():
    ekf = ps.EkfSlam(np.eye(3) * 0.01, np.diag([0.01, 0.001]), use_signatures=False)
    mean = ekf.mean
    assert not mean.flags.owndata
    ekf.predict(1.0, 0.0, 1.0)
    assert mean[0] == pytest.approx(1.0)  # same memory
    old_cov = ekf.covariance
    for j in range(200):  # grows the storage well past its initial capacity
        ekf.update([[5.0 + j * 0.01, 0.001 * j]], [j])
    assert ekf.num_landmarks == 200 and ekf.covariance.shape == (403, 403)
    assert old_cov.shape == (3, 3) and np.isfinite(old_cov).all()  # stale but valid memory


def test_landmark_accessors():
    ekf = ps.EkfSlam(np.eye(3) * 0.01, np.diag([0.01, 0.001, 0.1]), use_signatures=True)
    ekf.update([[2.0, 0.0, 7.0], [3.0, np.pi / 2, 9.0]], [10, 20])
    np.testing.assert_allclose(ekf.landmarks().means, [[2.0, 0.0], [0.0, 3.0]], atol=1e-12)
    assert ekf.landmark(20)[2] == 9.0
    assert ekf.landmark_covariance(10).shape == (3, 3)
    ekf.remove_landmark(10)
    assert list(ekf.landmarks().ids) == [20] and ekf.state_dim == 5  # the signature apart
    np.testing.assert_allclose(ekf.landmark(20)[:2], [0.0, 3.0], atol=1e-12)
    np.testing.assert_array_equal(ekf.signatures, [[9.0, 0.1]])
    assert ekf.landmark_covariance(20)[2, 2] == 0.1 and not ekf.landmark_covariance(20)[2, :2].any()


def test_unknown_correspondences_find_the_landmarks():
    rng = np.random.default_rng(4)
    world = ps.sim.LandmarkWorld.random(15, 10.0, rng, min_separation=2.0)
    q = np.diag([0.05 ** 2, np.radians(1.0) ** 2])
    sensor = ps.sim.Sensor(q, max_range=8.0, fov=np.radians(180))
    m = np.diag([0.003, 0.0005])  # moderate odometry noise: sigma_v 5.5 cm/s, sigma_w 1.3 deg/s
    run = ps.sim.simulate(world, ps.sim.circle_controls(300, 1.0, 0.12), 0.2, sensor, m, rng, initial_pose=(0, -8.3, 0))
    ekf = ps.EkfSlam(m, q, use_signatures=False, initial_pose=(0, -8.3, 0))
    truth_of = {}
    correct = total = 0
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        ekf.predict(v, w, run.dt)
        result = ekf.update_unknown(z)
        for true_id, got, outcome in zip(ids, result.ids, result.outcome):
            if outcome == result.NEW_LANDMARK:
                truth_of[got] = true_id
            elif outcome == result.ASSOCIATED:
                total += 1
                correct += truth_of[got] == true_id
        assert len(set(result.ids[result.ids >= 0])) == np.count_nonzero(result.ids >= 0)  # one per landmark
    assert correct / total > 0.99
    seen = {i for ids in run.ids for i in ids}
    assert ekf.num_landmarks == len(seen)


@pytest.mark.parametrize("call, err, name", [
    (lambda: ps.EkfSlam(np.diag([1, 1, -1.0]), np.eye(2)), ValueError, "motion_noise"),
    (lambda: ps.EkfSlam(np.ones((3, 3)), np.eye(2)), ValueError, "motion_noise"),
    (lambda: ps.EkfSlam(np.eye(4), np.eye(2)), ValueError, "motion_noise"),
    (lambda: ps.EkfSlam(np.eye(3), np.eye(2), use_signatures=True), ValueError, "measurement_noise"),
    # a signature correlated with range: the filter keeps signatures apart and cannot hold that
    (lambda: ps.EkfSlam(np.eye(3), [[1, 0, 0.1], [0, 1, 0], [0.1, 0, 1]], use_signatures=True), ValueError,
     "measurement_noise"),
    (lambda: ps.EkfSlam(np.eye(3), np.array([[1, 2], [0, 1.0]]), use_signatures=False), ValueError,
     "measurement_noise"),
    (lambda: ps.EkfSlam(np.eye(3), np.eye(2) * np.nan, use_signatures=False), ValueError, "measurement_noise"),
    (lambda: ps.EkfSlam(np.eye(3), np.eye(2), use_signatures=False, initial_pose=(0, np.nan, 0)), ValueError,
     "initial_pose"),
])
def test_bad_construction(call, err, name):
    with pytest.raises(err, match=name):
        call()


@pytest.mark.parametrize("call, err, name", [
    (lambda e: e.predict(1.0, 0.0, 0.0), ValueError, "dt"),
    (lambda e: e.predict(1.0, 0.0, -0.1), ValueError, "dt"),
    (lambda e: e.predict(np.nan, 0.0, 0.1), ValueError, "v"),
    (lambda e: e.predict(1.0, np.inf, 0.1), ValueError, "w"),
    (lambda e: e.update([[np.nan, 0.1]], [1]), ValueError, "z"),
    (lambda e: e.update([[-1.0, 0.1]], [1]), ValueError, "z"),
    (lambda e: e.update([[1.0, 0.1, 3.0]], [1]), ValueError, "z"),
    (lambda e: e.update([[1.0, 0.1], [2.0, 0.2]], [1]), ValueError, "ids"),
    (lambda e: e.update([[1.0, 0.1]], [1.5]), TypeError, "ids"),
    (lambda e: e.update_unknown([[1.0, np.inf]]), ValueError, "z"),
    (lambda e: e.update_unknown([[1.0, 0.1]], alpha=-1.0), ValueError, "alpha"),
    (lambda e: e.update_unknown([[1.0, 0.1]], association="nearest"), ValueError, "association"),
    (lambda e: e.update_unknown([[1.0, 0.1]], association=1), TypeError, "association"),
    (lambda e: e.update_unknown([[1.0, np.nan]], association="jcbb"), ValueError, "z"),
    (lambda e: e.landmark_covariance(99), ValueError, "id"),
    (lambda e: e.predict_odometry([0, 0, 0], np.diag([1, -1, 1.0])), ValueError, "noise"),
    (lambda e: e.predict_odometry([0, np.nan, 0], np.eye(3)), ValueError, "delta"),
])
def test_bad_calls_raise_and_leave_state_unchanged(call, err, name):
    ekf = ps.EkfSlam(np.diag([0.01, 0.01, 0.001]), np.diag([0.01, 0.001]), use_signatures=False)
    ekf.predict(1.0, 0.1, 0.5)
    ekf.update([[2.0, 0.3]], [5])
    mean, cov = ekf.mean.copy(), ekf.covariance.copy()
    with pytest.raises(err, match=name):
        call(ekf)
    np.testing.assert_array_equal(ekf.mean, mean)
    np.testing.assert_array_equal(ekf.covariance, cov)


def test_predict_with_per_call_noise_equals_a_filter_built_with_it():
    m = np.diag([0.04, 0.01])
    a = ps.EkfSlam(np.diag([0.3, 0.3]), np.diag([0.01, 0.001]), use_signatures=False)
    b = ps.EkfSlam(m, np.diag([0.01, 0.001]), use_signatures=False)
    for ekf in (a, b):
        ekf.update([[2.0, 0.3]], [1])
    a.predict(1.0, 0.2, 0.5, noise=m)
    b.predict(1.0, 0.2, 0.5)
    np.testing.assert_array_equal(a.covariance, b.covariance)
    with pytest.raises(ValueError, match="noise"):
        a.predict(1.0, 0.2, 0.5, noise=np.eye(4))
    with pytest.raises(ValueError, match="noise"):
        a.predict(1.0, 0.2, 0.5, noise=-np.eye(2))


def test_map_management_removes_clutter_landmarks():
    """With clutter, the provisional list and existence log-odds keep false landmarks out."""
    rng = np.random.default_rng(9)
    world = ps.sim.LandmarkWorld.random(20, 12.0, rng, min_separation=2.0)
    q = np.diag([0.05 ** 2, np.radians(1.0) ** 2])
    sensor = ps.sim.Sensor(q, max_range=8.0, fov=np.radians(180), clutter_rate=0.5)
    m = np.diag([0.003, 0.0005])
    run = ps.sim.simulate(world, ps.sim.circle_controls(400, 1.0, 0.1), 0.2, sensor, m, rng, initial_pose=(0, -10, 0))
    managed = ps.MapManagement()
    managed.provisional = managed.existence = True
    managed.sensor_range, managed.sensor_fov = 8.0, np.radians(180)
    sizes = {}
    for name, mm in (("plain", None), ("managed", managed)):
        ekf = ps.EkfSlam(m, q, use_signatures=False, initial_pose=(0, -10, 0), map_management=mm)
        for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
            ekf.predict(v, w, run.dt)
            if len(z):
                ekf.update_unknown(z)
        sizes[name] = ekf.num_landmarks
    seen = len({i for ids in run.ids for i in ids if i != ps.sim.CLUTTER_ID})
    assert sizes["plain"] > seen + 20  # clutter became landmarks
    assert sizes["managed"] >= seen - 2  # real landmarks are kept
    assert sizes["managed"] - seen < (sizes["plain"] - seen) / 5  # most of the excess is gone


def test_map_management_options_validated():
    mm = ps.MapManagement()
    mm.min_observations = 0
    with pytest.raises(ValueError, match="min_observations"):
        ps.EkfSlam(np.eye(3), np.eye(2), use_signatures=False, map_management=mm)
    mm = ps.MapManagement()
    mm.sensor_fov = -1.0
    with pytest.raises(ValueError, match="sensor_fov"):
        ps.EkfSlam(np.eye(3), np.eye(2), use_signatures=False, map_management=mm)


def clustered_scan(rng, n_landmarks, k):
    """A filter whose map holds landmarks 0.2-0.4 m apart, a robot whose heading became
    uncertain, and a scan of k measurements (a common heading error, noise, maybe clutter)."""
    q = np.diag([0.03 ** 2, 0.01 ** 2])
    ekf = ps.EkfSlam(np.diag([0.01, 0.01, 0.002]), q, use_signatures=False, gate_distance=100.0)
    centre = rng.uniform(2.5, 4.0) * np.array([1.0, rng.uniform(-0.3, 0.3)])
    xy = centre + rng.uniform(-0.4, 0.4, (n_landmarks, 2))
    z0 = np.column_stack([np.hypot(xy[:, 0], xy[:, 1]), np.arctan2(xy[:, 1], xy[:, 0])])
    ekf.update(z0 + rng.normal(0, [0.03, 0.01], z0.shape), np.arange(n_landmarks))
    ekf.predict(0.3, 0.0, 1.0, noise=np.diag([0.01, 0.01, rng.uniform(0.002, 0.02)]))
    seen = rng.choice(n_landmarks, size=min(k, n_landmarks), replace=False)
    pose = ekf.pose + rng.normal(0, [0.05, 0.05, 0.08])
    d = xy[seen] - pose[:2]
    z = np.column_stack([np.hypot(d[:, 0], d[:, 1]), wrap(np.arctan2(d[:, 1], d[:, 0]) - pose[2])])
    z += rng.normal(0, [0.03, 0.01], z.shape)
    if rng.random() < 0.3:  # clutter
        z = np.vstack([z, [rng.uniform(2, 4), rng.uniform(-0.5, 0.5)]])
    return ekf, z[rng.permutation(len(z))], q


@pytest.mark.parametrize("seed", range(40))
def test_joint_compatibility_equals_brute_force(seed):
    from ekf_reference import joint_compatibility_brute_force

    rng = np.random.default_rng(seed)
    ekf, z, q = clustered_scan(rng, int(rng.integers(2, 7)), int(rng.integers(1, 5)))
    alpha, alpha_new = ps.chi_square_quantile(0.99, 2), ps.chi_square_quantile(1 - 1e-6, 2)
    mu, sigma, ids = ekf.mean.copy(), ekf.covariance.copy(), ekf.landmarks().ids.copy()
    target, _, pi = joint_compatibility_brute_force(z, mu, sigma, q, 2, alpha)
    result = ekf.update_unknown(z, association="jcbb")
    paired = target >= 0
    np.testing.assert_array_equal(result.outcome[paired], result.ASSOCIATED)
    np.testing.assert_array_equal(result.ids[paired], ids[target[paired]])
    # Unpaired: a new landmark when every landmark not paired in this scan is beyond alpha_new.
    taken = np.zeros(len(ids), bool)
    taken[target[paired]] = True
    for i in np.flatnonzero(~paired):
        new = np.min(pi[i, ~taken], initial=np.inf) > alpha_new
        assert result.outcome[i] == (result.NEW_LANDMARK if new else result.DISCARDED)


def test_joint_compatibility_cases_differ_from_maximum_likelihood():
    """The random cases above are ones where the method matters."""
    differ = 0
    for seed in range(40):
        results = []
        for method in ("ml", "jcbb"):
            rng = np.random.default_rng(seed)
            ekf, z, _ = clustered_scan(rng, int(rng.integers(2, 7)), int(rng.integers(1, 5)))
            results.append(ekf.update_unknown(z, association=method))
        differ += not (np.array_equal(results[0].ids, results[1].ids)
                       and np.array_equal(results[0].outcome, results[1].outcome))
    assert differ >= 5


def test_chi_square_quantile_is_scipys():
    from scipy.stats import chi2

    for dof in (1, 2, 3, 7):
        for p in (1e-6, 0.05, 0.5, 0.95, 0.99, 1 - 1e-6):
            assert ps.chi_square_quantile(p, dof) == pytest.approx(chi2.ppf(p, dof), rel=1e-10)
            assert ps.chi_square_cdf(chi2.ppf(p, dof), dof) == pytest.approx(p, rel=1e-10)
    with pytest.raises(ValueError, match="^p "):
        ps.chi_square_quantile(1.0, 2)
    with pytest.raises(ValueError, match="^dof "):
        ps.chi_square_quantile(0.5, 0)
