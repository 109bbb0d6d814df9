"""Argument checks shared by the Python modules: a wrong type or shape raises TypeError or
ValueError naming the argument, before any work (and before an AttributeError or IndexError
deep inside could say less)."""

from __future__ import annotations

import dataclasses
from typing import Mapping, Optional, Tuple, Union

import numpy as np


def require_instance(value: object, types: Union[type, Tuple[type, ...]], name: str) -> None:
    """TypeError naming ``name`` unless ``value`` is one of ``types``."""
    if not isinstance(value, types):
        expected = " or ".join(t.__name__ for t in (types if isinstance(types, tuple) else (types,)))
        raise TypeError(f"{name}: expected {expected}, got {type(value).__name__}")


def options_over(cls: type, options: object, fields: Mapping, defaults: Mapping, name: str = "options"):
    """The options of a run taken as ``(..., options=None, **fields)`` over its own defaults (a
    dataset's noise, its sensor's field): ``options`` (None: ``cls()``) with each of ``defaults``
    where it still holds ``cls()``'s value, then ``fields`` set (a field named by keyword always
    wins: ``p_new=1e-2`` runs with that value even where it is ``cls()``'s). A ``cls`` is a bound
    options class (``replace`` validates); TypeError naming ``name`` for another type, the class's
    TypeError / ValueError naming the field's path for a bad field."""
    base = cls() if options is None else options
    require_instance(base, cls, name)
    stock = cls()
    own = {k: v for k, v in defaults.items() if k not in fields and getattr(base, k) == getattr(stock, k)}
    return base.replace(**own, **fields)


def differing_field(options: object, default: object) -> Optional[str]:
    """The first field of an options object (a bound options class's, a dataclass's) whose value
    is not ``default``'s (NaN equal to NaN); None when all are equal."""
    mine, theirs = _fields(options), _fields(default)
    return next((name for name, value in mine.items() if not _same(value, theirs[name])), None)


def _fields(options: object) -> dict:
    return dataclasses.asdict(options) if dataclasses.is_dataclass(options) else options.as_dict()


def _same(a: object, b: object) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and a != a and b != b)


def require_integer(value: object, name: str, lowest: Optional[int] = None, highest: Optional[int] = None) -> int:
    """``value`` as an int: a Python or numpy integer (not a bool, nor a float that int() would
    truncate), TypeError naming ``name`` otherwise; ValueError naming it and the range outside
    [lowest, highest] (None: no bound on that side)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if (lowest is not None and value < lowest) or (highest is not None and value > highest):
        if highest is None:
            raise ValueError(f"{name} must be >= {lowest}, got {value}")
        if lowest is None:
            raise ValueError(f"{name} must be <= {highest}, got {value}")
        raise ValueError(f"{name} must lie in [{lowest}, {highest}], got {value}")
    return int(value)


def require_fields(value: object, fields: Tuple[str, ...], name: str, what: str) -> None:
    """TypeError naming ``name`` unless ``value`` has every attribute in ``fields`` (for the
    functions that take any object with those fields, e.g. a LandmarkSlamResult)."""
    if not all(hasattr(value, f) for f in fields):
        raise TypeError(f"{name}: expected {what}, got {type(value).__name__}")


def real_array(value: object, name: str, shape: Optional[Tuple[Optional[int], ...]],
               finite: bool = True) -> np.ndarray:
    """``value`` as a float array of ``shape`` (None in it: any length; None for it: any shape),
    finite unless ``finite`` is False (then NaN and inf are the caller's to judge); TypeError for
    anything but real numbers, ValueError for a wrong shape or NaN / inf, both naming ``name``."""
    try:
        a = np.asarray(value)
    except ValueError as exc:  # ragged nested lists
        raise ValueError(f"{name}: not an array of numbers: {exc}") from None
    if a.dtype.kind not in "iuf":
        raise TypeError(f"{name}: expected real numbers, got dtype {a.dtype}")
    if shape is None:
        shape = (None,) * a.ndim
    want = "(" + ", ".join("N" if n is None else str(n) for n in shape) + ")"
    if a.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, a.shape)):
        raise ValueError(f"{name}: expected shape {want}, got {a.shape}")
    a = a.astype(float, copy=False)
    if finite and not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains NaN or inf (expected finite numbers)")
    return a


def positive_real(value: object, name: str) -> float:
    """``value`` as a float that is finite and > 0: TypeError naming ``name`` for anything but a
    real number (a bool included), ValueError naming it for NaN, inf, 0 or a negative value."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    try:
        number = float(value)
    except OverflowError:  # a Python int beyond a double's range
        number = float("inf")
    if not (np.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return number


def distinct_numbers(a: float, b: float, digits: int = 9) -> Tuple[str, str]:
    """``a`` and ``b`` as text with ``digits`` significant digits, or as many more (up to 17, a
    double's) as it takes to tell them apart: a message about two Unix times a fraction of a
    second apart must not print the same number twice."""
    for n in range(digits, 18):
        text_a, text_b = f"{a:.{n}g}", f"{b:.{n}g}"
        if text_a != text_b:
            break
    return text_a, text_b
