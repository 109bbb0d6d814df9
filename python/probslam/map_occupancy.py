"""MAP occupancy grid mapping with a forward sensor model (ch. 9.4.2, Table 9.3)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

from . import _core
from ._core import BeamSensorModel, OccupancyGrid2D


@dataclass
class MapOccupancyResult:
    """The mode of the map posterior found by Table 9.3's hill climbing.

    ``occupied`` (H, W) bool: the map; ``objective``: its eq. 9.24 (nats); ``sensitivity``
    (H, W): the change of eq. 9.24 when each cell alone is flipped (Fig. 9.8d; <= 0 at a local
    maximum; ``None`` if not asked for); ``field`` (H, W) bool: the cells some reading's beam
    covers (the cells visited); ``sweeps``/``flips``/``evaluations``: work done;
    ``converged``: a whole sweep changed nothing; ``readings``: range readings used;
    ``index_entries``: (reading, cell) pairs in the incremental scorer's index;
    ``trace_cells`` (n,) row-major index of each flipped cell and ``trace_objective`` (n,) eq.
    9.24 after it (empty unless ``record_trace``)."""

    occupied: np.ndarray
    objective: float
    sensitivity: Optional[np.ndarray]
    field: np.ndarray
    sweeps: int
    converged: bool
    flips: int
    evaluations: int
    readings: int
    field_cells: int
    index_entries: int
    trace_cells: np.ndarray
    trace_objective: np.ndarray


def map_occupancy_grid_mapping(poses, scans, beam_angles, model: BeamSensorModel, grid: OccupancyGrid2D,
                               prior: Union[None, float, np.ndarray] = None, *, max_sweeps: int = 1000,
                               scoring: str = "incremental", max_evaluations: int = 0, record_trace: bool = False,
                               sensitivity: bool = True) -> MapOccupancyResult:
    """Table 9.3: hill climbing on eq. 9.24 from the all-free map on ``grid``'s lattice.

    poses (T, 3) m, rad; scans (T, B) ranges in metres (>= 0, no NaN; inf or >= model.max_range
    are max readings); beam_angles (B,) or (T, B) rad relative to each heading; model: the
    forward model (its z_rand and z_max weights must be > 0); grid: only its geometry is used;
    prior: p(m_i = 1), a number or an (H, W) array, default ``grid.p_prior``. scoring
    ``"incremental"`` re-scores only the readings a flip affects; ``"full"`` re-evaluates
    eq. 9.24 from scratch per candidate (the literal table, for comparison); max_evaluations > 0
    stops after that many candidate flips."""
    out = _core.map_occupancy_grid_mapping(poses, scans, beam_angles, model, grid, prior, max_sweeps=max_sweeps,
                                           scoring=scoring, max_evaluations=max_evaluations,
                                           record_trace=record_trace, sensitivity=sensitivity)
    return MapOccupancyResult(**out)
