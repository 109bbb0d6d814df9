"""Checks shared by the Python-side readers: regular files only, and text read so that bytes
which are not UTF-8 reach the parser as visible escapes (then a ``ValueError`` naming the file
and line) rather than raising ``UnicodeDecodeError``."""

from __future__ import annotations

import bz2
import gzip
import io
import os
import stat
import zlib
from typing import Iterator, Tuple

#: The most bytes read from a compressed log. The largest shipped log (fr079.clf.bz2) expands
#: to 10 MB; a few megabytes of crafted .gz/.bz2 data could otherwise expand to gigabytes.
MAX_DECOMPRESSED_BYTES = 512 << 20


def file_path(value: object, arg: str = "path", expected: str = "a file path (str or os.PathLike)") -> str:
    """The str of a file path given as str, bytes or os.PathLike; anything else a TypeError
    naming the argument and what it takes (os.fspath's own message names neither)."""
    if not isinstance(value, (str, bytes, os.PathLike)):
        raise TypeError(f"{arg}: expected {expected}, got {type(value).__name__}")
    return os.fsdecode(value)


def require_regular_file(path: str, arg: str = "path") -> None:
    """FileNotFoundError for a missing path; ValueError for anything but a regular file (a
    directory, a device such as /dev/zero that never ends, a fifo that blocks on open)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise FileNotFoundError(f"{arg}: no such file: {path!r}") from None
    except OSError as exc:
        raise ValueError(f"{arg}: cannot read {path!r}: {exc.strerror}") from None
    if not stat.S_ISREG(mode):
        raise ValueError(f"{arg}: {path!r} is not a regular file")


def text_lines(path: str) -> Iterator[Tuple[int, str]]:
    """(line number, text) of a UTF-8 text file, plain or ``.gz`` / ``.bz2`` (see
    ``read_compressed``); invalid bytes appear as ``\\xNN`` escapes."""
    if path.endswith((".gz", ".bz2")):
        text = read_compressed(path).decode("utf-8", errors="backslashreplace")
        yield from enumerate(io.StringIO(text, newline=None), 1)  # line ends as open() reads them
        return
    with open(path, encoding="utf-8", errors="backslashreplace") as f:
        yield from enumerate(f, 1)


def read_compressed(path: str) -> bytes:
    """The decompressed bytes of a .gz or .bz2 file, at most MAX_DECOMPRESSED_BYTES; a corrupt or
    truncated stream raises ValueError naming the file."""
    opener = gzip.open if path.endswith(".gz") else bz2.open
    try:
        with opener(path, "rb") as f:
            data = f.read(MAX_DECOMPRESSED_BYTES + 1)
    except (OSError, EOFError, zlib.error) as exc:
        raise ValueError(f"{path}: corrupt compressed data: {exc}") from None
    if len(data) > MAX_DECOMPRESSED_BYTES:
        raise ValueError(f"{path}: decompresses to more than {MAX_DECOMPRESSED_BYTES} bytes "
                         "(MAX_DECOMPRESSED_BYTES)")
    return data
