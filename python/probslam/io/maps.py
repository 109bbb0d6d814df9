"""Map files: ROS map_server (YAML + PGM) and PNG pictures. The library's lossless grid file is
``OccupancyGrid2D.save`` / ``load`` (a state file, docs/file_format.md)."""

from __future__ import annotations

import os
import struct
import zlib
from typing import Optional, Union

import numpy as np

from .. import _core
from .._args import require_instance
from ._files import file_path

PathLike = Union[str, "os.PathLike[str]"]


#: map_saver's default thresholds: cells above OCCUPIED_THRESH are written occupied, below
#: FREE_THRESH free, the rest unknown.
OCCUPIED_THRESH, FREE_THRESH = 0.65, 0.196


def save_ros_map(grid: _core.OccupancyGrid2D, yaml_path: PathLike,
                 occupied_thresh: float = OCCUPIED_THRESH, free_thresh: float = FREE_THRESH) -> None:
    """Write ``yaml_path`` and a trinary PGM beside it (map_saver's conventions)."""
    _core.save_ros_map(grid, file_path(yaml_path, "yaml_path"), occupied_thresh, free_thresh)


def load_ros_map(yaml_path: PathLike) -> _core.OccupancyGrid2D:
    """Read a map_server map (modes trinary and scale) into an OccupancyGrid2D. A missing file
    raises FileNotFoundError, a malformed one ValueError naming it."""
    return _core.load_ros_map(file_path(yaml_path, "yaml_path"))


def _png(pixels: np.ndarray) -> bytes:
    """PNG bytes of an 8-bit (h, w) grey or (h, w, 3) RGB image, row 0 at the top."""
    h, w = pixels.shape[:2]
    colour_type = 2 if pixels.ndim == 3 else 0
    rows = pixels.reshape(h, -1)
    raw = np.hstack([np.zeros((h, 1), np.uint8), rows]).tobytes()  # filter byte 0 per row

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    header = struct.pack(">IIBBBBB", w, h, 8, colour_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")


def write_png(grid: _core.OccupancyGrid2D, path: PathLike, trajectory: Optional[np.ndarray] = None) -> None:
    """Picture of the map: occupancy probability as grey (black occupied, white free), the
    top of the image at the largest y; ``trajectory`` (n, 2 or 3) metres is drawn in red (rows
    that are not finite are left out)."""
    require_instance(grid, _core.OccupancyGrid2D, "grid")
    if trajectory is not None:
        trajectory = np.asarray(trajectory)
        if trajectory.dtype.kind not in "iuf":
            raise TypeError(f"trajectory: expected real numbers, got dtype {trajectory.dtype}")
        if trajectory.ndim != 2 or trajectory.shape[1] not in (2, 3):
            raise ValueError(f"trajectory: expected shape (n, 2) or (n, 3), got {trajectory.shape}")
    grey = np.round(255.0 * (1.0 - grid.probability())).astype(np.uint8)[::-1]
    if trajectory is None:
        pixels = grey
    else:
        pixels = np.repeat(grey[:, :, None], 3, axis=2)
        xy = trajectory.astype(float)[:, :2]
        cells = grid.cell_of(xy[np.isfinite(xy).all(axis=1)])
        inside = (cells[:, 0] >= 0) & (cells[:, 0] < grid.height) & (cells[:, 1] >= 0) & (cells[:, 1] < grid.width)
        rows, cols = grid.height - 1 - cells[inside, 0], cells[inside, 1]
        pixels[rows, cols] = (220, 30, 30)
    with open(file_path(path), "wb") as f:
        f.write(_png(np.ascontiguousarray(pixels)))
