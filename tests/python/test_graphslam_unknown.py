"""GraphSLAM with unknown correspondences: Table 11.8 against a dense inverse of Omega, and
Table 11.9's merges against the simulator's ground truth (precision and recall)."""

import numpy as np
import pytest
from scipy.stats import multivariate_normal

import probslam
from probslam import sim
from eif_reference import simulate

R = np.diag([0.02, 0.02, 0.005]) ** 2
Q2 = np.diag([0.05, 0.01]) ** 2
Q3 = np.diag([0.05, 0.01, 0.1]) ** 2
# Two double-precision inverses of systems with condition numbers near 1e6 agree to this.
TIGHT = 1e-9


def solved_form(signatures, seed=0):
    """Omega, Omega~ and the features at the converged GraphSLAM estimate of a small run."""
    controls, dt, meas, _, _ = simulate(steps=40, seed=seed, signatures=signatures)
    Q = Q3 if signatures else Q2
    res = probslam.graph_slam(controls, dt, meas, R, Q)
    y = np.concatenate([res.poses.ravel(), res.features.ravel()])
    omega, xi = probslam.eif_construct(controls, dt, meas, y, R, Q)
    num_poses, d = len(res.poses), res.features.shape[1]
    reduced, _ = probslam.eif_reduce(omega, xi, num_poses, d)
    return omega, reduced, res.features, num_poses


@pytest.mark.parametrize("signatures", [False, True])
def test_correspondence_test_equals_the_dense_marginal(signatures):
    omega, reduced, features, num_poses = solved_form(signatures)
    n, d = features.shape
    sigma = np.linalg.inv(omega.toarray())
    base = 3 * num_poses
    j, k = np.triu_indices(n, 1)
    batch = probslam.eif_correspondence_test(omega, reduced, features, num_poses, j, k)
    for i, (a, b) in enumerate(zip(j, k)):
        sa, sb = slice(base + d * a, base + d * (a + 1)), slice(base + d * b, base + d * (b + 1))
        cov = sigma[sa, sa] + sigma[sb, sb] - sigma[sa, sb] - sigma[sb, sa]
        mean = features[a] - features[b]
        np.testing.assert_allclose(batch.covariance[i], cov, rtol=0, atol=TIGHT * np.abs(cov).max())
        np.testing.assert_allclose(batch.mean[i], mean, rtol=0, atol=1e-12)
        assert batch.distance2[i] == pytest.approx(mean @ np.linalg.solve(cov, mean), rel=1e-6)
        density = multivariate_normal(mean=mean, cov=cov).pdf(np.zeros(d))
        assert batch.probability[i] == pytest.approx(density, rel=1e-6, abs=1e-300)
        one = probslam.eif_correspondence_test(omega, reduced, features, num_poses, int(a), int(b))
        assert one.probability == batch.probability[i] and one.distance2 == batch.distance2[i]


