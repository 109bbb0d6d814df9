"""FastSLAM's provisional landmarks (``min_sightings`` / ``provisional_max_age``) against a
count by hand, their options refused by name; the batched odometry predictions of FastSlam (bit
for bit) and EkfSlam (to rounding) against the step-by-step calls, and a refused batch leaving
the filter unchanged."""

import pickle

import numpy as np
import pytest

import probslam as ps

Q = np.diag([0.01, 1e-4])
#: The batched EKF prediction moves the landmarks' cross covariances once by the composed
#: Jacobian instead of once per step: the products are reassociated, so they differ by rounding.
BATCH_TOLERANCE = 1e-12


def filter_at_origin(**options):
    """One particle, no motion noise: its pose is the odometry's, its map the sightings'."""
    return ps.FastSlam(np.zeros((3, 3)), Q, num_particles=1, **options)


def sighting(landmark, pose=(0.0, 0.0, 0.0)):
    """The range and bearing of a landmark (x, y) from pose."""
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    return [np.hypot(dx, dy), np.arctan2(dy, dx) - pose[2]]


A, B, C = (5.0, 0.0), (0.0, 8.0), (-6.0, -3.0)


def ids(f):
    return list(f.landmarks(0).ids)


@pytest.mark.parametrize("min_sightings, max_age", [(2, 0), (3, 2), (4, 5), (6, 1)])
def test_an_unconfirmed_landmark_goes_after_exactly_max_age_scans_unseen(min_sightings, max_age):
    f = filter_at_origin(min_sightings=min_sightings, provisional_max_age=max_age)
    a_id, b_id = f.update_unknown(np.array([sighting(A), sighting(B)])).ids[0]
    # Call c (the first is 1) sees B only: A has gone c - 1 scans unseen, and is removed in the
    # call where that first exceeds max_age; B, seen in every call, is confirmed in call
    # min_sightings and stays however long it then goes unseen.
    for c in range(2, max(max_age + 2, min_sightings) + 3):
        removed = [tuple(row) for row in f.update_unknown(np.array([sighting(B)])).removed]
        assert ((0, a_id) in removed) == (c == max_age + 2)
        assert (a_id in ids(f)) == (c < max_age + 2)
    for _ in range(3 * max_age + 3):
        f.update_unknown(np.array([sighting(C)]))
    assert b_id in ids(f)


def test_a_resighting_resets_the_clock_and_min_sightings_one_keeps_everything():
    f = filter_at_origin(min_sightings=3, provisional_max_age=1)
    a_id = f.update_unknown(np.array([sighting(A)])).ids[0, 0]
    f.update_unknown(np.array([sighting(C)]))          # A unseen 1 scan: kept
    f.update_unknown(np.array([sighting(A)]))          # seen again: 2 sightings, clock reset
    f.update_unknown(np.array([sighting(C)]))          # unseen 1 scan: kept
    assert a_id in ids(f)
    f.update_unknown(np.array([sighting(C)]))          # unseen 2 scans: removed
    assert a_id not in ids(f)
    plain = filter_at_origin()
    plain.update_unknown(np.array([sighting(A)]))
    for _ in range(50):
        plain.update_unknown(np.array([sighting(C)]))
    assert len(ids(plain)) == 2


@pytest.mark.parametrize("name, value, error", [
    ("min_sightings", 0, ValueError), ("min_sightings", 1_000_001, ValueError), ("min_sightings", 2.5, TypeError),
    ("provisional_max_age", -1, ValueError), ("provisional_max_age", 1_000_001, ValueError),
    ("provisional_max_age", None, TypeError)])
def test_bad_provisional_options_are_refused_by_name(name, value, error):
    with pytest.raises(error, match=name):
        filter_at_origin(**{name: value})


