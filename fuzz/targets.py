"""Fuzz targets: one per parser entry point. Each writes the input bytes to file(s) in a
private temporary directory (the readers take paths) and calls the reader.

A target's documented outcomes are a result or ``ValueError`` (with ``FileNotFoundError``
where the reader documents it); ``UnicodeError`` is a ``ValueError`` subclass but is a finding
(the readers must name the file and line instead). Anything else escaping a target is a
finding: atheris reports it as a crash and saves the input.

``relations`` names its file ``.gz`` / ``.bz2`` when the input starts with that format's magic
bytes; ``learned_model`` feeds ``LearnedInverseModel.load`` (a .npz archive).

Multi-file formats take one input split at SEPARATOR lines: map_server is YAML + PGM, MRCLAM is
Barcodes + Landmark_Groundtruth + Odometry + Measurement (+ Groundtruth).
"""

from __future__ import annotations

import os
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
        from probslam import io
        io.read_pose_graph_3d(ws.write(name, data), format=fmt)
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


def state_file(ws: Workspace, data: bytes) -> None:
    import probslam as ps
    ps.OccupancyGrid2D.load(ws.write("map.psl", data))


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
