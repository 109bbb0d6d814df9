"""Multiple-hypothesis EKF SLAM: its likelihoods and its best history against a dense numpy
replay of the same equations, association quality on a simulated run with clutter, bad input."""

import numpy as np
import pytest

import probslam as ps
from ekf_reference import DenseEkfSlam, measurement_rows, wrap
from ekf_reference import motion as ekf_motion
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


#: kMhtCostResolution (multi_hypothesis_ekf_slam.hpp): the grid the beam's costs are ordered on.
MHT_COST_RESOLUTION = 1e-6


def drive(mht, run):
    """The filter over a simulated run: each control predicted, each non-empty scan an update."""
    for (v, w), z in zip(run.controls, run.measurements):
        mht.predict(v, w, run.dt)
        if len(z):
            mht.update(z)


def test_best_history_replayed_densely_gives_its_cost_and_state():
    run, m, q = clutter_run(3, steps=120)
    mht = ps.MultiHypothesisEkfSlam(ps.EkfSlam(m, q, use_signatures=False, initial_pose=(0, -8.3, 0)))
    drive(mht, run)
    o = mht.options
    log_det_q = np.log(np.linalg.det(2 * np.pi * q))
    ref = DenseEkfSlam(m, q, False, pose=(0, -8.3, 0))
    history = iter(mht.history())
    cost = 0.0
    for (v, w), z in zip(run.controls, run.measurements):
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
    assert list(best.landmarks().ids) == ref.ids
    np.testing.assert_allclose(best.mean, ref.mu, atol=1e-8)
    np.testing.assert_allclose(best.covariance, ref.sigma, atol=1e-8)
    # The beam is ordered by cost on a grid of kMhtCostResolution (1e-6; multi_hypothesis_ekf_slam.hpp):
    # costs equal but for the last bits keep their parents' order.
    assert mht.costs[0] == 0.0 and np.all(np.diff(mht.costs) >= -MHT_COST_RESOLUTION)
    assert mht.num_hypotheses <= o.max_hypotheses


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
    drive(mht, run)
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
    (dict(bearing_offset_sigma=-0.01), ValueError, "bearing_offset_sigma"),
    (dict(bearing_offset_sigma=np.nan), ValueError, "bearing_offset_sigma"),
    (dict(bearing_offset_sigma=4.0), ValueError, "bearing_offset_sigma"),
    (dict(bearing_offset_sigma=None), TypeError, "bearing_offset_sigma"),
    (dict(bearing_offset_correlation=1.0), ValueError, "bearing_offset_correlation"),
    (dict(bearing_offset_correlation=-0.5), ValueError, "bearing_offset_correlation"),
    (dict(bearing_offset_correlation=np.inf), ValueError, "bearing_offset_correlation"),
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


# ---- the scan's bearing offset -------------------------------------------------------------------
class DenseOffsetEkf:
    """The independent reference: a dense EKF whose state holds the offset b explicitly, as
    [x, y, theta, b, landmarks...], bearing = atan2(dy, dx) - theta - b, b an AR(1) stepped at
    every scan, motion leaving b alone (ekf_reference's equations otherwise)."""

    def __init__(self, m, q, sigma_b, rho, pose, pose_cov):
        self.m, self.q, self.sigma_b, self.rho = m, q, sigma_b, rho
        self.mu = np.concatenate([pose, [0.0]])
        self.sigma = np.zeros((4, 4))
        self.sigma[:3, :3] = pose_cov
        self.sigma[3, 3] = sigma_b ** 2
        self.ids = []

    def predict(self, v, w, dt):
        d, g3, dv = ekf_motion(self.mu[:3], v, w, dt)
        g = np.eye(len(self.mu))
        g[:3, :3] = g3
        self.mu[:3] += d
        self.mu[2] = wrap(self.mu[2])
        self.sigma = g @ self.sigma @ g.T
        self.sigma[:3, :3] += dv @ self.m @ dv.T

    def start_scan(self):
        a = np.eye(len(self.mu))
        a[3, 3] = self.rho
        self.mu = a @ self.mu
        self.sigma = a @ self.sigma @ a.T
        self.sigma[3, 3] += (1 - self.rho ** 2) * self.sigma_b ** 2

    def pairing(self, z, j):
        """(nu, H, S) of z against landmark j."""
        k0 = 4 + 2 * self.ids.index(j)
        dx, dy = self.mu[k0] - self.mu[0], self.mu[k0 + 1] - self.mu[1]
        q = dx * dx + dy * dy
        h = np.zeros((2, len(self.mu)))
        h[0, [0, 1, k0, k0 + 1]] = np.array([-dx, -dy, dx, dy]) / np.sqrt(q)
        h[1, [0, 1, 2, 3, k0, k0 + 1]] = np.array([dy, -dx, -q, -q, -dy, dx]) / q
        nu = z - np.array([np.sqrt(q), np.arctan2(dy, dx) - self.mu[2] - self.mu[3]])
        nu[1] = wrap(nu[1])
        return nu, h, h @ self.sigma @ h.T + self.q

    def update(self, z, j):
        if j in self.ids:
            nu, h, s = self.pairing(z, j)
            k = self.sigma @ h.T @ np.linalg.inv(s)
            self.mu = self.mu + k @ nu
            self.mu[2] = wrap(self.mu[2])
            self.sigma = (np.eye(len(self.mu)) - k @ h) @ self.sigma
            return
        x, a = self.mu[:3], z[1] + self.mu[2] + self.mu[3]
        gx = np.zeros((2, len(self.mu)))
        gx[:, :4] = [[1, 0, -z[0] * np.sin(a), -z[0] * np.sin(a)], [0, 1, z[0] * np.cos(a), z[0] * np.cos(a)]]
        gz = np.array([[np.cos(a), -z[0] * np.sin(a)], [np.sin(a), z[0] * np.cos(a)]])
        self.sigma = np.block([[self.sigma, self.sigma @ gx.T],
                               [gx @ self.sigma, gx @ self.sigma @ gx.T + gz @ self.q @ gz.T]])
        self.mu = np.concatenate([self.mu, x[:2] + z[0] * np.array([np.cos(a), np.sin(a)])])
        self.ids.append(j)


