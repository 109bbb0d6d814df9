"""Multiple-hypothesis EKF SLAM: its likelihoods and its best history against a dense numpy
replay of the same equations, association quality on a simulated run with clutter, bad input."""

import numpy as np
import pytest

import probslam as ps
from ekf_reference import DenseEkfSlam, measurement_rows
from test_ekf import random_sequence

EXACT = 1e-9  # the sparse and dense forms differ only by rounding


def dense_pairing(ref, z, landmark_id):
    """-2 log N(nu; 0, S) split as (NIS, log det(2 pi S)) from the dense filter."""
    z_hat, h = measurement_rows(ref.mu, ref.ld, ref.ids.index(landmark_id), ref.ld)
    nu = z - z_hat
    nu[1] = (nu[1] + np.pi) % (2 * np.pi) - np.pi
    s = h @ ref.sigma @ h.T + ref.q
    return nu @ np.linalg.solve(s, nu), np.log(np.linalg.det(2 * np.pi * s))


@pytest.mark.parametrize("signatures", [False, True])
def test_pairing_likelihood_equals_dense_numpy(signatures):
    rng = np.random.default_rng(11)
    run, q = random_sequence(rng, signatures)
    m = np.diag([0.02, 0.01])
    ekf = ps.EkfSlam(m, q, use_signatures=signatures, initial_pose=(0, 0, 0.3))
    ref = DenseEkfSlam(m, q, signatures, pose=(0, 0, 0.3))
    checked = 0
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        ekf.predict(v, w, run.dt)
        ref.predict(v, w, run.dt)
        for zi, i in zip(z, ids):
            if i in ref.ids:
                assert ekf.pairing_likelihood(zi, int(i)) == pytest.approx(dense_pairing(ref, zi, i), rel=EXACT)
                checked += 1
            ekf.update(zi[None], [int(i)])
            ref.update(zi[None], [i])
    assert checked > 50


def clutter_run(seed, steps=250, clutter=0.5):
    rng = np.random.default_rng(seed)
    world = ps.sim.LandmarkWorld.random(15, 10.0, rng, min_separation=2.0)
    q = np.diag([0.05 ** 2, np.radians(1.0) ** 2])
    sensor = ps.sim.Sensor(q, max_range=8.0, fov=np.radians(180), clutter_rate=clutter)
    m = np.diag([0.003, 0.0005])
    run = ps.sim.simulate(world, ps.sim.circle_controls(steps, 1.0, 0.12), 0.2, sensor, m, rng,
                          initial_pose=(0, -8.3, 0))
    return run, m, q


def test_best_history_replayed_densely_gives_its_cost_and_state():
    run, m, q = clutter_run(3, steps=120)
    mht = ps.MultiHypothesisEkfSlam(ps.EkfSlam(m, q, use_signatures=False, initial_pose=(0, -8.3, 0)))
    ref_scans = []
    for (v, w), z in zip(run.controls, run.measurements):
        mht.predict(v, w, run.dt)
        if len(z):
            mht.update(z)
        ref_scans.append(z)
    o = mht.options
    log_det_q = np.log(np.linalg.det(2 * np.pi * q))
    ref = DenseEkfSlam(m, q, False, pose=(0, -8.3, 0))
    history = iter(mht.history())
    cost = 0.0
    for (v, w), z in zip(run.controls, ref_scans):
        ref.predict(v, w, run.dt)
        if not len(z):
            continue
        for zi, lid in zip(z, next(history)):
            if lid < 0:
                cost += o.clutter_cost
                continue
            if lid in ref.ids:
                nis, log_det = dense_pairing(ref, zi, lid)
                cost += nis + log_det - log_det_q
            else:
                cost += o.new_landmark_cost
            ref.update(zi[None], [lid])
    best = mht.best
    assert mht.total_cost == pytest.approx(cost, rel=1e-9)
    assert list(best.landmark_ids) == ref.ids
    np.testing.assert_allclose(best.mean, ref.mu, atol=1e-8)
    np.testing.assert_allclose(best.covariance, ref.sigma, atol=1e-8)
    assert mht.costs[0] == 0.0 and np.all(np.diff(mht.costs) >= 0) and mht.num_hypotheses <= o.max_hypotheses


def association_scores(run, history):
    """Pairwise precision/recall of the best history against the simulator's ids, clutter
    counted as its own class, and the number of landmarks per true landmark."""
    truth = np.concatenate([ids for ids in run.ids if len(ids)])
    got = np.concatenate(history)
    real = truth != ps.sim.CLUTTER_ID
    clutter_kept = int(np.count_nonzero(~real & (got >= 0)))
    t, g = truth[real & (got >= 0)], got[real & (got >= 0)]
    same_t, same_g = t[:, None] == t[None, :], g[:, None] == g[None, :]
    off = ~np.eye(len(t), dtype=bool)
    precision = np.count_nonzero(same_t & same_g & off) / np.count_nonzero(same_g & off)
    recall = np.count_nonzero(same_t & same_g & off) / np.count_nonzero(same_t & off)
    return precision, recall, clutter_kept, len(set(g.tolist()))


