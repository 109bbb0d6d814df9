"""2-D pose/landmark graphs and 3-D pose graphs (``PoseGraph3D``): reading, initialising,
optimising (Gauss-Newton / Levenberg-Marquardt on CHOLMOD, one optimiser for both), marginal
covariances, writing. The math is in C++; this module only names things
and drives the EKF for the EKF initialisation.

Reliability (docs/reliability.md): every call on a PoseGraph2D takes the graph's lock, so
threads may share a graph; mutations and optimisations are all or nothing (a call that raises
leaves the graph as it was); results are finite or the call raises. A part of the graph not
connected to a fixed vertex (or to the first pose, held when none is fixed) is refused by name
before any number is computed; numerical singularity is CHOLMOD's own positive-definiteness
report plus a per-variable pivot test, not a cut on the condition number, so information from
1e-12 to 1e12 in one graph is fine. iSAM files number landmarks apart from poses: see
``PoseGraph2D.landmark_ids`` and ``write_isam``."""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import Optional, Union

from . import _core
from .io._files import file_path
from ._core import (IncrementalOptions, IncrementalReport, OptimizationReport, OptimizerOptions, PoseGraph2D,
                    PoseGraph3D, PoseGraphReadReport, SparseCholeskyOptions, initialize_chordal, initialize_odometry,
                    joint_marginal_covariances, marginal_covariances, optimize, optimize_incremental)

PathLike = Union[str, "os.PathLike[str]"]

#: rows="skip": a file with more than this fraction of its records skipped is refused, naming the
#: first bad line (the C++ reader's kMaxBadRowFraction).
MAX_BAD_ROW_FRACTION = _core.MAX_BAD_ROW_FRACTION
#: The information-repair policy's floor: a record's information matrix that is not positive
#: definite gets its eigenvalues raised to at least this fraction of the largest (the C++
#: reader's kInformationEigenvalueFloor; docs/pose_graphs.md).
INFORMATION_EIGENVALUE_FLOOR = _core.INFORMATION_EIGENVALUE_FLOOR


def read_pose_graph(path: PathLike, format: str = "auto", *, noise: str = "default",
                    rows: str = "strict", equivalences: str = "merge") -> PoseGraph2D:
    """Read a 2-D pose/landmark graph: ``format`` 'g2o' (VERTEX_SE2 / EDGE_SE2 / VERTEX_XY /
    EDGE_SE2_XY), 'toro' (VERTEX2 / EDGE2), 'isam' (ODOMETRY / EDGE2 / LANDMARK, vertices
    dead-reckoned) or 'auto' (from the first record).

    ``noise``: what the edges' noise entries (upper triangle, in the format's order) hold, as
    GTSAM's NoiseFormat: 'default' (the format's own: information for g2o and TORO, square-root
    information for iSAM), 'information', 'sqrt_information' (upper-triangular R, information
    R^T R) or 'covariance' (information by Cholesky inverse). The graph keeps information.

    ``rows``: 'strict' (a malformed record raises ``ValueError("file:line: ...")``) or 'skip'
    (skipped and counted; more than ``MAX_BAD_ROW_FRACTION`` of the records raises, naming the
    first; ``read_pose_graph_with_report`` tells which were skipped). A missing file raises
    ``FileNotFoundError`` naming it (as every reader of the package does).

    An edge whose information matrix is finite and symmetric but not positive definite (SE-Sync's
    cubicle.g2o has thousands) is repaired, not refused: its eigenvalues are raised to
    ``INFORMATION_EIGENVALUE_FLOOR`` times the largest, eigenvectors kept (docs/pose_graphs.md,
    "Information repair"); ``report.repaired_rows`` counts them. The same holds for the 3-D
    readers.

    ``equivalences``: what TORO's ``EQUIV i j`` records (i and j are one node) do: 'merge' (each
    chain of equivalent ids becomes its smallest id, edges between them are dropped: TORO's
    collapse) or 'ignore' (the VERTEX2 / EDGE2 records alone, as GTSAM's ``load2D`` reads)."""
    return _core.read_pose_graph(file_path(path), format, noise, rows, equivalences)


@dataclass(frozen=True)
class PoseGraphRead:
    """A graph read from a file and what the reader skipped (``report.skipped_rows``,
    ``report.skipped_lines``, ``report.skipped_reasons``) or repaired (``report.repaired_rows``,
    ``report.repaired_lines``, ``report.repaired_reasons``)."""

    graph: PoseGraph2D
    report: PoseGraphReadReport


def read_pose_graph_with_report(path: PathLike, format: str = "auto", *, noise: str = "default",
                                rows: str = "skip", equivalences: str = "merge") -> PoseGraphRead:
    """``read_pose_graph`` for real data: by default malformed records are skipped and reported
    (docs/reliability.md), the first ``_core.POSE_GRAPH_MAX_REPORTED_LINES`` by line and reason."""
    graph, report = _core.read_pose_graph_with_report(file_path(path), format, noise, rows, equivalences)
    return PoseGraphRead(graph, report)


