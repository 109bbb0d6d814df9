"""Fuzz targets: one per parser entry point. Each writes the input bytes to file(s) in a
private temporary directory (the readers take paths) and calls the reader.

A target's documented outcomes are a result or ``ValueError`` (with ``FileNotFoundError``
where the reader documents it); ``UnicodeError`` is a ``ValueError`` subclass but is a finding
(the readers must name the file and line instead). Anything else escaping a target is a
finding: atheris reports it as a crash and saves the input.

``state_file`` reads every class's state file; its inputs are a class byte and a payload that
the target frames with a valid checksum (or, from byte RAW_STATE on, a whole file).

``relations`` names its file ``.gz`` / ``.bz2`` when the input starts with that format's magic
bytes; ``learned_model`` feeds ``LearnedInverseModel.load`` (a .npz archive).

Multi-file formats take one input split at SEPARATOR lines: map_server is YAML + PGM, MRCLAM is
Barcodes + Landmark_Groundtruth + Odometry + Measurement (+ Groundtruth), the original Victoria
Park run inputs + measurements + GPS (+ a track of positions).
"""

from __future__ import annotations

import os
import struct
import tempfile
import warnings
from typing import Callable, Dict, Tuple

SEPARATOR = b"\n=====\n"
EXPECTED = (ValueError, FileNotFoundError)


class Workspace:
    """A private directory whose files are rewritten for every input."""

    def __init__(self, directory=None) -> None:
        self.dir = str(directory) if directory is not None else tempfile.mkdtemp(prefix="probslam-fuzz-")

    def write(self, name: str, data: bytes) -> str:
        path = os.path.join(self.dir, name)
        with open(path, "wb") as f:
            f.write(data)
        return path

    def clear(self) -> None:
        for name in os.listdir(self.dir):
            os.unlink(os.path.join(self.dir, name))


def _parts(data: bytes, n: int):
    parts = data.split(SEPARATOR, n - 1)
    return parts + [b""] * (n - len(parts))


def carmen(ws: Workspace, data: bytes) -> None:
    from probslam import io
    io.read_carmen_log(ws.write("log.log", data))


def carmen_gz(ws: Workspace, data: bytes) -> None:
    from probslam import io
    io.read_carmen_log(ws.write("log.log.gz", data))


def _pose_graph(name: str, fmt: str):
    def target(ws: Workspace, data: bytes) -> None:
        from probslam import graph
        graph.read_pose_graph(ws.write(name, data), format=fmt)
    return target


def _pose_graph_3d(name: str, fmt: str):
    def target(ws: Workspace, data: bytes) -> None:
        from probslam import graph
        graph.read_pose_graph_3d(ws.write(name, data), format=fmt)
    return target


def _pose_graph_3d_graph(name: str, fmt: str):
    """The 3-D reader straight into a PoseGraph3D (points, priors, FIX, sensor offsets applied)
    under both row policies, and the graph written back and read again: what it reads it must
    be able to write."""
    def target(ws: Workspace, data: bytes) -> None:
        from probslam import graph
        path = ws.write(name, data)
        for rows in ("strict", "skip"):
            try:
                g = graph.read_pose_graph_3d_with_report(path, format=fmt, rows=rows).graph
            except EXPECTED:
                continue
            back = ws.write("back.g2o", b"")
            graph.write_g2o_3d(g, back)
            again = graph.read_pose_graph_3d(back)
            if (again.num_vertices, again.num_pose_edges, again.num_point_edges) != (
                    g.num_vertices, g.num_pose_edges, g.num_point_edges):
                raise AssertionError("a graph read did not read back the same after writing")
    return target


def _toro_equivalences(ws: Workspace, data: bytes) -> None:
    """TORO under both EQUIV policies and the skip row policy (the merge's union-find)."""
    from probslam import graph
    path = ws.write("graph.graph", data)
    for equivalences in ("merge", "ignore"):
        try:
            graph.read_pose_graph_with_report(path, format="toro", rows="skip", equivalences=equivalences)
        except EXPECTED:
            pass


def ros_map(ws: Workspace, data: bytes) -> None:
    from probslam import io
    yaml, pgm = _parts(data, 2)
    ws.write("map.pgm", pgm)
    io.load_ros_map(ws.write("map.yaml", yaml))


#: The classes with a state file (docs/file_format.md), by their tag; the C++ class of each.
STATE_CLASSES = ("OccupancyGrid2D", "OccupancyGrid3D", "PoseGraph2D", "PoseGraph3D", "SubmapSlam2D", "GridFastSlam",
                 "FastSlam", "EkfSlam", "MultiHypothesisEkfSlam", "MonteCarloLocalization", "IncrementalScanMatcher")
_STATE_BINDINGS = {"EkfSlam": "_EkfSlam", "MultiHypothesisEkfSlam": "_MultiHypothesisEkfSlam"}
STATE_MAGIC = b"PSLSTATE"
STATE_VERSION = 7  # kStateFormatVersion (include/probslam/core/state_file.hpp)
#: A state_file input's first byte at or above this: the rest is a whole file, header included.
RAW_STATE = 0x80


