"""The reliability policy for MonteCarloLocalization: odd input is refused with ValueError/TypeError
naming the argument and changes nothing (every observable field compared before and after), what
it accepts keeps the particle cloud finite, a long update stops on Ctrl-C with the filter as it
was, and the likelihood field's memory is bounded by the map whatever the field's sigma."""

import math
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from hypothesis import given

import policy
from walled_room import room
from probslam import _core

PROPERTY = policy.PROPERTY

COVERED = (
    "MonteCarloLocalization(*, options)",
    "MonteCarloLocalization.predict_odometry",
    "MonteCarloLocalization.update",
    "MonteCarloLocalization.initialize_pose",
    "MonteCarloLocalization.measurement_log_likelihood",
    "MonteCarloLocalization.kld_bound",
)

ANGLES = np.linspace(-1.5, 1.5, 31)


def ranges_from(grid, pose):
    """The readings of ANGLES at pose (ray cast in the room's walls)."""
    binary = _core.BinaryMap2D(grid, grid.probability() > 0.65)
    return _core.BeamSensorModel("laser", 10.0).expected_ranges(pose, ANGLES, binary)


def tracked(**options):
    """A filter after two updates at (3, 2, 0) in the room."""
    g = room()
    mcl = _core.MonteCarloLocalization(g, initial_pose=[3.0, 2.0, 0.0], min_particles=100, max_particles=300,
                                       seed=1, **options)
    z = ranges_from(g, [3.0, 2.0, 0.0])
    mcl.update(z, ANGLES)
    mcl.predict_odometry([0.3, 0.0, 0.05])
    mcl.update(z, ANGLES)
    return mcl, z


def full_state(mcl):
    """Every observable field of the filter, compared one by one."""
    return policy.state_of(mcl, "poses", "weights", "pose", "covariance", "num_particles", "num_updates",
                           "w_slow", "w_fast")


def future(mcl, z):
    """What the next update gives: equal for two filters only if their hidden state (pending
    odometry, random streams, averages) is."""
    c = mcl.copy()
    c.update(z, ANGLES, force=True)
    return full_state(c)


# ---- accepted input keeps the cloud finite, or is refused with the object unchanged ----

@pytest.mark.parametrize("delta", [(1e300, 0.0, 0.0), (0.0, -1e308, 0.0), (2e6, 0.0, 0.0)])
def test_an_odometry_step_no_robot_makes_is_refused(delta):
    mcl, z = tracked()
    before, after_next = full_state(mcl), future(mcl, z)
    with pytest.raises(ValueError, match="^delta moves more than 1e6 m"):
        mcl.predict_odometry(delta)
    assert policy.same_state(before, full_state(mcl))
    assert policy.same_state(after_next, future(mcl, z))  # the pending motion is untouched too
    mcl.update(z, ANGLES, force=True)
    assert np.all(np.isfinite(mcl.poses)) and np.all(np.isfinite(mcl.pose))


def test_pending_motion_is_bounded_and_the_filter_keeps_working():
    """Twice 1e308 once made every later update raise until re-initialised: now the second step
    (or the sum) is refused, and the filter goes on."""
    mcl, z = tracked()
    mcl.predict_odometry([9e5, 0.0, 0.0])
    with pytest.raises(ValueError, match="^delta would bring the motion pending"):
        mcl.predict_odometry([9e5, 0.0, 0.0])
    mcl.update(z, ANGLES, force=True)
    assert np.all(np.isfinite(mcl.poses)) and np.all(np.isfinite(mcl.weights))
    mcl.predict_odometry([0.2, 0.0, 0.0])
    mcl.update(z, ANGLES)  # still works


@pytest.mark.parametrize("sigma_hit", [1e-200, 1e-300, 1e300])
def test_extreme_sigma_hit_gives_finite_poses(sigma_hit):
    mcl, z = tracked(sigma=sigma_hit)
    for _ in range(3):
        mcl.predict_odometry([0.25, 0.0, 0.0])
        mcl.update(z, ANGLES)
    assert np.all(np.isfinite(mcl.poses)) and np.all(np.isfinite(mcl.pose))
    assert np.all(np.isfinite(mcl.covariance))
    assert math.isfinite(mcl.measurement_log_likelihood([3.0, 2.0, 0.0], z, ANGLES))


@pytest.mark.parametrize("sigma_hit", [1e-320, 1e301, math.inf, math.nan, 0.0])
def test_sigma_hit_beyond_its_bounds_is_named(sigma_hit):
    with pytest.raises(ValueError, match="^sigma must lie in"):
        _core.MonteCarloLocalization(room(), sigma=sigma_hit)