@dataclass(frozen=True)
class PoseGraph3DRead:
    """A 3-D graph read from a file and what the reader skipped (as ``PoseGraphRead``)."""

    graph: PoseGraph3D
    report: PoseGraphReadReport


#: A quaternion further than this from unit norm is refused (files print 6-9 digits: rounding
#: alone stays within 1e-6); the C++ kQuaternionNormTolerance.
QUATERNION_NORM_TOLERANCE: float = _core.QUATERNION_NORM_TOLERANCE


def read_pose_graph_3d(path: PathLike, format: str = "auto", *, noise: str = "default",
                       rows: str = "strict") -> PoseGraph3D:
    """Read a 3-D pose graph file into a ``PoseGraph3D`` (in C++, no per-record Python).

    ``format``: 'g2o' (VERTEX_SE3:QUAT, EDGE_SE3:QUAT, EDGE_SE3_PRIOR through an identity
    PARAMS_SE3OFFSET, VERTEX_TRACKXYZ, EDGE_SE3_TRACKXYZ, FIX), 'isam' (EDGE3 i j x y z roll pitch
    yaw + 21; VERTEX3 id x y z roll pitch yaw as GTSAM's load3D; without vertices the poses are
    dead-reckoned along the edges), 'toro' (VERTEX3 / EDGE3) or 'auto' (from the first record:
    VERTEX3 is TORO, EDGE3 iSAM, anything else g2o). Euler angles give R = Rz(yaw) Ry(pitch)
    Rx(roll); quaternions are (x, y, z, w) as g2o writes them, normalised when a file's rounding
    leaves them within ``QUATERNION_NORM_TOLERANCE`` of unit norm, refused otherwise. An edge
    (i, j) measures x_i^-1 x_j with (6, 6) information in g2o's order [translation, rotation].

    ``noise``: what the 21 upper-triangle noise entries hold, as ``read_pose_graph``: 'default'
    (information for g2o and TORO, square-root information for iSAM, as iSAM's own loader;
    GTSAM's load3D reads iSAM files as 'information'), 'information', 'sqrt_information' or
    'covariance'. ``rows``: 'strict' (a malformed record raises ``ValueError("file:LINE:
    reason")``) or 'skip' (skipped and counted, ``read_pose_graph_3d_with_report``).

    FIX records fix their vertices; ``EDGE_SE3_PRIOR`` records become priors
    (``PoseGraph3D.add_pose_prior``), whose rotation block weighs the rotation vector as the
    graph's edges do. A 2-D file raises ``ValueError`` naming ``read_pose_graph``; a missing one
    ``FileNotFoundError``."""
    return _core.read_pose_graph_3d(file_path(path), format, noise, rows)[0]


def read_pose_graph_3d_with_report(path: PathLike, format: str = "auto", *, noise: str = "default",
                                   rows: str = "skip") -> PoseGraph3DRead:
    """``read_pose_graph_3d`` for real data: malformed records skipped and reported by default."""
    graph, report = _core.read_pose_graph_3d(file_path(path), format, noise, rows)
    return PoseGraph3DRead(graph, report)


def write_g2o_3d(graph: PoseGraph3D, path: PathLike) -> None:
    """Write ``graph`` at its current values to ``path`` as g2o text (VERTEX_SE3:QUAT, FIX,
    EDGE_SE3:QUAT, and priors as EDGE_SE3_PRIOR through one identity PARAMS_SE3OFFSET), 17
    significant digits: ``read_pose_graph_3d`` gives the same graph back."""
    if not isinstance(graph, PoseGraph3D):
        raise TypeError(f"graph: expected a PoseGraph3D, got {type(graph).__name__}")
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path: expected a str or os.PathLike, got {type(path).__name__}")
    _core.write_g2o_3d(os.fspath(path), graph)


#: Records that tell a 3-D graph file from a 2-D one (the first of either kind decides).
_TAGS_3D = frozenset({b"VERTEX_SE3:QUAT", b"EDGE_SE3:QUAT", b"EDGE_SE3_PRIOR", b"PARAMS_SE3OFFSET", b"VERTEX3",
                      b"EDGE3", b"VERTEX_TRACKXYZ", b"EDGE_SE3_TRACKXYZ"})
_TAGS_2D = frozenset({b"VERTEX_SE2", b"VERTEX_XY", b"EDGE_SE2", b"EDGE_SE2_XY", b"VERTEX2", b"EDGE2", b"ODOMETRY",
                      b"LANDMARK"})
#: Bytes of a line looked at for its tag: a record's tag is its first word, well within this.
_TAG_BYTES = 64


def pose_graph_dimension(path: PathLike) -> int:
    """2 or 3: the dimension of the graph in ``path``, from its first record that only one of the
    readers takes (``FIX``, comments and unknown tags are passed over). A file with none of them
    is 2 (the 2-D reader then names what is wrong with it)."""
    path = file_path(path)
    start_of_line = True
    with open(path, "rb") as f:
        # Bounded reads: a file of one endless line costs _TAG_BYTES at a time, not its size.
        while chunk := f.readline(_TAG_BYTES):
            head, start_of_line = start_of_line, chunk.endswith(b"\n")
            words = chunk.split(None, 1) if head else []
            if words and words[0] in _TAGS_3D:
                return 3
            if words and words[0] in _TAGS_2D:
                return 2
    return 2


