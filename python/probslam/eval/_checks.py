"""What every metric of ``probslam.eval`` checks of its arithmetic: a result computed from
finite input may still overflow a double near the largest one, and the policy is finite or
raise (a ValueError naming what overflowed)."""

from __future__ import annotations

import os
from typing import Union

import numpy as np

from .._core import wrap_angle

PathLike = Union[str, "os.PathLike[str]"]


def _require_finite(result: np.ndarray, what: str) -> None:
    """ValueError unless every number of a result is finite (inputs near the largest double
    can overflow in the arithmetic; the policy is finite or raise)."""
    if not np.all(np.isfinite(result)):
        raise ValueError(f"{what} overflows a double (inputs too large)")


def _wrap(angle: np.ndarray, what: str) -> np.ndarray:
    """``probslam.wrap_angle`` of angles the arithmetic here computed, which may have overflowed
    for inputs near the largest double: then a ValueError naming ``what`` (the bound function
    would name its own argument, ``angle``)."""
    _require_finite(angle, what)
    return wrap_angle(angle)