def test_a_split_feature_is_the_most_probable_pair():
    controls, dt, meas, _, _ = simulate(steps=40, seed=2)
    time, z, corr = meas
    n = corr.max() + 1
    target = corr[0]
    later = np.flatnonzero(corr == target)[len(np.flatnonzero(corr == target)) // 2:]
    corr = corr.copy()
    corr[later] = n  # the later half of one feature's measurements as a new feature
    res = probslam.graph_slam(controls, dt, (time, z, corr), R, Q2)
    y = np.concatenate([res.poses.ravel(), res.features.ravel()])
    omega, xi = probslam.eif_construct(controls, dt, (time, z, corr), y, R, Q2)
    reduced, _ = probslam.eif_reduce(omega, xi, len(res.poses), 2)
    j, k = np.triu_indices(n + 1, 1)
    tests = probslam.eif_correspondence_test(omega, reduced, res.features, len(res.poses), j, k)
    best = np.argmax(tests.probability)
    assert {j[best], k[best]} == {target, n}
    assert tests.distance2[best] < 13.8  # the 0.999 quantile of chi-square(2)


def flat_measurements(run: sim.SimRun):
    """The simulator's per-step scans as Table 11.2's flat arrays (scan t follows control t)."""
    time = np.concatenate([np.full(len(z), t + 1) for t, z in enumerate(run.measurements)])
    return time, np.vstack(run.measurements), np.concatenate(run.ids)


def pair_precision_recall(estimate, truth):
    """Over all pairs of measurements: the share of pairs put together that belong together,
    and of pairs that belong together that were put together."""
    same_e = estimate[:, None] == estimate[None, :]
    same_t = truth[:, None] == truth[None, :]
    upper = np.triu(np.ones_like(same_e, dtype=bool), 1)
    tp = np.sum(same_e & same_t & upper)
    return tp / max(np.sum(same_e & upper), 1), tp / max(np.sum(same_t & upper), 1)


def simulated_run(seed, signatures):
    rng = np.random.default_rng(seed)
    world = sim.LandmarkWorld.random(25, 12.0, rng, min_separation=2.0)
    q = Q3 if signatures else Q2
    sensor = sim.Sensor(q, max_range=8.0, signatures=signatures)
    run = sim.simulate(world, sim.circle_controls(160, v=1.0, w=0.1), 0.5, sensor, R, rng, initial_pose=(0, -8, 0))
    return run, flat_measurements(run), q


@pytest.mark.parametrize("signatures", [False, True])
@pytest.mark.slow
def test_merges_recover_the_simulated_correspondences(signatures):
    for seed in range(3):
        run, (time, z, truth), q = simulated_run(seed, signatures)
        dt = np.full(len(run.controls), run.dt)
        res = probslam.graph_slam(run.controls, dt, (time, z), R, q, initial_pose=run.poses[0])
        precision, recall = pair_precision_recall(res.correspondences, truth)
        assert precision >= 0.99 and recall >= 0.95, (seed, precision, recall)
        assert res.converged
        # Merges are named by first measurements, and every merge removed one feature.
        assert len(res.merges.kept) == len(z) - len(res.features)
        assert np.all(res.merges.kept < res.merges.merged)
        assert np.all(res.merges.probability > 1e-4)
        # No feature holds two measurements of one scan.
        pairs = set(zip(res.correspondences.tolist(), time.tolist()))
        assert len(pairs) == len(time)


@pytest.mark.slow
def test_the_unknown_result_is_the_known_solution_of_its_correspondences():
    run, (time, z, _), q = simulated_run(5, False)
    dt = np.full(len(run.controls), run.dt)
    unknown = probslam.graph_slam(run.controls, dt, (time, z, None), R, q, initial_pose=run.poses[0])
    known = probslam.graph_slam(run.controls, dt, (time, z, unknown.correspondences), R, q,
                                initial_pose=run.poses[0])
    np.testing.assert_allclose(unknown.poses, known.poses, atol=1e-6)
    np.testing.assert_allclose(unknown.features, known.features, atol=1e-6)
    assert unknown.objective == pytest.approx(known.objective, rel=1e-6)
    # Both are linearised within 1e-6 of the optimum: the covariances agree to about that.
    scale = np.abs(known.pose_covariances).max()
    np.testing.assert_allclose(unknown.pose_covariances, known.pose_covariances, rtol=0, atol=1e-6 * scale)


def test_bad_input_is_rejected():
    omega, reduced, features, num_poses = solved_form(False)
    with pytest.raises(ValueError, match="k"):
        probslam.eif_correspondence_test(omega, reduced, features, num_poses, 1, 1)
    with pytest.raises(ValueError, match="j"):
        probslam.eif_correspondence_test(omega, reduced, features, num_poses, -1, 1)
    with pytest.raises(ValueError, match="k"):
        probslam.eif_correspondence_test(omega, reduced, features, num_poses, 0, len(features))
    with pytest.raises(TypeError, match="j"):
        probslam.eif_correspondence_test(omega, reduced, features, num_poses, 0.5, 1)
    with pytest.raises(ValueError, match="same length"):
        probslam.eif_correspondence_test(omega, reduced, features, num_poses, [0, 1], [2])
    with pytest.raises(ValueError, match="features"):
        probslam.eif_correspondence_test(omega, reduced, features[:, :1], num_poses, 0, 1)
    with pytest.raises(ValueError, match="features"):
        probslam.eif_correspondence_test(omega, reduced, features[:-1], num_poses, 0, 1)
    with pytest.raises(TypeError, match="reduced_omega"):
        probslam.eif_correspondence_test(omega, reduced.toarray(), features, num_poses, 0, 1)

    controls, dt, (time, z, _), _, _ = simulate(steps=10)
    for kwargs, name in (({"chi": -1.0}, "chi"), ({"chi": np.nan}, "chi"), ({"search_radius": 0.0}, "search_radius"),
                         ({"max_rounds": -1}, "max_rounds")):
        with pytest.raises(ValueError, match=name):
            probslam.graph_slam(controls, dt, (time, z), R, Q2, **kwargs)
    bad = z.copy()
    bad[3, 0] = -1.0
    with pytest.raises(ValueError, match="z"):
        probslam.graph_slam(controls, dt, (time, bad), R, Q2)
    bad[3, 0] = np.nan
    with pytest.raises(ValueError, match="z"):
        probslam.graph_slam(controls, dt, (time, bad), R, Q2)
    with pytest.raises(TypeError, match="measurements"):
        probslam.graph_slam(controls, dt, (time,), R, Q2)
