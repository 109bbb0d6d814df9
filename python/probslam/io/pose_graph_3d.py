"""3-D pose graph files (g2o ``VERTEX_SE3:QUAT`` / ``EDGE_SE3:QUAT``, iSAM / GTSAM ``EDGE3``, TORO
3-D) as numpy arrays. The reading is C++ (``include/probslam/io/pose_graph_file_3d.hpp``); this
module names the arrays.

Conventions, the same for every format:

- a pose x = (q, t) maps body to world: p_world = R(q) p_body + t;
- quaternions are rows (x, y, z, w): the order of g2o files and of
  ``scipy.spatial.transform.Rotation.from_quat``; they are unit (normalised on reading when a
  file's rounding leaves them within ``QUATERNION_NORM_TOLERANCE`` of 1, refused otherwise);
- an edge (i, j) measures x_i^-1 x_j;
- information is (6, 6) in g2o's tangent order [translation, rotation]. The numbers are the
  file's: g2o's own EdgeSE3 applies the rotation block to the error quaternion's vector part
  (half the angle), GTSAM's readG2o and SE-Sync to the rotation vector (the whole angle);
- 3-D points (g2o ``VERTEX_TRACKXYZ``) share the poses' id space; a point edge
  (``EDGE_SE3_TRACKXYZ pose point param x y z`` + 6 information entries) measures the point in the
  frame of the sensor at the ``PARAMS_SE3OFFSET`` ``param`` on the pose: error
  (x_pose * offset)^-1 p - z, (3, 3) information (always information, g2o's convention).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Union

import numpy as np

from .. import _core
from ._files import file_path

PathLike = Union[str, "os.PathLike[str]"]

#: A quaternion further than this from unit norm is refused (files print 6-9 digits: rounding
#: alone stays within 1e-6); the C++ kQuaternionNormTolerance.
QUATERNION_NORM_TOLERANCE: float = _core.QUATERNION_NORM_TOLERANCE

_ARRAYS = ("vertex_ids", "quaternions", "translations", "fixed", "edges", "edge_quaternions", "edge_translations",
           "information", "prior_ids", "prior_quaternions", "prior_translations", "prior_information", "point_ids",
           "points", "point_fixed", "point_edges", "point_measurements", "point_information",
           "point_offset_quaternions", "point_offset_translations")


def _empty(*shape, dtype=float):
    return field(default_factory=lambda: np.zeros((0,) + shape, dtype=dtype))


@dataclass(frozen=True)
class PoseGraph3DFile:
    """A 3-D pose graph as its file holds it (vertices in file order, or in dead-reckoning order
    for an iSAM file, which lists none)."""

    vertex_ids: np.ndarray  #: (N,) int64
    quaternions: np.ndarray  #: (N, 4) unit quaternions (x, y, z, w)
    translations: np.ndarray  #: (N, 3)
    fixed: np.ndarray  #: (N,) bool: named by a g2o FIX record
    edges: np.ndarray  #: (E, 2) int64 vertex ids (from, to): the edge measures x_from^-1 x_to
    edge_quaternions: np.ndarray  #: (E, 4) (x, y, z, w)
    edge_translations: np.ndarray  #: (E, 3)
    information: np.ndarray  #: (E, 6, 6), order [translation, rotation]
    prior_ids: np.ndarray  #: (P,) int64: g2o EDGE_SE3_PRIOR, kept as priors (not fixed vertices)
    prior_quaternions: np.ndarray  #: (P, 4)
    prior_translations: np.ndarray  #: (P, 3)
    prior_information: np.ndarray  #: (P, 6, 6)
    report: "_core.PoseGraphReadReport"  #: rows read and skipped (rows="skip")
    point_ids: np.ndarray = _empty(dtype=np.int64)  #: (L,) int64: g2o VERTEX_TRACKXYZ, the poses' id space
    points: np.ndarray = _empty(3)  #: (L, 3) m
    point_fixed: np.ndarray = _empty(dtype=bool)  #: (L,) bool: named by a g2o FIX record
    point_edges: np.ndarray = _empty(2, dtype=np.int64)  #: (M, 2) int64 (pose id, point id)
    point_measurements: np.ndarray = _empty(3)  #: (M, 3) m, the point in the sensor's frame
    point_information: np.ndarray = _empty(3, 3)  #: (M, 3, 3)
    point_offset_quaternions: np.ndarray = _empty(4)  #: (M, 4) the sensor's rotation on the pose (x, y, z, w)
    point_offset_translations: np.ndarray = _empty(3)  #: (M, 3) the sensor's position on the pose


def read_pose_graph_3d(path: PathLike, format: str = "auto", *, noise: str = "default",
                       rows: str = "strict") -> PoseGraph3DFile:
    """Read a 3-D pose graph: ``format`` 'g2o' (VERTEX_SE3:QUAT, EDGE_SE3:QUAT, EDGE_SE3_PRIOR
    through an identity PARAMS_SE3OFFSET, VERTEX_TRACKXYZ, EDGE_SE3_TRACKXYZ, FIX), 'isam' (EDGE3 i j x y z roll pitch yaw + 21;
    VERTEX3 id x y z roll pitch yaw as GTSAM's load3D), 'toro' (VERTEX3 / EDGE3) or 'auto' (from
    the first record: VERTEX3 is TORO, EDGE3 iSAM, anything else g2o). Euler angles give
    R = Rz(yaw) Ry(pitch) Rx(roll).

    ``noise``: what the 21 upper-triangle noise entries hold, as ``probslam.graph.read_pose_graph``:
    'default' (information for g2o and TORO, square-root information for iSAM, as iSAM's own
    loader; GTSAM's load3D reads iSAM files as 'information'), 'information',
    'sqrt_information' or 'covariance'.

    ``rows``: 'strict' (a malformed record raises ``ValueError("file:LINE: reason")``) or 'skip'
    (skipped, counted and listed in ``report``; more than ``probslam.graph.MAX_BAD_ROW_FRACTION``
    of the records skipped raises, naming the first). A 2-D file raises, naming the 2-D reader. A
    missing file raises ``FileNotFoundError``."""
    arrays, report = _core.read_pose_graph_3d(file_path(path), format, noise, rows)
    return PoseGraph3DFile(report=report, **{name: arrays[name] for name in _ARRAYS})


def write_g2o_3d(graph: PoseGraph3DFile, path: PathLike) -> None:
    """Write ``graph`` (a ``PoseGraph3DFile``, e.g. one read and then changed with
    ``dataclasses.replace``) to ``path`` as g2o text, 17 significant digits: it reads back bit for
    bit. ValueError (and no file written) for arrays of the wrong shape, non-unit quaternions,
    non-symmetric information, a repeated vertex id or an edge naming an unknown vertex."""
    if not isinstance(graph, PoseGraph3DFile):
        raise TypeError(f"graph: expected a PoseGraph3DFile, got {type(graph).__name__}")
    _core.write_g2o_3d(file_path(path), {name: getattr(graph, name) for name in _ARRAYS})


__all__ = ["PoseGraph3DFile", "QUATERNION_NORM_TOLERANCE", "read_pose_graph_3d", "write_g2o_3d"]
