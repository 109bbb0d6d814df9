"""The reliability policy (docs/reliability.md) as reusable test pieces.

Property tests (hypothesis) feed public calls odd arrays and check the policy: the call either
returns a finite result or raises ValueError/TypeError (IndexError/KeyError where the API says so),
and an object is exactly as it was after a call that raised. Use:

    @given(z=policy.arrays())
    def test_update(z):
        ekf = make()
        policy.check_call(lambda: ekf.update(z, ids), snapshot=lambda: policy.state_of(ekf, "mean", "covariance"))
"""
from __future__ import annotations

import inspect
import threading
from typing import Any, Callable, Iterable

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

def property_settings(max_examples: int = 40) -> settings:
    """The property tests' settings: max_examples inputs a test, no deadline (a call's first run can
    be slow) and too_slow not a failure (each example builds its objects afresh)."""
    return settings(max_examples=max_examples, deadline=None, suppress_health_check=[HealthCheck.too_slow])


#: The settings of the property tests (test_reliability_*.py).
PROPERTY = property_settings()

# Exceptions the policy allows a public call to raise for bad input.
CLEAN_ERRORS = (ValueError, TypeError, IndexError, KeyError, OverflowError)

# Values that break numerics: the policy requires each to be refused or handled, never propagated.
SPECIAL_FLOATS = [np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-300, 1e200, -1e200, 1e308, np.finfo(float).max]


def floats(special: bool = True) -> st.SearchStrategy[float]:
    """Ordinary floats mixed with SPECIAL_FLOATS."""
    ordinary = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
    return st.one_of(ordinary, st.sampled_from(SPECIAL_FLOATS)) if special else ordinary


def _layouts(a: np.ndarray) -> st.SearchStrategy[np.ndarray]:
    """The same values in C order, Fortran order, as a non-contiguous view, or as another dtype."""
    options = [st.just(a), st.just(np.asfortranarray(a))]
    if a.ndim >= 1 and a.size:
        wide = np.repeat(a, 2, axis=-1)
        options.append(st.just(wide[..., ::2]))  # strided view, same values
    with np.errstate(over="ignore", invalid="ignore"):  # 1e200 as float32 is inf: a case of its own
        options.append(st.just(a.astype(np.float32)))
    if np.all(np.isfinite(a)) and np.all(np.abs(a) < 1e9):
        options.append(st.just(a.astype(np.int64)))
    return st.one_of(options)


def arrays(shape: tuple[int, ...] | None = None, max_side: int = 6, special: bool = True,
           max_dims: int = 3) -> st.SearchStrategy[np.ndarray]:
    """Float arrays of the given shape (or of any shape up to max_dims, 0-d and empty included),
    holding ordinary and special values, in any memory layout and dtype."""
    shapes = st.just(shape) if shape is not None else hnp.array_shapes(min_dims=0, max_dims=max_dims,
                                                                         min_side=0, max_side=max_side)
    base = shapes.flatmap(lambda s: hnp.arrays(np.float64, s, elements=floats(special)))
    return base.flatmap(_layouts)


def odd_objects() -> st.SearchStrategy[Any]:
    """Things that are not numeric arrays: None, strings, lists of strings, objects, huge ints."""
    return st.sampled_from([None, "abc", ["a", "b"], object(), 10**30, {"x": 1}, b"\xff"])


def state_of(obj: Any, *attributes: str) -> dict[str, Any]:
    """A deep copy of obj's attributes (arrays copied), to compare before and after a call."""
    out = {}
    for name in attributes:
        value = getattr(obj, name)
        value = value() if callable(value) else value
        out[name] = np.array(value, copy=True) if isinstance(value, np.ndarray) else _copy(value)
    return out


def _is_record(value: Any) -> bool:
    """A bound result struct of probslam._core (Landmarks, SubmapSlamSummary, ...): its fields are
    read-only properties, compared field by field."""
    t = type(value)
    return t.__module__ == "probslam._core" and t.__name__ in RECORD_TYPES