def offset_drive(world, rng, steps, sigma_b, rho):
    """The clutter run's robot through `world`, 0.5 deg bearing noise, with an AR(1) bearing
    offset (stationary sigma_b, rho per step) added to every scan's bearings."""
    q = np.diag([0.05 ** 2, np.radians(0.5) ** 2])
    sensor = ps.sim.Sensor(q, max_range=8.0, fov=np.radians(180))
    m = np.diag([0.003, 0.0005])
    run = ps.sim.simulate(world, ps.sim.circle_controls(steps, 1.0, 0.12), 0.2, sensor, m, rng,
                          initial_pose=(0, -8.3, 0))
    b = rng.normal(0.0, sigma_b)
    for z in run.measurements:
        b = rho * b + np.sqrt(1 - rho ** 2) * rng.normal(0.0, sigma_b)
        if len(z):
            z[:, 1] = wrap(z[:, 1] - b)
    return run, m, q


def offset_run(seed, steps, sigma_b, rho):
    """Fifteen landmarks at least 2 m apart."""
    rng = np.random.default_rng(seed)
    return offset_drive(ps.sim.LandmarkWorld.random(15, 10.0, rng, min_separation=2.0), rng, steps, sigma_b, rho)


def test_bearing_offset_filter_equals_dense_reference_with_the_offset_in_the_state():
    """Greedy beam (one filter), offset AR(1): the best filter's state, after marginalising b
    from the reference, and its total cost equal the dense numpy replay of its history."""
    sigma_b, rho = 0.03, 0.8
    run, m, q = offset_run(7, 80, sigma_b, rho)
    pose_cov = np.diag([1e-4, 1e-4, 1e-5])
    ekf = ps.EkfSlam(m, q, use_signatures=False, initial_pose=(0, -8.3, 0), initial_pose_cov=pose_cov)
    # new landmarks cheaper than clutter, so that the one filter maps (clutter costs no state)
    mht = ps.MultiHypothesisEkfSlam(ekf, max_hypotheses=1, max_children=1, bearing_offset_sigma=sigma_b,
                                    bearing_offset_correlation=rho, new_landmark_cost=10.0)
    drive(mht, run)
    o = mht.options
    log_det_q = np.log(np.linalg.det(2 * np.pi * (q + np.diag([0.0, sigma_b ** 2]))))
    ref = DenseOffsetEkf(m, q, sigma_b, rho, np.array([0, -8.3, 0.0]), pose_cov)
    history, cost, kinds = iter(mht.history()), 0.0, set()
    for (v, w), z in zip(run.controls, run.measurements):
        ref.predict(v, w, run.dt)
        if not len(z):
            continue
        ref.start_scan()
        for zi, lid in zip(z, next(history)):
            if lid < 0:
                cost += o.clutter_cost
                kinds.add("clutter")
                continue
            if lid in ref.ids:
                nu, _, s = ref.pairing(zi, lid)
                cost += nu @ np.linalg.solve(s, nu) + np.log(np.linalg.det(2 * np.pi * s)) - log_det_q
                kinds.add("pairing")
            else:
                cost += o.new_landmark_cost
                kinds.add("new")
            ref.update(zi, lid)
    assert kinds == {"pairing", "new"} and len(ref.ids) >= 5
    keep = np.r_[0:3, 4:len(ref.mu)]  # b marginalised out
    best = mht.best
    assert list(best.landmarks().ids) == ref.ids
    np.testing.assert_allclose(best.mean, ref.mu[keep], atol=1e-8)
    np.testing.assert_allclose(best.covariance, ref.sigma[np.ix_(keep, keep)], atol=1e-10)
    assert mht.total_cost == pytest.approx(cost, rel=1e-9)