def fnv1a(data: bytes) -> int:
    """The state file's checksum (FNV-1a, 64 bits) of data."""
    h = 0xcbf29ce484222325
    for b in data:
        h = ((h ^ b) * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return h


def frame_state(tag: str, payload: bytes) -> bytes:
    """A whole state file of class ``tag`` around payload, its checksum recomputed: an edited
    payload passes the integrity check and reaches the class's reader."""
    name = tag.encode()
    return (STATE_MAGIC + struct.pack("<IQ", STATE_VERSION, len(name)) + name +
            struct.pack("<QQ", len(payload), fnv1a(payload)) + payload)


def state_payload(framed: bytes) -> Tuple[str, bytes]:
    """(tag, payload) of a state file as frame_state writes it."""
    (tag_size,) = struct.unpack_from("<Q", framed, 12)
    start = 20 + tag_size + 16
    return framed[20:20 + tag_size].decode(), framed[start:]


def state_class(tag: str):
    """The C++ binding whose load reads a state of class ``tag``."""
    from probslam import _core
    return getattr(_core, _STATE_BINDINGS.get(tag, tag))


def state_file(ws: Workspace, data: bytes) -> None:
    """Every class's state file: the first byte picks the class (modulo their number); below
    RAW_STATE the rest is a payload framed with a valid checksum (so that mutations reach the
    field readers rather than the integrity check), from RAW_STATE on it is the whole file
    (mutations of the header)."""
    if not data:
        return
    tag = STATE_CLASSES[data[0] % len(STATE_CLASSES)]
    body = data[1:] if data[0] >= RAW_STATE else frame_state(tag, data[1:])
    state_class(tag).load(ws.write("state.psl", body))


def octomap_bt(ws: Workspace, data: bytes) -> None:
    import probslam as ps
    ps.OccupancyGrid3D.read_bt(ws.write("tree.bt", data))


MRCLAM_FILES = ("Barcodes.dat", "Landmark_Groundtruth.dat", "Robot1_Odometry.dat", "Robot1_Measurement.dat",
                "Robot1_Groundtruth.dat")


def mrclam(ws: Workspace, data: bytes) -> None:
    from probslam import io
    parts = data.split(SEPARATOR, len(MRCLAM_FILES) - 1)
    ws.clear()
    for name, part in zip(MRCLAM_FILES, parts):
        ws.write(name, part)
    io.read_mrclam(ws.dir, robot=1)


def victoria_park(ws: Workspace, data: bytes) -> None:
    """The C++ iSAM reader under rows="skip" (read_victoria_park has no parser of its own since
    issue 34), and the arrays built from the graph."""
    from probslam import io
    io.read_victoria_park(ws.write("victoriaPark.txt", data))


VICTORIA_PARK_ACFR_FILES = ("inputs.dat", "measurements.dat", "gps.dat")


def victoria_park_acfr(ws: Workspace, data: bytes) -> None:
    """The original Victoria Park run's three files (``io.read_victoria_park_acfr``); a fourth
    part of the input, if any, is read as a ``t x y`` track (``io.read_positions``)."""
    from probslam import io
    parts = data.split(SEPARATOR, len(VICTORIA_PARK_ACFR_FILES))
    ws.clear()
    if len(parts) > len(VICTORIA_PARK_ACFR_FILES):
        try:
            io.read_positions(ws.write("track.txt", parts[-1]))
        except EXPECTED:
            pass
    for name, part in zip(VICTORIA_PARK_ACFR_FILES, parts):
        ws.write(name, part)
    io.read_victoria_park_acfr(ws.dir)


def relations(ws: Workspace, data: bytes) -> None:
    from probslam import eval as ev
    # The reader picks plain, .gz or .bz2 by the name: name the file after the input's magic bytes
    # so that mutations of a compressed seed reach the decompressors.
    suffix = ".gz" if data.startswith(b"\x1f\x8b") else ".bz2" if data.startswith(b"BZh") else ""
    ws.clear()
    ev.read_relations(ws.write("log.relations" + suffix, data))


def trajectory(ws: Workspace, data: bytes) -> None:
    """A trajectory file in any of its formats (the field count decides); KITTI rows read their
    times from a times file that the input's second part fills."""
    from probslam import io
    poses, times = _parts(data, 2)
    ws.clear()
    ws.write("traj_times.txt", times)
    io.read_trajectory(ws.write("traj.txt", poses))


def learned_model(ws: Workspace, data: bytes) -> None:
    import probslam as ps
    ps.LearnedInverseModel.load(ws.write("model.npz", data))


TARGETS: Dict[str, Callable[[Workspace, bytes], None]] = {
    "carmen": carmen,
    "carmen_gz": carmen_gz,
    "g2o": _pose_graph("graph.g2o", "g2o"),
    "toro": _pose_graph("graph.graph", "toro"),
    "isam": _pose_graph("graph.txt", "isam"),
    "g2o_3d": _pose_graph_3d("graph3d.g2o", "g2o"),
    "isam_3d": _pose_graph_3d("graph3d.txt", "isam"),
    "toro_3d": _pose_graph_3d("graph3d.graph", "toro"),
    "g2o_3d_graph": _pose_graph_3d_graph("graph3d.g2o", "g2o"),
    "toro_equiv": _toro_equivalences,
    "ros_map": ros_map,
    "state_file": state_file,
    "octomap_bt": octomap_bt,
    "mrclam": mrclam,
    "victoria_park": victoria_park,
    "victoria_park_acfr": victoria_park_acfr,
    "relations": relations,
    "learned_model": learned_model,
    "trajectory": trajectory,
}


def check(target: Callable[[Workspace, bytes], None], ws: Workspace, data: bytes) -> None:
    """Runs one input; returns quietly on a documented outcome, raises on a finding."""
    try:
        with warnings.catch_warnings():  # readers warn about the bad lines they skip
            warnings.simplefilter("ignore")
            target(ws, data)
    except UnicodeError:
        raise
    except EXPECTED:
        pass


def describe() -> Tuple[str, ...]:
    return tuple(TARGETS)