def test_clutter_and_new_landmarks_are_told_apart_on_a_simulated_run():
    run, m, q = clutter_run(5)
    mht = ps.MultiHypothesisEkfSlam(ps.EkfSlam(m, q, use_signatures=False, initial_pose=(0, -8.3, 0)))
    for (v, w), z in zip(run.controls, run.measurements):
        mht.predict(v, w, run.dt)
        if len(z):
            mht.update(z)
    precision, recall, clutter_kept, n_landmarks = association_scores(run, mht.history())
    n_clutter = sum(int(np.count_nonzero(ids == ps.sim.CLUTTER_ID)) for ids in run.ids)
    seen = {int(i) for ids in run.ids for i in ids if i != ps.sim.CLUTTER_ID}
    assert precision > 0.999 and recall > 0.99
    assert n_clutter > 50 and clutter_kept <= 0.05 * n_clutter  # clutter is dropped as clutter
    assert n_landmarks == len(seen)  # each real landmark once, no duplicates


def test_copy_is_independent():
    ekf = ps.EkfSlam(np.eye(2) * 0.01, np.eye(2) * 0.01, use_signatures=False)
    ekf.update(np.array([[2.0, 0.1]]), [5])
    other = ekf.copy()
    other.update(np.array([[3.0, 0.5]]), [6])
    other.predict(1.0, 0.1, 1.0)
    assert ekf.num_landmarks == 1 and other.num_landmarks == 2
    assert np.all(ekf.pose == 0.0) and not np.all(other.pose == 0.0)


@pytest.mark.parametrize("kwargs, err, name", [
    (dict(max_hypotheses=0), ValueError, "max_hypotheses"),
    (dict(max_children=0), ValueError, "max_children"),
    (dict(gate=np.nan), ValueError, "gate"),
    (dict(new_landmark_cost=-1.0), ValueError, "new_landmark_cost"),
    (dict(clutter_cost=np.inf), ValueError, "clutter_cost"),
    (dict(prune_margin=0.0), ValueError, "prune_margin"),
    (dict(detection_probability=1.0, sensor_range=5.0, sensor_fov=1.0), ValueError, "detection_probability"),
    (dict(detection_probability=-0.1), ValueError, "detection_probability"),
    (dict(detection_probability=np.nan), ValueError, "detection_probability"),
    (dict(detection_probability="high"), TypeError, "detection_probability"),
    (dict(detection_probability=0.5, sensor_range=0.0, sensor_fov=1.0), ValueError, "sensor_range"),
    (dict(detection_probability=0.5, sensor_range=np.inf, sensor_fov=1.0), ValueError, "sensor_range"),
    (dict(detection_probability=0.5, sensor_range=5.0, sensor_fov=7.0), ValueError, "sensor_fov"),
    (dict(detection_probability=0.5, sensor_range=5.0), ValueError, "sensor_fov"),
])
def test_bad_options(kwargs, err, name):
    ekf = ps.EkfSlam(np.eye(2) * 0.01, np.eye(2) * 0.01, use_signatures=False)
    with pytest.raises(err, match=name):
        ps.MultiHypothesisEkfSlam(ekf, **kwargs)


def test_bad_input_raises_and_leaves_the_beam_unchanged():
    with pytest.raises(TypeError, match="ekf"):
        ps.MultiHypothesisEkfSlam("not a filter")
    ekf = ps.EkfSlam(np.eye(2) * 0.01, np.eye(2) * 0.01, use_signatures=False)
    mht = ps.MultiHypothesisEkfSlam(ekf)
    mht.update(np.array([[2.0, 0.1], [4.0, -0.5]]))
    before = (mht.num_hypotheses, mht.total_cost, mht.best.mean.copy(), len(mht.history()))
    for z, err in [([[1.0, np.nan]], ValueError), ([[-1.0, 0.1]], ValueError), ([[1.0, 0.1, 0.2]], ValueError),
                   ("abc", (TypeError, ValueError))]:
        with pytest.raises(err, match="z"):
            mht.update(z)
    with pytest.raises(ValueError, match="dt"):
        mht.predict(1.0, 0.0, -1.0)
    with pytest.raises(ValueError, match="id"):
        ekf.pairing_likelihood([1.0, 0.1], 99)
    after = (mht.num_hypotheses, mht.total_cost, mht.best.mean, len(mht.history()))
    assert before[:2] == after[:2] and before[3] == after[3]
    np.testing.assert_array_equal(before[2], after[2])


