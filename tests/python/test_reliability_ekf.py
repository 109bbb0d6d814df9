"""Issue 12 in the EKF and the core models: every public call validates all of its input before
it changes anything, returns finite values or raises ValueError/TypeError with the filter
unchanged, and is safe when several Python threads share one filter."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import policy
import probslam as ps
from probslam import _core

COVERED = (
    "EkfSlam.__init__", "EkfSlam.predict", "EkfSlam.predict_odometry", "EkfSlam.update",
    "EkfSlam.update_unknown", "EkfSlam.pairing_likelihood", "EkfSlam.landmark", "EkfSlam.landmark_covariance",
    "EkfSlam.existence", "EkfSlam.remove_landmark", "EkfSlam.map_management", "EkfSlam.copy",
    "_core._EkfSlam.__init__", "_core._EkfSlam.update", "_core._EkfSlam.predict", "_core._EkfSlam.gate_distance",
    "MultiHypothesisEkfSlam.__init__", "MultiHypothesisEkfSlam.predict", "MultiHypothesisEkfSlam.update",
    "Pose2.__init__", "Pose2.from_array", "Pose2.compose", "Pose2.between", "Pose2.inverse",
    "Pose2.transform_from", "Pose2.transform_to",
    "velocity_motion", "velocity_motion_jacobian", "velocity_motion_control_jacobian",
    "range_bearing", "range_bearing_jacobians", "landmark_from_range_bearing",
    "landmark_from_range_bearing_jacobians", "wrap_angle",
)

R = np.diag([0.01, 0.01, 0.001])
Q = np.diag([0.01, 0.001])
PROPERTY = policy.property_settings(max_examples=60)


def filled(signatures=False):
    """A filter with three landmarks (ids 2, 5, 7) after one motion."""
    q = np.diag([0.01, 0.001, 0.1]) if signatures else Q
    ekf = ps.EkfSlam(R, q, use_signatures=signatures, initial_pose_cov=np.eye(3) * 1e-3)
    ekf.predict(1.0, 0.1, 0.5)
    z = np.array([[2.0, 0.3, 1.0], [4.0, -1.0, 2.0], [3.0, 2.0, 3.0]])[:, :3 if signatures else 2]
    ekf.update(z, [2, 5, 7])
    return ekf


def snapshot(ekf):
    return policy.state_of(ekf, "mean", "covariance", "landmarks", "pose", "num_provisional")


def assert_unchanged_after(ekf, call, err=ValueError, match=None):
    before = snapshot(ekf)
    with pytest.raises(err, match=match):
        call()
    assert policy.same_state(before, snapshot(ekf))


def run_isolated(code: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """Runs code in a fresh interpreter: a crash there fails the test instead of killing pytest.
    env: variables added to this process's environment."""
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=300,
                          env=None if env is None else {**os.environ, **env})


# --- 1. crashes: every shape is validated -------------------------------------------------
@pytest.mark.parametrize("cov", ["np.zeros((0, 0))", "np.eye(1)", "np.eye(2)", "np.eye(4)", "np.zeros(3)",
                                 "np.float64(1.0)", "np.zeros((3, 3, 1))"])
def test_initial_pose_cov_of_any_other_shape_is_refused(cov):
    result = run_isolated(f"""
        import numpy as np, probslam as ps
        from probslam import _core
        for make in (lambda c: ps.EkfSlam(np.eye(3), np.eye(2), use_signatures=False, initial_pose_cov=c),
                     lambda c: _core._EkfSlam(np.eye(3), np.eye(2), False, np.zeros(3), c)):
            try:
                make({cov})
            except ValueError as e:
                assert "initial_pose_cov" in str(e), e
            else:
                raise SystemExit("accepted")
    """)
    assert result.returncode == 0, result.stderr + result.stdout


