"""The files the pipelines read, checked before a run and read with errors that name them: an
``InputError`` (a ValueError) says the file, what is wrong with it and what was expected
("intel.log: empty file; expected a CARMEN laser log ..."), so that a caller only prints it."""

from __future__ import annotations

import contextlib
import os
import re
from typing import Iterable, Iterator, Mapping, Optional, Tuple

from .. import io
from ..io._files import path_kind
from ..io.laser_log import read_carmen_scans

#: What each kind of input file must be, for the error messages.
CARMEN_LOG = "a CARMEN laser log (.log/.clf, optionally .gz/.bz2/.xz)"
ROS_BAG = "a ROS bag (ROS 1 .bag, a ROS 2 bag folder, or its .db3 / .mcap)"
LANDMARK_DATASET = ("a UTIAS MRCLAM folder (Barcodes.dat, Landmark_Groundtruth.dat, RobotN_Odometry.dat, "
                    "RobotN_Measurement.dat) or a Victoria Park file in iSAM/GTSAM text format")
ANY_POSE_GRAPH = "a 2-D or 3-D pose graph (g2o, TORO or iSAM text)"
MAP_FILE = "a map_server map (YAML with its image)"
TRAJECTORY_FILE = "a trajectory: TUM (t x y z qx qy qz qw), KITTI (12 numbers a row) or 't x y theta' rows"
REFERENCE_FILES = {"trajectory": TRAJECTORY_FILE, "carmen": CARMEN_LOG,
                   "relations": "a Freiburg relations file (t1 t2 x y z roll pitch yaw rows)",
                   "positions": "positions with times (t x y rows, e.g. a GPS track)"}
#: read_rosbag's parameters that ``read_log`` passes on.
BAG_OPTIONS = ("scan_topic", "odom_topic", "pose_topic", "laser_offset")
#: The errors of a reader that say the file is not what was expected.
READ_ERRORS = (ValueError, OSError, EOFError, UnicodeError, IndexError)


class InputError(ValueError):
    """A file refused: the message names it and what was expected."""


def one_line(exc: BaseException) -> str:
    """An error's message on one line (its type's name when it has none)."""
    text = str(exc) or type(exc).__name__
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def name_pattern(names: Iterable[str]) -> "re.Pattern[str]":
    """A parameter's name in a message (not part of a longer name, a flag or a file name)."""
    return re.compile(r"(?<![-\w.])(" + "|".join(sorted(map(re.escape, names), key=len, reverse=True)) + r")\b(?![.])")


def renamed(text: str, names: Mapping[str, str], given: object = None) -> Tuple[str, bool]:
    """A message about parameters told in the caller's words, and whether it named one: its subject
    (a leading name of ``names``) as ``names`` calls it, with the value ``given`` for it unless the
    message says it ("min_particles must ..." -> "--min-particles 0: must ..."), the other names
    with an underscore (a word of prose is not a parameter) as theirs."""
    if not names:
        return text, False
    pattern = name_pattern(names)
    subject = pattern.match(text)
    rest = text[subject.end():] if subject else text
    mentioned = {m.group(1) for m in pattern.finditer(rest) if "_" in m.group(1)}
    rest = pattern.sub(lambda m: names[m.group(1)] if m.group(1) in mentioned else m.group(1), rest)
    if not subject:
        return rest, bool(mentioned)
    name, colon = names[subject.group(1)], ":" if rest.startswith(":") else ""
    rest = rest.lstrip(": ")
    if isinstance(given, (list, tuple)):
        given = " ".join(map(str, given))
    if (given is None or isinstance(given, bool) or rest.startswith((f"{given} ", f"{given}:"))
            or f"got {given}" in rest):
        return f"{name}{colon} {rest}", True  # no value to add, or the message says it
    return f"{name} {given}: {rest}", True


def check_input(path: str, expected: str, folder: bool = False) -> None:
    """InputError naming ``path`` when it is missing, empty, or not a regular file (or a ``folder``)."""
    kind, why = path_kind(path)
    problem = {"missing": "no such file", "unreadable": f"cannot read it ({why})",
               "folder": None if folder else "is a directory", "special": "not a regular file",
               "empty": "empty file"}.get(kind)
    if problem:
        raise InputError(f"{path}: {problem}; expected {expected}")


@contextlib.contextmanager
def reading(path: str, expected: str, arguments: Iterable[str] = (), folder: bool = False,
            files: Optional[Mapping[str, str]] = None) -> Iterator[None]:
    """``path`` checked (``check_input``), then a reader's error as an InputError naming the file
    and what was ``expected``. An error about one of the parameters ``arguments`` (``renamed``)
    is not the file's: raised as it is, for the caller to tell as its argument; one about a
    parameter of ``files`` (parameter -> what it was read from) is told so, naming ``path``."""
    check_input(path, expected, folder)
    try:
        yield
    except InputError:
        raise
    except READ_ERRORS as exc:
        message = one_line(exc)
        text, of_file = renamed(message, files or {})
        if of_file:
            raise ValueError(text if path in text else f"{path}: {text}") from None
        if renamed(message, {name: name for name in arguments})[1]:
            raise
        raise InputError(f"{message if path in message else f'{path}: {message}'}; expected {expected}") from None


def read_log(path: str, **bag):
    """The CARMEN log (``io.read_carmen_scans``) or ROS bag (``io.read_rosbag`` with ``bag``, of
    BAG_OPTIONS) at ``path``, its errors naming the file (``reading``)."""
    path = os.fspath(path)
    if io.rosbag.is_bag(path):
        with reading(path, ROS_BAG, BAG_OPTIONS, folder=True):
            return io.read_rosbag(path, **bag)
    if bag:
        raise ValueError(f"{next(iter(bag))} applies to ROS bags; {path} is read as {CARMEN_LOG}")
    with reading(path, CARMEN_LOG):
        return read_carmen_scans(path)


__all__ = ["ANY_POSE_GRAPH", "BAG_OPTIONS", "CARMEN_LOG", "InputError", "LANDMARK_DATASET", "MAP_FILE", "ROS_BAG",
           "REFERENCE_FILES", "TRAJECTORY_FILE", "check_input", "name_pattern", "one_line", "reading", "read_log",
           "renamed"]
