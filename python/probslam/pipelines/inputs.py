"""The files the pipelines read, checked before a run and read with errors that name them: an
``InputError`` (a ValueError) says the file, what is wrong with it and what was expected
("intel.log: empty file; expected a CARMEN laser log ..."), so that a caller only prints it."""

from __future__ import annotations

import contextlib
import os
import re
import stat
from typing import Iterator, Sequence

from .. import io
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


def name_pattern(names: Sequence[str]) -> "re.Pattern[str]":
    """A parameter's name in a message (not part of a longer name, a flag or a file name)."""
    return re.compile(r"(?<![-\w.])(" + "|".join(sorted(map(re.escape, names), key=len, reverse=True)) + r")\b(?![.])")


def names_argument(text: str, names: Sequence[str]) -> bool:
    """Whether a message is about one of the parameters ``names``: it starts with one, or names one
    with an underscore (a word of prose is not a parameter)."""
    if not names:
        return False
    pattern = name_pattern(names)
    return bool(pattern.match(text)) or any("_" in m.group(1) for m in pattern.finditer(text))


def check_input(path: str, expected: str, folder: bool = False) -> None:
    """InputError naming ``path`` when it is missing, empty, or not a regular file (or a ``folder``)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise InputError(f"{path}: no such file; expected {expected}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read it ({exc.strerror}); expected {expected}") from None
    if stat.S_ISDIR(mode):
        if not folder:
            raise InputError(f"{path}: is a directory; expected {expected}")
    elif not stat.S_ISREG(mode):
        raise InputError(f"{path}: not a regular file; expected {expected}")
    elif os.path.getsize(path) == 0:
        raise InputError(f"{path}: empty file; expected {expected}")


@contextlib.contextmanager
def reading(path: str, expected: str, arguments: Sequence[str] = (), folder: bool = False) -> Iterator[None]:
    """``path`` checked (``check_input``), then a reader's error as an InputError naming the file
    and what was ``expected``. An error about one of the parameters ``arguments``
    (``names_argument``) is not the file's: raised as it is, for the caller to tell as its argument."""
    check_input(path, expected, folder)
    try:
        yield
    except InputError:
        raise
    except READ_ERRORS as exc:
        message = one_line(exc)
        if names_argument(message, arguments):
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
           "REFERENCE_FILES", "TRAJECTORY_FILE", "check_input", "name_pattern", "names_argument", "one_line", "reading",
           "read_log"]