@pytest.mark.parametrize("call, err, name", [
    (lambda: ps.EkfSlam(np.eye(1), Q, use_signatures=False), ValueError, "motion_noise"),
    (lambda: ps.EkfSlam(np.zeros((0, 0)), Q, use_signatures=False), ValueError, "motion_noise"),
    (lambda: ps.EkfSlam(np.ones((3, 2)), Q, use_signatures=False), ValueError, "motion_noise"),
    (lambda: ps.EkfSlam(R, np.eye(3), use_signatures=False), ValueError, "measurement_noise"),
    (lambda: ps.EkfSlam(R, np.zeros((0, 0)), use_signatures=False), ValueError, "measurement_noise"),
    (lambda: ps.EkfSlam(R, Q, use_signatures=False, initial_pose=np.zeros(2)), ValueError, "initial_pose"),
    (lambda: ps.EkfSlam(R * 1e300, Q, use_signatures=False), ValueError, "motion_noise"),
    (lambda: ps.EkfSlam(R, Q, use_signatures=False, initial_pose=(1e300, 0, 0)), ValueError, "initial_pose"),
    (lambda: ps.EkfSlam(R, Q, use_signatures=False, map_management="abc"), TypeError, "map_management"),
    (lambda: ps.EkfSlam(R, Q, use_signatures=False, gate_distance=np.nan), ValueError, "gate_distance"),
])
def test_bad_construction_is_refused_by_name(call, err, name):
    with pytest.raises(err, match=name):
        call()


@pytest.mark.parametrize("call, err, name", [
    (lambda e: e.predict(1.0, 0.1, 0.5, noise=np.eye(1)), ValueError, "noise"),
    (lambda e: e.predict(1.0, 0.1, 0.5, noise=np.zeros((0, 0))), ValueError, "noise"),
    (lambda e: e.predict(1.0, 0.1, 0.5, noise=np.eye(4)), ValueError, "noise"),
    (lambda e: e.predict_odometry([0, 0, 0], np.eye(2)), ValueError, "noise"),
    (lambda e: e.predict_odometry([0, 0], np.eye(3)), ValueError, "delta"),
    (lambda e: e.update(np.zeros(()), []), ValueError, "z"),
    (lambda e: e.update(np.zeros((1, 2, 1)), [1]), ValueError, "z"),
    (lambda e: e.update([[1.0, 0.1]], [-1]), ValueError, "ids"),
    (lambda e: e.update([[1.0, 0.1]], np.array([2**63 + 5], np.uint64)), ValueError, "ids"),
    (lambda e: e._f.update([[1.0, 0.1]], np.array([1.5]), np.inf), TypeError, "ids"),
    (lambda e: e._f.update([[1.0, 0.1]], np.array([True]), np.inf), TypeError, "ids"),
    (lambda e: e.update([[1.0, 0.1]], [1], gate=np.nan), ValueError, "gate"),
    (lambda e: e.update_unknown([[1.0, 0.1]], alpha=np.nan), ValueError, "alpha"),
    (lambda e: e.update_unknown([[1.0, 0.1]], alpha=1.0, alpha_new=np.nan), ValueError, "alpha_new"),
    (lambda e: e.pairing_likelihood([[1.0, 0.1], [2.0, 0.1]], 2), ValueError, "z"),
    (lambda e: e.pairing_likelihood([1.0, 0.1], -3), ValueError, "id"),
    (lambda e: e.remove_landmark(99), ValueError, "id"),
    (lambda e: e.existence(99), ValueError, "id"),
])
def test_bad_calls_are_refused_by_name_and_change_nothing(call, err, name):
    ekf = filled()
    assert_unchanged_after(ekf, lambda: call(ekf), err, name)


@pytest.mark.parametrize("field, value", [
    ("min_observations", -3), ("provisional_max_age", -1), ("provisional_max_std", np.nan),
    ("existence_hit", 1e300), ("existence_miss", np.inf), ("existence_threshold", np.nan),
    ("sensor_range", np.nan), ("sensor_fov", -1.0),
])
def test_nonsensical_map_management_is_refused_when_set(field, value):
    ekf = filled()
    m = ps.MapManagement()
    setattr(m, field, value)
    before = ekf.map_management
    with pytest.raises(ValueError, match=field):
        ekf.map_management = m
    assert getattr(ekf.map_management, field) == getattr(before, field)