def pair_run(seed, sigma_b, rho, gap, steps=250):
    """Eight pairs of landmarks `gap` m apart seen through a scan-wide AR(1) bearing offset."""
    rng = np.random.default_rng(seed)
    centres = ps.sim.LandmarkWorld.random(8, 9.0, rng, min_separation=3.0).landmarks
    turn = rng.uniform(0, np.pi, len(centres))
    d = 0.5 * gap * np.column_stack([np.cos(turn), np.sin(turn)])
    world = ps.sim.LandmarkWorld(np.vstack([centres - d, centres + d]), np.arange(16.0))
    return offset_drive(world, rng, steps, sigma_b, rho)


def share_correct(run, history):
    """The share of the real sightings whose filter landmark's majority true id is their own
    (a sighting dropped as clutter or merged into its neighbour's landmark is not)."""
    truth = np.concatenate([ids for ids in run.ids if len(ids)])
    got = np.concatenate(history)
    majority = {g: np.bincount(truth[got == g]).argmax() for g in set(got[got >= 0].tolist())}
    correct = [g >= 0 and majority[g] == t for t, g in zip(truth, got)]
    return float(np.mean(correct))


@pytest.mark.parametrize("new_landmark_cost", [0.0, 21.0])  # 0.0: the default quantile
@pytest.mark.slow
def test_bearing_offset_keeps_close_pairs_apart_whatever_the_new_landmark_cost(new_landmark_cost):
    """Pairs 0.3 m apart, a 3 deg scan-wide offset (rho 0.8), 0.5 deg noise of each sighting,
    missed detections charged (P_D 0.9). The filter carrying the offset sees a scan's sharp
    relative bearings and places over 97% of the sightings on their own landmark, with the
    default new-landmark cost and a cheaper one. Folding the offset into each bearing's noise
    instead (the same marginal noise per sighting) needs the cheaper cost: with the default one
    it merges pairs or drops their sightings as ambiguous (below half right)."""
    sigma_b, rho = np.radians(3.0), 0.8
    field = dict(detection_probability=0.9, sensor_range=8.0, sensor_fov=np.pi, new_landmark_cost=new_landmark_cost)
    for seed in (1, 2, 3):
        run, m, q = pair_run(seed, sigma_b, rho, gap=0.3)
        scores = {}
        for model in ("offset", "inflated"):
            if model == "offset":
                ekf = ps.EkfSlam(m, q, use_signatures=False, initial_pose=(0, -8.3, 0))
                mht = ps.MultiHypothesisEkfSlam(ekf, bearing_offset_sigma=sigma_b, bearing_offset_correlation=rho,
                                                **field)
            else:
                ekf = ps.EkfSlam(m, q + np.diag([0.0, sigma_b ** 2]), use_signatures=False, initial_pose=(0, -8.3, 0))
                mht = ps.MultiHypothesisEkfSlam(ekf, **field)
            drive(mht, run)
            scores[model] = share_correct(run, mht.history())
        assert scores["offset"] > 0.97
        if new_landmark_cost is None:
            assert scores["inflated"] < 0.5


def test_update_says_the_best_filters_assignments_the_beam_and_its_cost():
    """update's HypothesisUpdate is the beam after the scan: the best filter's ids for the scan
    are the last entry of its history, the count and cost the beam's own."""
    ekf = ps.EkfSlam(np.eye(2) * 0.01, np.eye(2) * 0.01, use_signatures=False)
    mht = ps.MultiHypothesisEkfSlam(ekf, max_hypotheses=5)
    rng = np.random.default_rng(4)
    for _ in range(6):
        z = np.column_stack([rng.uniform(1.0, 8.0, 3), rng.uniform(-1.0, 1.0, 3)])
        result = mht.update(z)
        assert isinstance(result, ps.HypothesisUpdate)
        assert result.ids.dtype == np.int64 and result.ids.shape == (3,)
        np.testing.assert_array_equal(result.ids, mht.history()[-1])
        assert result.num_hypotheses == mht.num_hypotheses and result.cost == mht.total_cost
        mht.predict(0.5, 0.1, 1.0)
