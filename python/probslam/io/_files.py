"""Checks shared by the Python-side readers: regular files only, and text read so that bytes
which are not UTF-8 reach the parser as visible escapes (then a ``ValueError`` naming the file
and line) rather than raising ``UnicodeDecodeError``."""

from __future__ import annotations

import bz2
import gzip
import io
import lzma
import math
import os
import stat
import warnings
import zlib
from dataclasses import dataclass, field
from typing import Callable, Iterator, List, Optional, Tuple

import numpy as np

#: The most bytes read from a compressed log. The largest shipped log (fr079.clf.bz2) expands
#: to 10 MB; a few megabytes of crafted .gz/.bz2 data could otherwise expand to gigabytes.
MAX_DECOMPRESSED_BYTES = 512 << 20


def file_path(value: object, arg: str = "path", expected: str = "a file path (str or os.PathLike)") -> str:
    """The str of a file path given as str, bytes or os.PathLike; anything else a TypeError
    naming the argument and what it takes (os.fspath's own message names neither)."""
    if not isinstance(value, (str, bytes, os.PathLike)):
        raise TypeError(f"{arg}: expected {expected}, got {type(value).__name__}")
    return os.fsdecode(value)


def path_kind(path: str) -> Tuple[str, str]:
    """What is at ``path``, and why it cannot be read: ("missing", ""), ("unreadable", the
    system's reason), ("folder", ""), ("special", "") for a device such as /dev/zero that never
    ends or a fifo that blocks on open, ("empty", "") for a regular file of no bytes, else
    ("file", "")."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "missing", ""
    except OSError as exc:
        return "unreadable", exc.strerror or type(exc).__name__
    if stat.S_ISDIR(st.st_mode):
        return "folder", ""
    if not stat.S_ISREG(st.st_mode):
        return "special", ""
    return ("empty" if st.st_size == 0 else "file"), ""


def require_regular_file(path: str, arg: str = "path") -> None:
    """FileNotFoundError for a missing path; ValueError for anything but a regular file
    (``path_kind``: a folder, a device, a fifo, or a path that cannot be read)."""
    kind, why = path_kind(path)
    if kind == "missing":
        raise FileNotFoundError(f"{arg}: no such file: {path!r}")
    if kind == "unreadable":
        raise ValueError(f"{arg}: cannot read {path!r}: {why}")
    if kind in ("folder", "special"):
        raise ValueError(f"{arg}: {path!r} is not a regular file")


#: The compressions the readers open, by their magic numbers (a file's first bytes) and their
#: suffixes: a gzipped log named .log is read as one named .log.gz.
_COMPRESSIONS = {"gzip": (gzip.open, ".gz"), "bzip2": (bz2.open, ".bz2"), "xz": (lzma.open, ".xz")}


def compression(path: str) -> Optional[str]:
    """"gzip", "bzip2" or "xz" when the file at ``path`` starts with that compression's magic
    number, else the one its suffix (.gz, .bz2, .xz) names, else None (plain text)."""
    with open(path, "rb") as f:
        head = f.read(10)
    if head.startswith(b"\x1f\x8b"):
        return "gzip"
    # "BZh", the block size 1-9, then a block's or the end of stream's magic.
    if head[:3] == b"BZh" and head[3:4] in b"123456789" and head[4:10] in (b"1AY&SY", b"\x17rE8P\x90"):
        return "bzip2"
    if head.startswith(b"\xfd7zXZ\x00"):
        return "xz"
    return next((name for name, (_, suffix) in _COMPRESSIONS.items() if path.endswith(suffix)), None)


def text_lines(path: str) -> Iterator[Tuple[int, str]]:
    """(line number, text) of a UTF-8 text file, plain or compressed (gzip, bzip2, xz; see
    ``read_compressed``); invalid bytes appear as ``\\xNN`` escapes."""
    if compression(path):
        text = read_compressed(path).decode("utf-8", errors="backslashreplace")
        yield from enumerate(io.StringIO(text, newline=None), 1)  # line ends as open() reads them
        return
    with open(path, encoding="utf-8", errors="backslashreplace") as f:
        yield from enumerate(f, 1)


def read_compressed(path: str) -> bytes:
    """The decompressed bytes of a gzip, bzip2 or xz file (told by ``compression``), at most
    MAX_DECOMPRESSED_BYTES; a corrupt or truncated stream raises ValueError naming the file."""
    opener = _COMPRESSIONS[compression(path) or "gzip"][0]
    try:
        with opener(path, "rb") as f:
            data = f.read(MAX_DECOMPRESSED_BYTES + 1)
    except (OSError, EOFError, zlib.error, lzma.LZMAError) as exc:
        raise ValueError(f"{path}: corrupt compressed data: {exc}") from None
    if len(data) > MAX_DECOMPRESSED_BYTES:
        raise ValueError(f"{path}: decompresses to more than {MAX_DECOMPRESSED_BYTES} bytes "
                         "(MAX_DECOMPRESSED_BYTES)")
    return data


#: How many line numbers of skipped rows a reader of numeric text rows keeps (and its warning
#: names); every skipped row is counted.
MAX_REPORTED_LINES = 20


@dataclass
class NumericRows:
    """What ``numeric_rows`` read: ``table`` (n, k) the readable rows, ``lines`` (n,) their line
    numbers, ``ordinals`` (n,) their places among the file's rows (comments and blank lines not
    counted, skipped rows counted); ``skipped`` the unreadable rows, ``skipped_lines`` the line numbers of the first
    ``MAX_REPORTED_LINES`` of them and ``first_reason`` why the first was skipped."""

    table: np.ndarray
    lines: np.ndarray
    ordinals: np.ndarray
    skipped: int = 0
    skipped_lines: List[int] = field(default_factory=list)
    first_reason: str = ""

    def warn(self, path: str, what: str) -> None:
        """One warning naming the file, the count and the first skipped lines (none if nothing
        was skipped)."""
        if self.skipped:
            more = ", ..." if self.skipped > len(self.skipped_lines) else ""
            warnings.warn(f"{path}: skipped {self.skipped} unreadable {what} rows (lines "
                          f"{', '.join(map(str, self.skipped_lines))}{more}; first: {self.first_reason})",
                          stacklevel=3)


def numeric_rows(path: str, field_counts: Tuple[int, ...], what: str,
                 check: Optional[Callable[[List[float]], str]] = None) -> NumericRows:
    """The rows of whitespace-separated finite numbers of a text file (plain, ``.gz`` or
    ``.bz2``; ``#`` starts a comment, blank lines are ignored), as a real file is read: a row that
    cannot be used is skipped and counted, not fatal.

    The first row of numbers whose field count is one of ``field_counts`` fixes the count; later
    rows with another count, with words, 'nan', 'inf' or '1_0' (which ``float`` takes), or for
    which ``check(values)`` returns a reason, are skipped. ``ValueError`` naming the file when no
    row is readable (``"no valid {what} rows"``)."""
    rows: List[List[float]] = []
    numbers: List[int] = []
    ordinals: List[int] = []
    result = NumericRows(np.empty((0, 0)), np.empty(0, np.int64), np.empty(0, np.int64))
    width = 0
    for number, line in text_lines(path):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        reason = ""
        if len(fields) != width and (width or len(fields) not in field_counts):
            counts = " or ".join(map(str, (width,) if width else field_counts))
            reason = f"expected {counts} fields, got {len(fields)}"
        else:
            try:
                values = [float(x) for x in fields]
            except ValueError:
                values, reason = [], "not numbers"
            if values and (not all(map(math.isfinite, values)) or any("_" in x for x in fields)):
                reason = "not finite numbers"
            reason = reason or (check(values) if check else "")
        if not reason:
            width = len(fields)
            ordinals.append(len(rows) + result.skipped)
            rows.append(values)
            numbers.append(number)
            continue
        result.skipped += 1
        if len(result.skipped_lines) < MAX_REPORTED_LINES:
            result.skipped_lines.append(number)
        result.first_reason = result.first_reason or reason
    if not rows:
        detail = (f"first bad line {result.skipped_lines[0]}: {result.first_reason}" if result.skipped
                  else "empty or only comments")
        raise ValueError(f"{path}: no valid {what} rows ({detail})")
    result.table = np.array(rows, dtype=float)
    result.lines = np.array(numbers, dtype=np.int64)
    result.ordinals = np.array(ordinals, dtype=np.int64)
    return result


def numeric_table(path: str, columns: int, what: str) -> NumericRows:
    """``numeric_rows(path, (columns,), what)`` at numpy's speed: a file whose every line is a row
    of ``columns`` finite numbers (no comment, no blank line) is parsed by ``np.loadtxt``, nearly
    four times faster than the row loop on the original Victoria Park run's files
    (docs/victoria_park.md); any other file goes through ``numeric_rows``, whose result (rows
    kept, rows skipped and why) is the policy."""
    text = (io.StringIO(read_compressed(path).decode("utf-8", errors="backslashreplace"), newline=None).read()
            if path.endswith((".gz", ".bz2")) else _plain_text(path))
    lines = text.count("\n") + (0 if text.endswith("\n") else 1)
    table = None
    if "#" not in text and text.strip():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # loadtxt warns of an empty input; numeric_rows says it
            try:
                table = np.loadtxt(io.StringIO(text), dtype=float, ndmin=2)
            except ValueError:  # words, another field count: numeric_rows finds and counts them
                pass
    if table is None or table.shape != (lines, columns) or not np.all(np.isfinite(table)):
        return numeric_rows(path, (columns,), what)
    rows = np.arange(len(table), dtype=np.int64)
    return NumericRows(table, rows + 1, rows)


def _plain_text(path: str) -> str:
    """A plain text file as ``text_lines`` reads it (line ends as open() reads them)."""
    with open(path, encoding="utf-8", errors="backslashreplace") as f:
        return f.read()