#: The result structs of probslam._core whose fields a snapshot compares.
RECORD_TYPES = {"Landmarks", "LandmarkDetails", "MapSharing", "FastSlamUpdateResult", "FastSlamAssociationResult",
                "SubmapConstraints", "SubmapSlamSummary", "GridFastSlamSummary", "TileSharing", "InsertStats3D"}


def record_fields(value: Any) -> dict[str, Any]:
    """A bound result struct's fields as a dict (arrays copied)."""
    return {n: _copy(getattr(value, n)) for n in dir(type(value))
            if not n.startswith("_") and isinstance(inspect.getattr_static(type(value), n), property)}


def _copy(value: Any) -> Any:
    if _is_record(value):
        return record_fields(value)
    if isinstance(value, (list, tuple)):
        return type(value)(_copy(v) for v in value)
    if isinstance(value, dict):
        return {k: _copy(v) for k, v in value.items()}
    return np.array(value, copy=True) if isinstance(value, np.ndarray) else value


def same_state(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """True when two state_of snapshots are equal (NaN equal to NaN, bit for bit otherwise)."""
    if a.keys() != b.keys():
        return False
    return all(_same(a[k], b[k]) for k in a)


def _same(x: Any, y: Any) -> bool:
    if _is_record(x) or _is_record(y):
        x, y = (record_fields(v) if _is_record(v) else v for v in (x, y))
    if isinstance(x, dict) and isinstance(y, dict):
        return x.keys() == y.keys() and all(_same(x[k], y[k]) for k in x)
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        x, y = np.asarray(x), np.asarray(y)
        return x.shape == y.shape and x.dtype == y.dtype and np.array_equal(x, y, equal_nan=x.dtype.kind in "fc")
    if isinstance(x, (list, tuple)) and isinstance(y, (list, tuple)):
        return len(x) == len(y) and all(_same(p, q) for p, q in zip(x, y))
    if isinstance(x, float) and isinstance(y, float):
        return (x == y) or (np.isnan(x) and np.isnan(y))
    return x == y


def all_finite(result: Any) -> bool:
    """True when every number in result (arrays, tuples, lists, floats, nested) is finite."""
    if result is None or isinstance(result, (bool, str, bytes)):
        return True
    if isinstance(result, (int, float, np.number)):
        return bool(np.isfinite(result))
    if isinstance(result, np.ndarray):
        return result.dtype.kind not in "fc" or bool(np.all(np.isfinite(result)))
    if isinstance(result, (list, tuple)):
        return all(all_finite(r) for r in result)
    if isinstance(result, dict):
        return all(all_finite(r) for r in result.values())
    if _is_record(result):
        return all_finite(record_fields(result))
    return True  # an object (a grid, a report): checked by its own snapshot


def check_call(call: Callable[[], Any], snapshot: Callable[[], dict[str, Any]] | None = None,
               finite: bool = True) -> tuple[bool, Any]:
    """Runs call under the policy. Returns (raised, result_or_exception). Fails the test when the
    call raises anything but a CLEAN_ERRORS exception, when it raised after changing the
    snapshot, or (finite=True) when it returned a non-finite number."""
    before = snapshot() if snapshot else None
    try:
        result = call()
    except CLEAN_ERRORS as error:
        if snapshot:
            assert same_state(before, snapshot()), f"state changed by a call that raised {error!r}"
        assert str(error), "an error without a message"
        return True, error
    if finite:
        assert all_finite(result), f"non-finite result {result!r}"
    return False, result


def run_threads(targets: Iterable[Callable[[], Any]]) -> list[BaseException]:
    """Runs each target on its own thread at once; returns the exceptions they raised."""
    errors: list[BaseException] = []
    barrier_targets = list(targets)
    barrier = threading.Barrier(len(barrier_targets))

    def wrap(f: Callable[[], Any]) -> Callable[[], None]:
        def run() -> None:
            barrier.wait()
            try:
                f()
            except BaseException as e:  # noqa: BLE001 - collected for the test to judge
                errors.append(e)
        return run

    threads = [threading.Thread(target=wrap(f)) for f in barrier_targets]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return errors