def _writer_arguments(name: str, graph, path):
    """(graph, path) of a writer called as ``name(graph, path)``, or in the old order
    ``name(path, graph)`` (deprecated: a DeprecationWarning)."""
    if isinstance(path, PoseGraph2D) and not isinstance(graph, PoseGraph2D):
        warnings.warn(f"{name}(path, graph) is deprecated: call {name}(graph, path), the order of every writer "
                      "(save_ros_map(grid, path), grid.write_bt(path))", DeprecationWarning, stacklevel=3)
        graph, path = path, graph
    if not isinstance(graph, PoseGraph2D):
        raise TypeError(f"graph: expected a PoseGraph2D, got {type(graph).__name__}")
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path: expected a str or os.PathLike, got {type(path).__name__}")
    return graph, os.fspath(path)


def write_g2o(graph: PoseGraph2D, path: PathLike) -> None:
    """Write ``graph`` to ``path`` in g2o text (VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY, FIX).
    The old argument order ``write_g2o(path, graph)`` still works, with a DeprecationWarning."""
    graph, path = _writer_arguments("write_g2o", graph, path)
    _core.write_g2o(path, graph)


def write_isam(graph: PoseGraph2D, path: PathLike) -> None:
    """Write ``graph`` to ``path`` in iSAM text: pose edges, then LANDMARK edges under each point's
    landmark id (see ``PoseGraph2D.landmark_ids``); no vertex values (reading back dead-reckons
    them). The old argument order ``write_isam(path, graph)`` still works, with a
    DeprecationWarning."""
    graph, path = _writer_arguments("write_isam", graph, path)
    _core.write_isam(path, graph)

#: The starting points ``initialize`` offers (ch. 11.3): dead reckoning, the EKF SLAM estimate,
#: and incremental optimisation pose by pose.
INITIALIZATIONS = ("odometry", "ekf", "incremental")


def initialize(graph: PoseGraph2D, method: str = "odometry", options: Optional[IncrementalOptions] = None,
               **fields) -> Optional[IncrementalReport]:
    """Replace the graph's values by a starting point for ``optimize``.

    ``method``:
      * ``"odometry"``: dead reckoning, composing pose edges outward from the held vertices
        (``initialize_odometry``);
      * ``"ekf"``: the estimate of EKF SLAM run along the poses in the order they were added,
        with the pose edges between consecutive poses as odometry and the point edges as
        landmark observations (``landmark_slam.run_ekf_on_graph``);
      * ``"incremental"``: ``optimize_incremental`` with ``options`` (an ``IncrementalOptions``,
        None: its defaults) and ``fields`` of it by keyword (``poses_per_step``, ``step``): the
        poses join ``poses_per_step`` at a time and the graph so far is optimised after each
        step; its report is returned, and the graph ends at a minimum of the full problem.

    Fixed vertices keep their values. Raises ValueError for an unknown method.
    """
    if method != "incremental" and (options is not None or fields):
        name = "options" if options is not None else next(iter(fields))
        raise ValueError(f"{name}: options apply to method 'incremental' only, not to {method!r}")
    if method == "odometry":
        initialize_odometry(graph)
        return None
    if method == "ekf":
        from .landmark_slam import run_ekf_on_graph

        run = run_ekf_on_graph(graph)
        free = [not graph.is_fixed(int(i)) for i in graph.pose_ids]
        graph.set_poses(graph.pose_ids[free], run.poses[free])
        points = [i for i in run.landmarks if not graph.is_fixed(i)]
        if points:
            graph.set_points(points, [run.landmarks[i] for i in points])
        return None
    if method == "incremental":
        return optimize_incremental(graph, options=options, **fields)
    raise ValueError(f"method must be one of {', '.join(repr(m) for m in INITIALIZATIONS)}, got {method!r}")


__all__ = [
    "QUATERNION_NORM_TOLERANCE",
    "INITIALIZATIONS",
    "IncrementalOptions",
    "IncrementalReport",
    "OptimizerOptions",
    "SparseCholeskyOptions",
    "OptimizationReport",
    "INFORMATION_EIGENVALUE_FLOOR",
    "MAX_BAD_ROW_FRACTION",
    "PoseGraph2D",
    "PoseGraph3D",
    "PoseGraph3DRead",
    "PoseGraphRead",
    "PoseGraphReadReport",
    "initialize",
    "initialize_chordal",
    "initialize_odometry",
    "joint_marginal_covariances",
    "marginal_covariances",
    "optimize",
    "optimize_incremental",
    "pose_graph_dimension",
    "read_pose_graph",
    "read_pose_graph_3d",
    "read_pose_graph_3d_with_report",
    "read_pose_graph_with_report",
    "write_g2o",
    "write_g2o_3d",
    "write_isam",
]