@pytest.mark.parametrize("field, value", [
    ("max_hypotheses", -1), ("max_hypotheses", 10**7), ("max_children", 0), ("max_children", 10**7),
    ("gate", np.nan), ("new_landmark_cost", np.inf), ("clutter_cost", -1.0), ("prune_margin", np.nan),
])
def test_nonsensical_multi_hypothesis_options_are_refused(field, value):
    o = _core.MultiHypothesisOptions()
    setattr(o, field, value)
    with pytest.raises(ValueError, match=field):
        _core._MultiHypothesisEkfSlam(filled()._f, o)


def test_state_size_is_bounded_before_allocation():
    ekf = ps.EkfSlam(R, Q, use_signatures=False)
    n = 10**5  # 2e5-dimensional state: an 320 GB covariance
    z = np.column_stack([np.full(n, 2.0), np.linspace(-3, 3, n)])
    assert_unchanged_after(ekf, lambda: ekf.update(z, np.arange(n)), ValueError, "state")
    assert_unchanged_after(ekf, lambda: ekf.update_unknown(z), ValueError, "state")


# --- 3. finite or raise, and 4. all or nothing ----------------------------------------------
@pytest.mark.parametrize("signatures", [False, True])
def test_a_huge_range_is_refused_not_folded_into_an_infinite_covariance(signatures):
    ekf = filled(signatures)
    bad = [1e200, 0.1, 5.0][:3 if signatures else 2]
    ok = [2.1, 0.3, 1.0][:3 if signatures else 2]
    # the bad row comes after two good ones: neither may be applied
    assert_unchanged_after(ekf, lambda: ekf.update([ok, ok, bad], [2, 11, 12]), ValueError, "z")
    assert_unchanged_after(ekf, lambda: ekf.update([ok, bad], [2, 5]), ValueError, "z")
    for association in ("ml", "jcbb"):
        assert_unchanged_after(ekf, lambda: ekf.update_unknown([ok, bad], association=association), ValueError, "z")
    mht = ps.MultiHypothesisEkfSlam(ekf)
    before = (mht.num_hypotheses, mht.total_cost, mht.best.mean.copy(), mht.best.covariance.copy())
    with pytest.raises(ValueError, match="z"):
        mht.update([ok, bad])
    assert before[:2] == (mht.num_hypotheses, mht.total_cost)
    np.testing.assert_array_equal(before[2], mht.best.mean)
    np.testing.assert_array_equal(before[3], mht.best.covariance)


@pytest.mark.parametrize("call, name", [
    (lambda e: e.predict(1e300, 0.0, 1e10), "v"),
    (lambda e: e.predict(1.0, 1e300, 1e300), "w"),
    (lambda e: e.predict(1.0, 0.0, 1.0, noise=np.eye(3) * 1e300), "noise"),
    (lambda e: e.predict(1.0, 0.0, 1.0, noise=np.eye(2) * 1e300), "noise"),
    (lambda e: e.predict(1e150, 0.0, 1.0, noise=np.eye(2)), "v"),
    (lambda e: e.predict_odometry([1e300, 0, 0], np.eye(3)), "delta"),
    (lambda e: e.predict_odometry([1, 0, 0], np.eye(3) * 1e300), "noise"),
])
def test_huge_motion_is_refused_with_the_filter_unchanged(call, name):
    ekf = filled()
    assert_unchanged_after(ekf, lambda: call(ekf), ValueError, name)
    assert np.all(np.isfinite(ekf.covariance))


