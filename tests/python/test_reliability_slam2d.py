"""The reliability policy for the stateful laser SLAM classes (IncrementalScanMatcher,
SubmapSlam2D, GridFastSlam): odd arrays are refused with ValueError/TypeError and change nothing; several
threads sharing one object get the same result as one thread feeding it in order."""

import numpy as np
import pytest
from hypothesis import given, settings, HealthCheck

import policy
from probslam import _core
from corridor_world import ANGLES, MAX_RANGE, corridor_drive

PROPERTY = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
CLASSES = [_core.IncrementalScanMatcher, _core.SubmapSlam2D, _core.GridFastSlam]

_DRIVE = corridor_drive(laps=0.3)


def fed(cls, n=4):
    true, odo, ranges = _DRIVE
    obj = cls(max_range=MAX_RANGE)
    obj.add_scans(ranges[:n], ANGLES, odo[:n], np.arange(n, dtype=float))
    return obj


def state(obj):
    if isinstance(obj, _core.GridFastSlam):
        return {"n": obj.num_scans, "poses": obj.scan_poses() if obj.num_scans else np.zeros((0, 3)),
                "w": obj.log_weights, "t": obj.timestamps}
    poses = obj.scan_poses if isinstance(obj, _core.SubmapSlam2D) else obj.poses
    return {"n": obj.num_scans, "poses": poses, "info": obj.scan_info, "t": obj.timestamps}


#: Numeric options of each class (the scan matchers share the frontend's).
FRONTEND_OPTIONS = ["resolution", "max_range", "min_range", "max_usable_range", "sigma", "p_rand", "linear_window",
                    "angular_window", "min_travel", "min_rotation", "submap_distance", "min_match_quality",
                    "field_refresh_distance", "field_refresh_angle"]
RBPF_OPTIONS = ["resolution", "max_range", "min_range", "max_usable_range", "sigma", "p_rand", "search_radius",
                "linear_step", "angular_step", "sample_linear", "sample_angular", "min_match_quality",
                "resample_threshold", "update_distance", "update_angle"]


@pytest.mark.parametrize("cls", CLASSES)
@PROPERTY
@given(ranges=policy.arrays(), angles=policy.arrays(), odometry=policy.arrays(), stamps=policy.arrays())
@pytest.mark.slow
def test_add_scans_with_odd_arrays(cls, ranges, angles, odometry, stamps):
    obj = fed(cls)
    policy.check_call(lambda: obj.add_scans(ranges, angles, odometry, stamps), snapshot=lambda: state(obj))


@pytest.mark.parametrize("cls", CLASSES)
@PROPERTY
@given(value=policy.floats(), pick=policy.st.integers(0, 10 ** 6))
def test_options_with_odd_numbers(cls, value, pick):
    names = RBPF_OPTIONS if cls is _core.GridFastSlam else FRONTEND_OPTIONS
    name = names[pick % len(names)]
    raised, _ = policy.check_call(lambda: cls(**{name: value}))
    if np.isnan(value) or (np.isinf(value) and name != "max_range"):  # max_range = inf: none stated
        assert raised, (name, value)


@pytest.mark.parametrize("cls", CLASSES)
@PROPERTY
@given(odd=policy.odd_objects())
@pytest.mark.slow
def test_odd_objects(cls, odd):
    obj = fed(cls)
    policy.check_call(lambda: obj.add_scans(odd, ANGLES, np.zeros((1, 3)), np.zeros(1)), snapshot=lambda: state(obj))
    policy.check_call(lambda: cls(resolution=odd))


@pytest.mark.parametrize("cls", CLASSES)
@pytest.mark.slow
def test_threads_sharing_one_object(cls):
    true, odo, ranges = _DRIVE
    n = len(true)
    alone = cls(max_range=MAX_RANGE)
    for k in range(n):
        alone.add_scans(ranges[k:k + 1], ANGLES, odo[k:k + 1], np.array([float(k)]))
    shared = cls(max_range=MAX_RANGE)
    order = []

    def feeder():
        # Each thread takes the next scan under the object's own lock: the order is the log's.
        for _ in range(n):
            with lock:
                if len(order) == n:
                    return
                k = len(order)
                order.append(k)
                shared.add_scans(ranges[k:k + 1], ANGLES, odo[k:k + 1], np.array([float(k)]))

    def reader():
        # Each property is read under the lock: whole and finite, though scans may arrive between two.
        seen = 0
        for _ in range(50):
            s = state(shared)
            assert seen <= s["n"] <= n and len(s["poses"]) <= n and np.isfinite(s["poses"]).all()
            seen = s["n"]

    import threading
    lock = threading.Lock()
    errors = policy.run_threads([feeder, feeder, reader, reader])
    assert not errors, errors
    np.testing.assert_array_equal(state(shared)["poses"], state(alone)["poses"])