@pytest.mark.parametrize("sensor_model", ["likelihood-field", "beam"])
def test_beam_options_are_checked_and_named_whichever_model(sensor_model):
    """beam_sigma_hit = NaN was kept unseen with the likelihood field, and with the beam model
    refused as 'sigma_hit' (the likelihood field's option)."""
    with pytest.raises(ValueError, match="^beam.sigma_hit must be finite"):
        _core.MonteCarloLocalization(room(), sensor_model=sensor_model, beam={"sigma_hit": math.nan})
    with pytest.raises(ValueError, match="^beam.z_hit"):
        _core.MonteCarloLocalization(room(), sensor_model=sensor_model, beam={"z_hit": 0.9})  # weights sum to 1.05


def test_kld_bound_never_returns_inf():
    assert math.isfinite(_core.MonteCarloLocalization.kld_bound(1000, 1e-3, 3.0))
    for k, epsilon, z in ((2, 1e-309, 1.0), (10 ** 9, 1e-300, 0.0), (3, 0.05, 1e300)):
        with pytest.raises(ValueError, match="^epsilon"):
            _core.MonteCarloLocalization.kld_bound(k, epsilon, z)


@pytest.mark.parametrize("bins", [dict(bin_xy=5e-324), dict(bin_theta=5e-324), dict(bin_xy=1e300, bin_theta=2 * math.pi)])
def test_extreme_histogram_bins_give_a_finite_estimate(bins):
    """A bin of 5e-324 m or rad put a pose's bin index beyond int64 (undefined behaviour, caught by
    UBSan in the estimate's clustering); indices are now clamped. Every particle in its own bin
    (or all in one) still gives the weighted mean of its cluster."""
    g = room()
    z = ranges_from(g, [3.0, 2.0, 0.0])
    mcl = _core.MonteCarloLocalization(g, initial_pose=[3.0, 2.0, 0.0], min_particles=50, max_particles=200,
                                       seed=4, **bins)
    mcl.update(z, ANGLES, force=True)
    assert np.all(np.isfinite(mcl.pose)) and np.all(np.isfinite(mcl.covariance))
    assert np.hypot(mcl.pose[0] - 3.0, mcl.pose[1] - 2.0) < 0.5


# ---- memory bounded by the map ----

def test_a_huge_sigma_hit_gives_the_right_field():
    """sigma = 150 m: every end point lies within a metre of a wall, far inside 6 sigma, so
    each beam's log p is log((1 - p_rand) exp(-d^2 / 2 sigma^2) + p_rand) ~ 0."""
    g = room()
    mcl = _core.MonteCarloLocalization(g, sigma=150.0, min_particles=10, max_particles=10)
    z = ranges_from(g, [3.0, 2.0, 0.0])
    ll = mcl.measurement_log_likelihood([3.0, 2.0, 0.0], z, ANGLES)
    assert -1e-3 < ll <= 0.0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS as Linux has it")
@pytest.mark.skipif(bool(os.environ.get("PROBSLAM_SANITIZED")),
                    reason="AddressSanitizer's shadow memory cannot map under an address-space limit")
def test_a_huge_sigma_hit_builds_in_memory_bounded_by_the_map():
    """sigma = 150 m on a 20 x 20 m map of 0.05 m cells asked for tables of (6 sigma /
    resolution)^2 = 3.2e8 entries (2.6 GB); in a child process limited to 1 GiB of address space
    the filter now builds (its field holds the map's 160,000 cells)."""
    code = ("import resource, numpy as np\n"
            "resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))\n"
            "from probslam import _core\n"
            "g = _core.OccupancyGrid2D(0.05, 400, 400, origin=(0.0, 0.0))\n"
            "lo = np.full((400, 400), -3.0); lo[0] = lo[-1] = 3.0; lo[:, 0] = lo[:, -1] = 3.0\n"
            "g.log_odds[:] = lo\n"
            "_core.MonteCarloLocalization(g, sigma=150.0, min_particles=10, max_particles=10)\n"
            "print('ok')\n")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")  # no per-thread arenas
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


# ---- Ctrl-C ----

def _press_ctrl_c_until(done):
    while not done.wait(0.3):
        os.kill(os.getpid(), signal.SIGINT)


def test_a_long_beam_model_update_stops_on_ctrl_c_and_changes_nothing():
    """The beam model at 2^20 particles took minutes a scan, uninterruptible; now Ctrl-C ends the
    update within milliseconds, and the filter is exactly as before it."""
    g = room(res=0.05, w=400, h=400)
    mcl = _core.MonteCarloLocalization(g, sensor_model="beam", min_particles=1 << 18, max_particles=1 << 18,
                                       max_beams=200, max_range=30.0, seed=3)
    angles = np.linspace(-1.5, 1.5, 200)
    z = np.full(200, 5.0)
    before = full_state(mcl)
    done = threading.Event()
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    presser = threading.Thread(target=_press_ctrl_c_until, args=(done,), daemon=True)
    start = time.monotonic()
    presser.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            mcl.update(z, angles)  # 2^18 particles x 200 rays of up to 600 cells: minutes
    finally:
        done.set()
        presser.join()
        signal.signal(signal.SIGINT, previous)
    assert time.monotonic() - start < 10.0
    assert policy.same_state(before, full_state(mcl))


