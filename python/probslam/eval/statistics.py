"""The statistics of a set of errors as evo prints them, and their table."""

from __future__ import annotations

from typing import Dict

import numpy as np

from .._args import real_array


#: The statistics of errors that evo prints, in its order (alphabetical).
STATISTICS = ("max", "mean", "median", "min", "rmse", "sse", "std")


def error_statistics(errors: object) -> Dict[str, float]:
    """evo's statistics of errors (K,) >= 0, K >= 1: max, mean, median, min, rmse (root mean
    square), sse (sum of squares), std (population, ddof=0)."""
    e = real_array(errors, "errors", (None,))
    if e.size == 0:
        raise ValueError("errors: empty (no statistic of nothing)")
    squares = e ** 2
    return dict(max=float(np.max(e)), mean=float(np.mean(e)), median=float(np.median(e)), min=float(np.min(e)),
                rmse=float(np.sqrt(np.mean(squares))), sse=float(np.sum(squares)), std=float(np.std(e)))


def statistics_table(title: str, statistics: Dict[str, float]) -> str:
    """``title``, a blank line and one ``name<TAB>value`` row per statistic, laid out as evo's
    ``Result.pretty_str`` (names right-aligned in 10 characters, six decimals)."""
    return title + "\n\n" + "".join(f"{name:>10}\t{value:.6f}\n" for name, value in statistics.items())


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root mean square of the Euclidean distances between rows of a and b (N, 2 or 3)."""
    return float(np.sqrt(np.mean(np.sum((np.asarray(a) - np.asarray(b)) ** 2, axis=1))))