def test_provisional_state_survives_save_and_load(tmp_path):
    rng = np.random.default_rng(3)
    f = ps.FastSlam(np.diag([0.01, 0.01, 1e-3]), Q, num_particles=20, min_sightings=3, provisional_max_age=2, seed=5)
    world = rng.uniform(-10, 10, (15, 2))
    for _ in range(4):
        f.predict_odometry([0.3, 0.0, 0.05], np.diag([1e-3, 1e-3, 1e-4]))
        seen = world[rng.random(len(world)) < 0.4]
        f.update_unknown(np.array([sighting(w, f.mean_pose) for w in seen]).reshape(-1, 2))
    f.save(tmp_path / "f.state")
    g = ps.FastSlam.load(tmp_path / "f.state")
    h = pickle.loads(pickle.dumps(f))
    for _ in range(6):
        z = np.array([sighting(w, f.mean_pose) for w in world[rng.random(len(world)) < 0.4]]).reshape(-1, 2)
        results = [x.update_unknown(z) for x in (f, g, h)]
        for r in results[1:]:
            np.testing.assert_array_equal(r.removed, results[0].removed)
    for k in range(f.num_particles):
        assert list(f.landmarks(k).ids) == list(g.landmarks(k).ids) == list(h.landmarks(k).ids)


# ---- batched odometry ----------------------------------------------------------------------

def odometry(n, seed=0):
    rng = np.random.default_rng(seed)
    deltas = np.column_stack([rng.uniform(0.05, 0.2, n), rng.normal(0, 0.01, n), rng.normal(0, 0.02, n)])
    a = rng.normal(0, 0.01, (n, 3, 3))
    return deltas, a @ a.transpose(0, 2, 1) + 1e-6 * np.eye(3)


@pytest.mark.parametrize("version", [1, 2])
def test_fastslam_batch_is_the_steps_bit_for_bit(version):
    deltas, noises = odometry(40)
    z = np.array([sighting(A), sighting(B)])
    one = ps.FastSlam(np.zeros((3, 3)), Q, num_particles=30, version=version, seed=7)
    many = ps.FastSlam(np.zeros((3, 3)), Q, num_particles=30, version=version, seed=7)
    for f in (one, many):
        f.update_unknown(z)
    for d, n in zip(deltas[:25], noises[:25]):
        one.predict_odometry(d, n)
    many.predict_odometry_batch(deltas[:25], noises[:25])
    for f in (one, many):
        f.update_unknown(np.array([sighting(A, f.mean_pose)]))
    for d, n in zip(deltas[25:], noises[25:]):
        one.predict_odometry(d, n)
    many.predict_odometry_batch(deltas[25:], noises[25:])
    np.testing.assert_array_equal(one.poses, many.poses)
    np.testing.assert_array_equal(one.log_weights, many.log_weights)
    for k in range(one.num_particles):
        np.testing.assert_array_equal(one.path(k), many.path(k))


def test_fastslam_refused_batch_changes_nothing():
    deltas, noises = odometry(10)
    f = ps.FastSlam(np.zeros((3, 3)), Q, num_particles=10, version=2, seed=1)
    f.predict_odometry_batch(deltas[:3], noises[:3])
    before = (f.poses.copy(), [f.path(k).copy() for k in range(10)])
    bad = deltas.copy()
    bad[6, 1] = np.nan
    with pytest.raises(ValueError, match=r"^deltas\[6\]"):
        f.predict_odometry_batch(bad, noises)
    bad_noise = noises.copy()
    bad_noise[4] = -np.eye(3)
    with pytest.raises(ValueError, match=r"^noises\[4\]"):
        f.predict_odometry_batch(deltas, bad_noise)
    far = deltas.copy()
    far[8, 0] = 9e8  # a step of 0.9e9 m: the robot beyond 1e9 m after two of them
    far[9, 0] = 9e8
    with pytest.raises(ValueError, match="^deltas"):
        f.predict_odometry_batch(far, noises)
    with pytest.raises(ValueError, match="^noises"):
        f.predict_odometry_batch(deltas, noises[:5])
    with pytest.raises(ValueError, match="^deltas"):
        f.predict_odometry_batch(deltas[:, :2], noises)
    np.testing.assert_array_equal(f.poses, before[0])
    for k in range(10):
        np.testing.assert_array_equal(f.path(k), before[1][k])
    # and it continues as one never refused
    g = ps.FastSlam(np.zeros((3, 3)), Q, num_particles=10, version=2, seed=1)
    g.predict_odometry_batch(deltas[:3], noises[:3])
    f.predict_odometry_batch(deltas[3:], noises[3:])
    g.predict_odometry_batch(deltas[3:], noises[3:])
    np.testing.assert_array_equal(f.poses, g.poses)


def ekf_with_landmarks():
    ekf = ps.EkfSlam(np.diag([0.01, 0.01]), Q)
    ekf.update(np.array([sighting(A), sighting(B), sighting(C)]), [0, 1, 2])
    return ekf


