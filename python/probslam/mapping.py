"""Occupancy grid mapping with known poses (ch. 9.2) over a whole laser log."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Optional, Tuple

import numpy as np

from ._core import OccupancyGrid2D
from .io.carmen import LaserScans
from ._args import require_instance


@dataclass
class MappingResult:
    """What map_laser_log made: the grid, and what it integrated (scans, valid readings (beams),
    cell updates, seconds spent in the grid updates)."""

    grid: OccupancyGrid2D
    scans: int
    beams: int  # valid readings integrated
    cells_updated: int
    seconds: float  # time spent in the grid updates


def scan_bounds(scans: LaserScans, max_range: float, margin: float = 1.0) -> Tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) metres covering every pose and every beam end point (readings
    beyond max_range cut to it), widened by margin metres."""
    require_instance(scans, LaserScans, "scans")
    poses = scans.laser_poses
    ranges = np.where(np.isfinite(scans.ranges) & (scans.ranges >= 0), scans.ranges, 0.0)
    reach = np.minimum(ranges, max_range)
    bearing = poses[:, 2:3] + scans.beam_angles()
    xs = np.concatenate([poses[:, 0], (poses[:, 0:1] + reach * np.cos(bearing)).ravel()])
    ys = np.concatenate([poses[:, 1], (poses[:, 1:2] + reach * np.sin(bearing)).ravel()])
    return (xs.min() - margin, ys.min() - margin, xs.max() + margin, ys.max() + margin)


#: map_laser_log's cell size and range (m) by default (``probslam map``'s, and a learned inverse
#: model's that does not record its own).
DEFAULT_RESOLUTION, DEFAULT_MAX_RANGE = 0.05, 30.0


def map_laser_log(scans: LaserScans, resolution: float = DEFAULT_RESOLUTION, max_range: float = DEFAULT_MAX_RANGE,
                  robot_radius: float = 0.0, grid: Optional[OccupancyGrid2D] = None,
                  skip_no_return: bool = True, progress: Optional[bool] = None,
                  chunk: int = 64) -> MappingResult:
    """Map scans with known laser poses using the laser-beam update (``insert_rays``).

    The grid is sized from the data unless given (a given grid is grown to fit). Readings at
    or beyond ``max_range`` (metres) only clear space up to it. With ``skip_no_return``,
    readings at the sensor's maximum (``LaserScans.no_return_range``) are dropped: they mean "nothing
    seen" (often glass), not free space. With ``robot_radius`` > 0 the robot's footprint
    around each robot pose is cleared too. ``progress=None`` shows a bar only on a terminal.
    Returns a ``MappingResult`` (``.grid`` the map).
    """
    require_instance(scans, LaserScans, "scans")
    # All or nothing: everything is checked before the first chunk changes the grid, so that a
    # bad pose in the last chunk is reported by name, not as a bound or a half-built map.
    if len(scans) == 0:
        raise ValueError("scans must not be empty")
    if not (np.isfinite(max_range) and max_range > 0):
        raise ValueError("max_range must be finite and > 0")
    if not (np.isfinite(resolution) and resolution > 0):
        raise ValueError("resolution must be finite and > 0")
    if not (np.isfinite(robot_radius) and robot_radius >= 0):
        raise ValueError("robot_radius must be finite and >= 0")
    if int(chunk) != chunk or chunk < 1:
        raise ValueError("chunk must be an integer >= 1")
    if not np.all(np.isfinite(scans.laser_poses)):
        raise ValueError("scans.laser_poses must contain only finite values")
    if robot_radius > 0 and not np.all(np.isfinite(scans.robot_poses)):
        raise ValueError("scans.robot_poses must contain only finite values")
    if not np.all(np.isfinite(scans.beam_angles())):
        raise ValueError("scans.start_angles and angular_resolutions must be finite")
    if skip_no_return:
        ranges = np.where(scans.ranges >= scans.no_return_range(), np.nan, scans.ranges)
        scans = replace(scans, ranges=ranges)
    bounds = scan_bounds(scans, max_range)
    grid = OccupancyGrid2D.covering(bounds, resolution) if grid is None else grid.grown(bounds)
    angles = scans.beam_angles()
    from tqdm import tqdm

    updated, seconds = 0, 0.0
    bar = tqdm(total=len(scans), unit="scan", disable=(None if progress is None else not progress))
    chunk = int(chunk)
    for start in range(0, len(scans), chunk):
        stop = min(start + chunk, len(scans))
        t0 = time.perf_counter()
        updated += grid.insert_scans(scans.laser_poses[start:stop], scans.ranges[start:stop],
                                     angles[start:stop], max_range)
        if robot_radius > 0:
            for pose in scans.robot_poses[start:stop]:
                updated += grid.clear_footprint(pose, robot_radius)
        seconds += time.perf_counter() - t0
        bar.update(stop - start)
    bar.close()
    beams = int(np.count_nonzero(np.isfinite(scans.ranges) & (scans.ranges >= 0)))
    return MappingResult(grid, len(scans), beams, updated, seconds)