def test_calls_at_the_limits_apply_finitely_or_change_nothing():
    """Every input at the edge of its limit (variances 1e18, ranges and motions of 1e9 m) over
    many calls: each call either applies with a finite state or raises with the state exactly
    as before. (Before the limits, this run filled the covariance with inf and NaN.)"""
    big = 1e18
    ekf = ps.EkfSlam(np.eye(3) * big, np.diag([big, 1.0]), use_signatures=False, initial_pose_cov=np.eye(3) * big)
    calls = [lambda: ekf.predict(1e6, 1.0, 1e3), lambda: ekf.predict(1e6, 1.0, 1e3, noise=np.eye(2) * big),
             lambda: ekf.predict_odometry([1e8, -1e8, 3.0], np.eye(3) * big),
             lambda: ekf.update([[1e9, 0.5], [1e9, -0.5], [1e9, 2.0], [0.0, 0.0]], [0, 1, 2, 3]),
             lambda: ekf.update_unknown([[1e9, 0.5], [1e9, -2.5]], association="jcbb"),
             lambda: ekf.update_unknown([[1e9, 1.5], [1e3, -2.5]]),
             # and beyond them: refused
             lambda: ekf.update([[1e3, 0.1], [1e200, 0.1]], [0, 7]), lambda: ekf.predict(1e150, 1.0, 1.0),
             lambda: ekf.predict(1.0, 1.0, 1.0, noise=np.eye(3) * 1e300),
             lambda: ekf.update_unknown([[1e3, 0.1], [1e250, 0.2]], association="jcbb")]
    refused = 0
    for step in range(100):
        before = snapshot(ekf)
        try:
            calls[step % len(calls)]()
        except ValueError:
            refused += 1
            assert policy.same_state(before, snapshot(ekf))
        assert finite_state(ekf), step
    assert ekf.num_landmarks > 0 and refused >= 40


def test_views_still_see_updates_in_place():
    ekf = filled()
    mean, cov = ekf.mean, ekf.covariance
    ekf.update([[2.05, 0.31]], [2])
    np.testing.assert_array_equal(mean, ekf.mean)
    np.testing.assert_array_equal(cov, ekf.covariance)


@pytest.mark.slow
def test_joint_compatibility_on_a_dense_cluster_ends():
    """JCBB is exponential in the worst case: 16 measurements of 25 landmarks packed within the
    noise ran for minutes. The search is now bounded (kJcbbMaxNodes) and returns its best
    jointly compatible hypothesis. Run in a subprocess with a timeout, so a hang fails."""
    result = run_isolated("""
        import numpy as np, probslam as ps
        rng = np.random.default_rng(1)
        n = 25
        ekf = ps.EkfSlam(np.diag([0.01, 0.01, 0.001]), np.diag([0.5, 0.05]), use_signatures=False,
                         initial_pose_cov=np.eye(3) * 0.5)
        ekf.update(np.column_stack([10 + rng.uniform(-0.3, 0.3, n), rng.uniform(-0.05, 0.05, n)]), np.arange(n))
        z = np.column_stack([10 + rng.uniform(-0.3, 0.3, 20), rng.uniform(-0.05, 0.05, 20)])
        r = ekf.update_unknown(z, association="jcbb")
        paired = r.ids[r.outcome == r.ASSOCIATED]
        assert len(paired) > 0 and len(set(paired)) == len(paired)
        assert np.all(np.isfinite(ekf.covariance))
        print("ok")
    """)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "ok" in result.stdout


# --- 2. threads --------------------------------------------------------------------------
THREAD_PRELUDE = """
import threading, numpy as np, probslam as ps
def run(targets):
    errors = []
    barrier = threading.Barrier(len(targets))
    def wrap(f):
        def go():
            barrier.wait()
            try:
                f()
            except BaseException as e:
                errors.append(e)
        return go
    threads = [threading.Thread(target=wrap(f)) for f in targets]
    for t in threads: t.start()
    for t in threads: t.join()
    assert not errors, errors
"""


# With FMA a landmark's entries round differently by where the landmark sits in the state (the
# covariance product takes another path at the end of a tile: src/ekf/gram_kernels.hpp): a
# threaded run matches a serial replay to this relative tolerance, a few roundings per update
# over 150 updates (at most 2e-15 measured over 20 random interleavings), far below a torn
# update's error (the size of the entries themselves).
FMA_REPLAY_RTOL = 1e-12