def test_ekf_batch_is_the_steps_to_rounding():
    deltas, noises = odometry(200, seed=4)
    one, many = ekf_with_landmarks(), ekf_with_landmarks()
    poses = []
    for d, n in zip(deltas, noises):
        one.predict_odometry(d, n)
        poses.append(one.pose)
    batch = many.predict_odometry_batch(deltas, noises)
    np.testing.assert_allclose(batch, np.array(poses), rtol=0, atol=BATCH_TOLERANCE)
    np.testing.assert_allclose(many.mean, one.mean, rtol=0, atol=BATCH_TOLERANCE)
    np.testing.assert_allclose(many.covariance, one.covariance, rtol=0, atol=BATCH_TOLERANCE)
    assert batch.shape == (200, 3) and many.predict_odometry_batch(deltas[:0], noises[:0]).shape == (0, 3)


def test_ekf_refused_batch_changes_nothing():
    deltas, noises = odometry(10)
    ekf = ekf_with_landmarks()
    mean, cov = ekf.mean.copy(), ekf.covariance.copy()
    bad = deltas.copy()
    bad[7, 2] = np.inf
    with pytest.raises(ValueError, match=r"^deltas\[7\]"):
        ekf.predict_odometry_batch(bad, noises)
    bad_noise = noises.copy()
    bad_noise[2, 0, 1] += 1.0  # not symmetric
    with pytest.raises(ValueError, match=r"^noises\[2\]"):
        ekf.predict_odometry_batch(deltas, bad_noise)
    with pytest.raises(ValueError, match="^noises"):
        ekf.predict_odometry_batch(deltas, noises.reshape(10, 9))
    with pytest.raises(TypeError, match="^deltas"):
        ekf.predict_odometry_batch(None, noises)
    np.testing.assert_array_equal(ekf.mean, mean)
    np.testing.assert_array_equal(ekf.covariance, cov)


# ---- the Victoria Park driver's blocks against one call per step ------------------------------

#: The driver's EKF over a prefix against one predict_odometry per step: the batched prediction
#: reassociates the cross-covariance products (above), and 60 s of updates carry that rounding.
DRIVER_TOLERANCE = 1e-9


@pytest.mark.slow  # two FastSLAM and two EKF runs over 60 s of the run
def test_victoria_park_driver_blocks_equal_one_call_per_step():
    from conftest import SHARED_DATA
    from probslam.datasets import victoria_park_acfr, victoria_park_acfr_run as run
    folder = SHARED_DATA / "landmark_slam" / "victoria_park_acfr"
    if not folder.is_dir():
        pytest.skip(f"{folder} not present")
    data = run.first_seconds(victoria_park_acfr.load(folder), 60.0)
    steps = run.schedule(data)
    z = [data.measurements[a:b, 1:4] for a, b in zip(data.scan_starts[:-1], data.scan_starts[1:])]
    order = np.argsort(steps.scan_after, kind="stable")

    def stepwise(predict, update):
        pending = list(order)
        while pending and steps.scan_after[pending[0]] < 0:
            update(z[pending.pop(0)])
        for k in range(len(steps.ends)):
            predict(steps.deltas[k], steps.covariances[k])
            while pending and steps.scan_after[pending[0]] == k:
                update(z[pending.pop(0)])

    fast = run.run_fastslam(data, seed=3)
    f = ps.FastSlam(np.zeros((3, 3)), run.measurement_noise(True), num_particles=100, seed=3, use_signatures=True,
                    initial_pose=victoria_park_acfr.start_pose(data), p_new=ps.fastslam.DEFAULT_P_NEW)
    stepwise(f.predict_odometry, f.update_unknown)
    np.testing.assert_array_equal(fast.poses, f.path())
    ekf = run.run_ekf(data)
    e = ps.EkfSlam(run.control_noise(), run.measurement_noise(True), use_signatures=True,
                   initial_pose=victoria_park_acfr.start_pose(data))
    poses = [e.pose]

    def predict(delta, cov):
        e.predict_odometry(delta, cov)
        poses.append(e.pose)
    stepwise(predict, lambda zs: e.update_unknown(zs, association="jcbb"))
    np.testing.assert_allclose(ekf.poses, np.array(poses), rtol=0, atol=DRIVER_TOLERANCE)
    assert len(ekf.landmarks) == e.num_landmarks
