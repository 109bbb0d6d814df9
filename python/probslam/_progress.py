"""The progress bars of long runs (tqdm), one policy for every driver: ``progress=None`` shows a
bar only when stderr is a terminal (tqdm's ``disable=None``), True always, False never."""

from __future__ import annotations

from typing import Iterator, Optional

from tqdm import tqdm


def progress_bar(total: int, desc: str, unit: str, progress: Optional[bool]) -> tqdm:
    """A tqdm bar of ``total`` steps (use it in a ``with`` block, or close it)."""
    if progress is not None and not isinstance(progress, bool):
        raise TypeError(f"progress must be None, True or False, got {type(progress).__name__}")
    return tqdm(total=total, desc=desc, unit=unit, disable=None if progress is None else not progress)


def progress_range(n: int, desc: str, unit: str, progress: Optional[bool]) -> Iterator[int]:
    """``range(n)``, a bar advancing with it; the bar closes when the loop ends or is left."""
    with progress_bar(n, desc, unit, progress) as bar:
        for k in range(n):
            yield k
            bar.update(1)