@pytest.mark.slow
@pytest.mark.parametrize("kernels", ["generic", "default"])
def test_threads_updating_one_filter_equal_a_serial_replay(kernels):
    """With a robot whose covariance is exactly zero and stays so (no motion noise, no motion),
    landmarks are uncorrelated: an update of one landmark changes only that landmark's entries,
    and a zero predict changes nothing, bit for bit. Threads that each own a set of landmarks
    therefore give exactly the state of any serial replay with the plain kernel (compared landmark
    by landmark: the order in which threads first see their landmarks decides the state order),
    and the same to FMA_REPLAY_RTOL with the CPU's own (AVX2 + FMA where it has them)."""
    exact = kernels == "generic"
    result = run_isolated(f"EXACT, RTOL = {exact}, {FMA_REPLAY_RTOL}\n" + THREAD_PRELUDE + """
def make():
    return ps.EkfSlam(np.diag([1e-3, 1e-3]), np.diag([0.01, 0.001]), use_signatures=False)
def script(t, rng):
    ops = []
    for step in range(150):
        ids = 100 * t + rng.choice(8, size=rng.integers(1, 4), replace=False)
        z = np.column_stack([rng.uniform(1, 20, len(ids)), rng.uniform(-3, 3, len(ids))])
        ops.append(("update", z, ids))
        ops.append(("predict",))
        ops.append(("read", int(ids[0])))
    return ops
def apply(e, op):
    if op[0] == "update":
        e.update(op[1], op[2])
    elif op[0] == "predict":
        e.predict(0.0, 0.0, 1.0, noise=np.zeros((3, 3)))
    else:
        e.landmark(op[1]); e.landmark_covariance(op[1]); e.pose; e.landmarks().ids
scripts = [script(t, np.random.default_rng(t)) for t in range(4)]
shared = make()
run([lambda s=s: [apply(shared, op) for op in s] for s in scripts])
serial = make()
for s in scripts:
    for op in s:
        apply(serial, op)
assert sorted(shared.landmarks().ids) == sorted(serial.landmarks().ids)
same = np.array_equal if EXACT else (lambda a, b: np.allclose(a, b, rtol=RTOL, atol=0.0))
for i in serial.landmarks().ids:
    assert same(shared.landmark(i), serial.landmark(i)), i
    assert same(shared.landmark_covariance(i), serial.landmark_covariance(i)), i
assert np.array_equal(shared.pose, serial.pose)
cov = shared.covariance
blocks = np.zeros_like(cov, bool)
blocks[:3, :3] = True
for k in range(shared.num_landmarks):
    blocks[3 + 2 * k:5 + 2 * k, 3 + 2 * k:5 + 2 * k] = True
assert np.all(cov[~blocks] == 0.0)
print("ok")
""", env={"PROBSLAM_EKF_KERNELS": "generic"} if exact else None)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "ok" in result.stdout