# ---- missed detections ---------------------------------------------------------------------------
def mapped_filter(landmarks):
    """An EKF at the origin facing +x with the given landmarks ((id, x, y)), each from one sighting."""
    q = np.diag([0.05 ** 2, np.radians(1.0) ** 2])
    ekf = ps.EkfSlam(np.diag([0.003, 0.0005]), q, use_signatures=False)
    for i, x, y in landmarks:
        ekf.update(np.array([[np.hypot(x, y), np.arctan2(y, x)]]), [i])
    return ekf, q


def test_missed_detection_costs_equal_hand_computation():
    """Landmark 0 ahead (in view), landmark 1 behind (out of the 180 deg field), landmark 2
    beyond range. A scan of one far outlier: every child misses landmark 0 only, so the best
    (clutter) costs clutter_cost - 2 ln(1 - P_D). A scan that sees landmark 0 exactly: its
    pairing cost - 2 ln P_D, the pairing cost from the dense numpy reference."""
    p_d = 0.8
    ekf, q = mapped_filter([(0, 3.0, 0.5), (1, -2.0, 0.0), (2, 9.0, 0.0)])
    ref = DenseEkfSlam(np.diag([0.003, 0.0005]), q, False)
    for i, x, y in [(0, 3.0, 0.5), (1, -2.0, 0.0), (2, 9.0, 0.0)]:
        ref.update(np.array([[np.hypot(x, y), np.arctan2(y, x)]]), [i])
    mht = ps.MultiHypothesisEkfSlam(ekf, detection_probability=p_d, sensor_range=6.0, sensor_fov=np.pi)
    o = mht.options
    mht.update(np.array([[5.0, -1.2]]))  # far from every landmark: clutter or new
    assert mht.total_cost == pytest.approx(o.clutter_cost - 2 * np.log(1 - p_d), rel=1e-12)
    before = mht.total_cost
    z = np.array([np.hypot(3.0, 0.5), np.arctan2(0.5, 3.0)])
    nis, log_det = dense_pairing(ref, z, 0)
    mht.update(z[None])
    log_det_q = np.log(np.linalg.det(2 * np.pi * q))
    assert mht.total_cost - before == pytest.approx(nis + log_det - log_det_q - 2 * np.log(p_d), rel=1e-9, abs=1e-9)
    assert list(mht.history()[-1]) == [0]


def test_missed_detections_off_by_default_and_costless_out_of_view():
    ekf, _ = mapped_filter([(0, -3.0, 0.5)])  # behind the robot
    on = ps.MultiHypothesisEkfSlam(ekf, detection_probability=0.9, sensor_range=6.0, sensor_fov=np.pi)
    off = ps.MultiHypothesisEkfSlam(ekf)
    for m in (on, off):
        m.update(np.array([[5.0, 1.0]]))
    assert on.total_cost == off.total_cost == off.options.clutter_cost


def test_missed_detections_retire_alternatives_nobody_sees_again():
    """The clutter run with the simulator's sensor field and P_D 0.9: every real landmark once,
    clutter dropped, and the beam's alternatives no longer sit at the same cost as the fresh
    ones (a landmark made of a clutter point pays for every scan that misses it)."""
    run, m, q = clutter_run(5)
    tied = {}
    for p_d in (0.0, 0.9):
        mht = ps.MultiHypothesisEkfSlam(ps.EkfSlam(m, q, use_signatures=False, initial_pose=(0, -8.3, 0)),
                                        detection_probability=p_d, sensor_range=8.0, sensor_fov=np.radians(180))
        one_new = mht.options.new_landmark_cost - mht.options.clutter_cost
        tied[p_d] = 0
        for (v, w), z in zip(run.controls, run.measurements):
            mht.predict(v, w, run.dt)
            if len(z):
                mht.update(z)
                tied[p_d] += int(np.count_nonzero(np.abs(mht.costs[1:] - one_new) < 1e-6))
    assert tied[0.9] < 0.5 * tied[0.0]  # alternatives "one more landmark, never seen again" retire
    precision, recall, clutter_kept, n_landmarks = association_scores(run, mht.history())
    n_clutter = sum(int(np.count_nonzero(ids == ps.sim.CLUTTER_ID)) for ids in run.ids)
    seen = {int(i) for ids in run.ids for i in ids if i != ps.sim.CLUTTER_ID}
    assert precision > 0.999 and recall > 0.99
    assert clutter_kept <= 0.05 * n_clutter
    assert n_landmarks == len(seen)