# ---- threads that cannot start ----

def test_threads_that_cannot_start_are_named_and_change_nothing():
    z = ranges_from(room(), [3.0, 2.0, 0.0])
    mcl = _core.MonteCarloLocalization(room(), initial_pose=[3.0, 2.0, 0.0], min_particles=2000,
                                       max_particles=2000, threads=4, seed=1)
    before = full_state(mcl)
    _core._fail_worker_thread_start_after(1)
    try:
        with pytest.raises(ValueError, match="^threads: the system refused to start 4 worker threads"):
            mcl.update(z, ANGLES)
    finally:
        _core._fail_worker_thread_start_after(-1)
    assert policy.same_state(before, full_state(mcl))
    mcl.update(z, ANGLES)  # the threads start now
    assert mcl.num_updates == 1


# ---- properties: odd input refused, object unchanged field by field ----

NUMERIC_OPTIONS = ["occupied_threshold", "free_threshold", "sigma", "p_rand", "beam.sigma_hit",
                   "beam.lambda_short", "max_range", "min_range", "weight_scale", "kld_epsilon", "kld_z", "bin_xy",
                   "bin_theta", "alpha_slow", "alpha_fast", "recovery_ratio", "resample_threshold", "update.distance",
                   "update.angle"]


@PROPERTY
@given(value=policy.floats(), pick=policy.st.integers(0, 10 ** 6))
def test_options_with_odd_numbers(value, pick):
    name = NUMERIC_OPTIONS[pick % len(NUMERIC_OPTIONS)]
    group, _, field = name.rpartition(".")
    fields = {group: {field: value}} if group else {name: value}
    raised, result = policy.check_call(lambda: _core.MonteCarloLocalization(room(), min_particles=50, max_particles=50,
                                                                            **fields))
    if np.isnan(value):
        assert raised, (name, value)
    if not raised:
        assert np.all(np.isfinite(result.poses)) and np.all(np.isfinite(result.pose))


@PROPERTY
@given(delta=policy.arrays())
def test_predict_odometry_with_odd_arrays(delta):
    mcl, z = tracked()
    before_next = future(mcl, z)
    raised, _ = policy.check_call(lambda: mcl.predict_odometry(delta), snapshot=lambda: full_state(mcl))
    if raised:
        assert policy.same_state(before_next, future(mcl, z))
    mcl.update(z, ANGLES, force=True)
    assert np.all(np.isfinite(mcl.poses)) and np.all(np.isfinite(mcl.weights))


@PROPERTY
@given(ranges=policy.arrays(), angles=policy.arrays())
def test_update_with_odd_arrays(ranges, angles):
    mcl, z = tracked()
    mcl.predict_odometry([0.3, 0.0, 0.0])
    before_next = future(mcl, z)
    raised, _ = policy.check_call(lambda: mcl.update(ranges, angles), snapshot=lambda: full_state(mcl))
    if raised:
        assert policy.same_state(before_next, future(mcl, z))
    else:
        assert np.all(np.isfinite(mcl.poses)) and np.all(np.isfinite(mcl.weights))


@PROPERTY
@given(pose=policy.arrays(), covariance=policy.arrays())
def test_initialize_pose_with_odd_arrays(pose, covariance):
    mcl, z = tracked()
    raised, _ = policy.check_call(lambda: mcl.initialize_pose(pose, covariance), snapshot=lambda: full_state(mcl))
    if not raised:
        assert np.all(np.isfinite(mcl.poses))


@PROPERTY
@given(pose=policy.arrays(), ranges=policy.arrays())
def test_measurement_log_likelihood_with_odd_arrays(pose, ranges):
    mcl, z = tracked()
    policy.check_call(lambda: mcl.measurement_log_likelihood(pose, ranges, ANGLES[:np.size(ranges)]),
                      snapshot=lambda: full_state(mcl))


@PROPERTY
@given(k=policy.st.one_of(policy.st.integers(-5, 10 ** 9), policy.odd_objects()), epsilon=policy.floats(),
       z=policy.floats())
def test_kld_bound_with_odd_numbers(k, epsilon, z):
    policy.check_call(lambda: _core.MonteCarloLocalization.kld_bound(k, epsilon, z))


@PROPERTY
@given(odd=policy.odd_objects())
def test_odd_objects(odd):
    mcl, z = tracked()
    for call in (lambda: mcl.update(odd, ANGLES), lambda: mcl.predict_odometry(odd),
                 lambda: mcl.initialize_pose(odd, np.eye(3)), lambda: mcl.measurement_log_likelihood(odd, z, ANGLES)):
        policy.check_call(call, snapshot=lambda: full_state(mcl))