@pytest.mark.slow
def test_threads_mixing_every_call_keep_the_filter_consistent():
    """update_unknown, motion, removal, copies and reads from several threads on one filter and
    one multi-hypothesis filter: no crash, and the state stays finite, symmetric and positive
    semi-definite, with a landmark list that matches the state's size."""
    result = run_isolated(THREAD_PRELUDE + """
ekf = ps.EkfSlam(np.diag([0.01, 0.002]), np.diag([0.01, 0.001]), use_signatures=False)
mht = ps.MultiHypothesisEkfSlam(ps.EkfSlam(np.diag([0.01, 0.002]), np.diag([0.01, 0.001]), use_signatures=False))
def scan(rng):
    return np.column_stack([rng.uniform(1, 10, 4), rng.uniform(-3, 3, 4)])
def unknown(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        ekf.update_unknown(scan(rng), association="jcbb" if seed % 2 else "ml")
def mover(seed):
    for _ in range(300):
        ekf.predict(0.5, 0.1, 0.1)
        ekf.predict_odometry([0.01, 0.0, 0.001], np.eye(3) * 1e-4)
def known(seed):
    rng = np.random.default_rng(seed)
    for _ in range(100):
        ekf.update(scan(rng)[:2], [1000 + rng.integers(5), 2000 + rng.integers(5)])
def remover(seed):
    for _ in range(200):
        ids = ekf.landmarks().ids
        if len(ids):
            try:
                ekf.remove_landmark(int(ids[-1]))
            except ValueError:
                pass  # another thread removed it first
        ekf.copy(); ekf.pose; ekf.num_landmarks
def hypotheses(seed):
    rng = np.random.default_rng(seed)
    for _ in range(15):
        mht.predict(0.5, 0.1, 0.1)
        mht.update(scan(rng)[:3])
        mht.best; mht.pose; mht.costs; mht.history()
run([lambda: unknown(1), lambda: unknown(2), lambda: mover(3), lambda: known(4), lambda: remover(5),
     lambda: hypotheses(6), lambda: hypotheses(7)])
cov, mean = ekf.covariance, ekf.mean
assert np.all(np.isfinite(cov)) and np.all(np.isfinite(mean))
assert np.allclose(cov, cov.T, atol=1e-9)
assert np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() > -1e-6
assert len(mean) == 3 + 2 * ekf.num_landmarks == 3 + 2 * len(set(ekf.landmarks().ids))
print("ok")
""")
    assert result.returncode == 0, result.stderr[-3000:]
    assert "ok" in result.stdout


# --- 5. property tests -----------------------------------------------------------------------
def finite_state(ekf):
    return np.all(np.isfinite(ekf.mean)) and np.all(np.isfinite(ekf.covariance))


matrices = policy.arrays(max_side=4, max_dims=3)


@PROPERTY
@given(motion=matrices, measurement=matrices, pose=policy.arrays(max_side=4), cov=matrices,
       signatures=st.booleans())
def test_construction_property(motion, measurement, pose, cov, signatures):
    policy.check_call(lambda: _core._EkfSlam(motion, measurement, signatures, pose, cov))
    policy.check_call(lambda: ps.EkfSlam(motion, measurement, use_signatures=signatures, initial_pose=pose,
                                         initial_pose_cov=cov))


@PROPERTY
@given(z=policy.arrays(max_side=5, max_dims=3), ids=st.one_of(policy.arrays(max_side=5, max_dims=2),
                                                                st.lists(st.integers(-3, 2**63), max_size=5),
                                                                policy.odd_objects()),
       gate=st.one_of(st.none(), policy.floats()), signatures=st.booleans())
def test_update_property(z, ids, gate, signatures):
    ekf = filled(signatures)
    policy.check_call(lambda: ekf._f.update(z, ids, np.inf if gate is None else gate), lambda: snapshot(ekf),
                      finite=False)
    assert finite_state(ekf)
    int_ids = np.asarray(ids).astype(np.int64) if isinstance(ids, np.ndarray) and np.all(np.isfinite(ids)) and \
        np.all(np.abs(ids) < 1e9) else ids
    raised, result = policy.check_call(lambda: ekf.update(z, int_ids, gate), lambda: snapshot(ekf), finite=False)
    assert finite_state(ekf)
    if not raised:  # NaN marks a first sighting or a landmark on the robot (no bearing): never inf
        assert not np.any(np.isinf(result.nis))


@PROPERTY
@given(v=policy.floats(), w=policy.floats(), dt=policy.floats(), noise=st.one_of(st.none(), matrices),
       delta=policy.arrays(max_side=4, max_dims=2))
def test_predict_property(v, w, dt, noise, delta):
    ekf = filled()
    policy.check_call(lambda: ekf.predict(v, w, dt, noise), lambda: snapshot(ekf))
    assert finite_state(ekf)
    policy.check_call(lambda: ekf.predict_odometry(delta, np.eye(3) * 1e-3 if noise is None else noise),
                      lambda: snapshot(ekf))
    assert finite_state(ekf)


@PROPERTY
@given(z=policy.arrays(max_side=5, max_dims=3), alpha=st.one_of(st.none(), policy.floats()),
       alpha_new=st.one_of(st.none(), policy.floats()), association=st.sampled_from(["ml", "jcbb"]),
       provisional=st.booleans(), existence=st.booleans())
def test_update_unknown_property(z, alpha, alpha_new, association, provisional, existence):
    ekf = filled()
    m = ps.MapManagement()
    m.provisional, m.existence, m.min_observations = provisional, existence, 1
    ekf.map_management = m
    raised, result = policy.check_call(lambda: ekf.update_unknown(z, alpha, alpha_new, association),
                                       lambda: snapshot(ekf), finite=False)
    assert finite_state(ekf)
    if not raised:  # inf marks a measurement without candidates, and nothing else
        assert not np.any(np.isnan(result.mahalanobis))
        assert np.all(np.isfinite(result.mahalanobis) | (result.mahalanobis == np.inf))


@PROPERTY
@given(z=policy.arrays(max_side=4, max_dims=2), id=st.one_of(st.integers(-5, 10), st.sampled_from([2, 5, 7])),
       value=policy.floats())
def test_queries_and_removal_property(z, id, value):
    ekf = filled()
    for call in (lambda: ekf.pairing_likelihood(z, id), lambda: ekf.landmark(id), lambda: ekf.landmark_covariance(id),
                 lambda: ekf.existence(id), lambda: ekf.remove_landmark(id)):
        policy.check_call(call, lambda: snapshot(ekf))
    policy.check_call(lambda: setattr(ekf._f, "gate_distance", value), lambda: snapshot(ekf))
    assert finite_state(ekf)
    assert np.isfinite(ekf._f.gate_distance)


@PROPERTY
@given(max_hypotheses=st.integers(-2, 40), max_children=st.integers(-2, 10), costs=st.lists(policy.floats(), min_size=4,
                                                                                           max_size=4),
       z=policy.arrays(max_side=4, max_dims=2), motion=st.lists(policy.floats(), min_size=3, max_size=3))
def test_multi_hypothesis_property(max_hypotheses, max_children, costs, z, motion):
    gate, new_cost, clutter, margin = costs
    raised, mht = policy.check_call(lambda: ps.MultiHypothesisEkfSlam(
        filled(), max_hypotheses=max_hypotheses, max_children=max_children, gate=gate, new_landmark_cost=new_cost,
        clutter_cost=clutter, prune_margin=margin), finite=False)
    if raised:
        return

    def state():
        b = mht.best
        return {"n": mht.num_hypotheses, "cost": mht.total_cost, "costs": mht.costs, "mean": b.mean.copy(),
                "cov": b.covariance.copy(), "history": mht.history()}

    policy.check_call(lambda: mht.predict(*motion), state)
    policy.check_call(lambda: mht.update(z), state)
    assert np.all(np.isfinite(mht.costs)) and np.isfinite(mht.total_cost)
    assert finite_state(mht.best)


@PROPERTY
@given(pose=policy.arrays(max_side=4, max_dims=2), other=policy.arrays(max_side=4, max_dims=2),
       points=policy.arrays(max_side=4, max_dims=3), xyz=st.lists(policy.floats(), min_size=3, max_size=3))
def test_pose2_property(pose, other, points, xyz):
    raised, a = policy.check_call(lambda: ps.Pose2.from_array(pose), finite=False)
    raised_b, b = policy.check_call(lambda: ps.Pose2(*xyz), finite=False)
    if raised or raised_b:
        return
    for call in (lambda: a.compose(b).as_array(), lambda: (a * b).as_array(), lambda: a.between(b).as_array(),
                 lambda: a.inverse().as_array(), lambda: a.transform_from(points), lambda: a.transform_to(points),
                 lambda: (a.x, a.y, a.theta)):
        policy.check_call(call)


@PROPERTY
@given(pose=policy.arrays(max_side=4, max_dims=2), other=policy.arrays(max_side=4, max_dims=2),
       v=policy.floats(), w=policy.floats(), dt=policy.floats(), angles=policy.arrays(max_side=4))
def test_models_property(pose, other, v, w, dt, angles):
    for call in (lambda: ps.velocity_motion(pose, v, w, dt), lambda: ps.velocity_motion_jacobian(pose, v, w, dt),
                 lambda: ps.velocity_motion_control_jacobian(pose, v, w, dt),
                 lambda: ps.range_bearing(pose, other), lambda: ps.range_bearing_jacobians(pose, other),
                 lambda: ps.landmark_from_range_bearing(pose, other),
                 lambda: ps.landmark_from_range_bearing_jacobians(pose, other),
                 lambda: ps.wrap_angle(angles)):
        policy.check_call(call)


@pytest.mark.parametrize("call, name", [
    (lambda: ps.velocity_motion([0, 0, 0], 1e308, 0.0, 1e308), "v"),
    (lambda: ps.velocity_motion_control_jacobian([0, 0, 0], 1e308, 1.0, 1e308), "v"),
    (lambda: ps.range_bearing([-1e308, 0, 0], [1e308, 0]), "landmark"),
    (lambda: ps.range_bearing([0, 0, 0], [1.7e308, 1.7e308]), "landmark"),  # each offset finite, the range not
    (lambda: ps.landmark_from_range_bearing([1e308, 0, 0], [1e308, 0.0]), "z"),
    (lambda: ps.Pose2(1e308, 0, 0).compose(ps.Pose2(1e308, 0, 0)), "pose"),
    (lambda: ps.Pose2(1e308, 0, np.pi).inverse().compose(ps.Pose2(-1e308, 0, 0)), "pose"),
    (lambda: ps.Pose2(1e308, 0, 0).transform_from([1e308, 0]), "point"),
    (lambda: ps.wrap_angle(np.nan), "angle"),
    (lambda: ps.wrap_angle([0.0, np.inf]), "angle"),
])
def test_model_overflow_raises_instead_of_returning_inf(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_far_landmark_jacobians_are_finite_and_right():
    """The 1/q entries of H at 1e200 m: q overflows, the Jacobian must not (it is 1/r times a
    unit vector)."""
    pose, near = np.array([0.0, 0.0, 0.3]), np.array([3.0, 4.0])
    hx_near, hm_near = ps.range_bearing_jacobians(pose, near)
    hx_far, hm_far = ps.range_bearing_jacobians(pose, near * 4e199)  # r = 2e200
    np.testing.assert_allclose(hx_far[0], hx_near[0], rtol=1e-15)  # the same unit vector
    np.testing.assert_allclose(hm_far[1], hm_near[1] * 5 / 2e200, rtol=1e-15)
    np.testing.assert_allclose(hx_far[1, :2], hx_near[1, :2] * 5 / 2e200, rtol=1e-15)


def test_valid_simulated_runs_stay_finite_and_consistent():
    """A valid run, through every association, stays within the limits: nothing refused."""
    rng = np.random.default_rng(3)
    world = ps.sim.LandmarkWorld.random(12, 10.0, rng, min_separation=2.0)
    sensor = ps.sim.Sensor(Q, max_range=8.0, fov=np.radians(180))
    m = np.diag([0.003, 0.0005])
    run = ps.sim.simulate(world, ps.sim.circle_controls(120, 1.0, 0.12), 0.2, sensor, m, rng, initial_pose=(0, -8.3, 0))
    for association in ("ml", "jcbb"):
        ekf = ps.EkfSlam(m, Q, use_signatures=False, initial_pose=(0, -8.3, 0))
        for (v, w), z in zip(run.controls, run.measurements):
            ekf.predict(v, w, run.dt)
            ekf.update_unknown(z, association=association)
        assert finite_state(ekf) and ekf.num_landmarks == len({i for ids in run.ids for i in ids})
