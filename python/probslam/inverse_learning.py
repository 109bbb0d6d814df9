"""Learning inverse measurement models from a forward model (ch. 9.3).

9.3.2: random maps from a documented prior (:func:`random_map`), poses uniform in free space,
readings sampled from a forward model (:class:`probslam.BeamSensorModel`, ch. 6.3), and the true
occupancy of the cells inside the perceptual field, encoded by the invariances of 9.3.2: the
cell's polar coordinates relative to the robot (eq. 9.14), as range and angle off the nearest
beam's axis, and the ranges of the five adjacent beams (Fig. 9.6).
9.3.3: a function approximator f(input, W) in [0, 1] trained by minimising J(W) of eq. 9.20
(cross-entropy): a one-hidden-layer network (tanh, sigmoid output) in numpy with its gradient
written out (tested against finite differences), minimised by scipy's L-BFGS.
The learned model plugs into Table 9.1 (:meth:`LearnedInverseModel.insert_scan`).

Units: metres, radians. Maps are (H, W) bool arrays on an OccupancyGrid2D's lattice.
"""

from __future__ import annotations

import io
import json
import lzma
import math
import os
import struct
import time
import zipfile
import zlib
from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np

from ._core import BeamSensorModel, BinaryMap2D, OccupancyGrid2D, logit
from .io._files import file_path, require_regular_file
from ._args import positive_real, real_array, require_fields, require_instance, require_integer

#: Beams whose readings are the input besides the cell's coordinates: the nearest and two on
#: each side (Fig. 9.6's "five adjacent range measurements").
NEIGHBOURS = 5
#: Predicted probabilities are kept in [EPS, 1 - EPS] before logit and log: a saturated
#: network would otherwise give infinite log-odds and an infinite J(W).
EPS = 1e-6
#: The most (cell, beam) pairs field_features holds at once: each cell's nearest beam is found
#: over all beams, at 16 bytes (complex) per pair in each of a few temporaries, so 2^20 pairs keep
#: the peak near 50 MB whatever the scan (one 180-beam 30 m scan on a 5 cm grid asked for 3.9 GiB).
FIELD_CHUNK_PAIRS = 1 << 20


def _outer_walls(grid: OccupancyGrid2D, rng: np.random.Generator) -> np.ndarray:
    """Where every prior starts: (H, W) bool, the outer walls one cell thick (``grid`` and ``rng``
    checked)."""
    require_instance(grid, OccupancyGrid2D, "grid")
    require_instance(rng, np.random.Generator, "rng")
    occ = np.zeros(grid.shape, dtype=bool)
    occ[[0, -1], :] = True
    occ[:, [0, -1]] = True
    return occ


def random_map(grid: OccupancyGrid2D, rng: np.random.Generator, min_room: float = 2.0, door: float = 0.9,
               clutter: int = 6) -> np.ndarray:
    """A map drawn from the prior used for training: outer walls one cell thick; the floor split
    recursively into rooms (a split while the part is wider than 2 ``min_room`` m, at a uniform
    position at least ``min_room`` from its ends) by walls with one door ``door`` m wide each at
    a uniform position; then ``clutter`` boxes of 0.2-0.6 m per side at uniform positions
    (furniture). Returns (H, W) bool."""
    occ = _outer_walls(grid, rng)
    (h, w), res = occ.shape, grid.resolution
    min_cells = max(2, int(round(min_room / res)))
    door_cells = max(1, int(round(door / res)))

    def split(r0, r1, c0, c1):  # the free rectangle rows [r0, r1), cols [c0, c1)
        can_h, can_v = r1 - r0 > 2 * min_cells, c1 - c0 > 2 * min_cells
        if not (can_h or can_v):
            return
        vertical = can_v and (not can_h or rng.random() < (c1 - c0) / (r1 - r0 + c1 - c0))
        if vertical:
            c = int(rng.integers(c0 + min_cells, c1 - min_cells))
            occ[r0:r1, c] = True
            d = int(rng.integers(r0, max(r0 + 1, r1 - door_cells)))
            occ[d:d + door_cells, c] = False
            split(r0, r1, c0, c)
            split(r0, r1, c + 1, c1)
        else:
            r = int(rng.integers(r0 + min_cells, r1 - min_cells))
            occ[r, c0:c1] = True
            d = int(rng.integers(c0, max(c0 + 1, c1 - door_cells)))
            occ[r, d:d + door_cells] = False
            split(r0, r, c0, c1)
            split(r + 1, r1, c0, c1)

    split(1, h - 1, 1, w - 1)
    for _ in range(clutter):
        bh, bw = (rng.uniform(0.2, 0.6, 2) / res).astype(int) + 1
        r, c = int(rng.integers(1, h - bh - 1)), int(rng.integers(1, w - bw - 1))
        occ[r:r + bh, c:c + bw] = True
    return occ


def pillar_map(grid: OccupancyGrid2D, rng: np.random.Generator, walls: int = 5, pillars: int = 8) -> np.ndarray:
    """A second prior, unlike :func:`random_map`'s axis-aligned rooms: outer walls one cell
    thick, ``walls`` straight walls 1.5-4 m long at uniform positions and uniform angles (slanted
    against the lattice), and ``pillars`` round pillars of radius 0.1-0.4 m (a cell is occupied
    when its centre lies inside the disc or the wall's segment passes through the cell).
    Returns (H, W) bool."""
    occ = _outer_walls(grid, rng)
    walls, pillars = require_integer(walls, "walls", 0), require_integer(pillars, "pillars", 0)
    (h, w), res = occ.shape, grid.resolution
    for _ in range(walls):
        length, angle = rng.uniform(1.5, 4.0), rng.uniform(-np.pi, np.pi)
        cx, cy = rng.uniform(0, w * res), rng.uniform(0, h * res)
        t = np.linspace(-length / 2, length / 2, int(np.ceil(4 * length / res)) + 1)  # 4 points per cell
        cols = np.floor((cx + t * np.cos(angle)) / res).astype(int)
        rows = np.floor((cy + t * np.sin(angle)) / res).astype(int)
        ok = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        occ[rows[ok], cols[ok]] = True
    yy, xx = (np.mgrid[0:h, 0:w] + 0.5) * res
    for _ in range(pillars):
        radius = rng.uniform(0.1, 0.4)
        cx, cy = rng.uniform(radius, w * res - radius), rng.uniform(radius, h * res - radius)
        occ |= np.hypot(xx - cx, yy - cy) <= max(radius, res / 2)
    return occ


#: The world priors by name (studies and the sampling functions take any callable (grid, rng) -> map).
WORLDS = {"rooms": random_map, "pillars": pillar_map}


def free_poses(grid: OccupancyGrid2D, occupied: np.ndarray, n: int, rng: np.random.Generator,
               clearance: float = 0.3) -> np.ndarray:
    """n poses (n, 3) uniform over the cells farther than ``clearance`` m from every occupied
    cell (continuous within the cell), headings uniform in (-pi, pi]."""
    require_instance(grid, OccupancyGrid2D, "grid")
    require_instance(rng, np.random.Generator, "rng")
    occupied = np.asarray(occupied)
    if occupied.dtype != bool or occupied.shape != tuple(grid.shape):
        raise ValueError(f"occupied: expected a bool array of the grid's shape {tuple(grid.shape)}, "
                         f"got {occupied.dtype} {occupied.shape}")
    from scipy.ndimage import distance_transform_edt

    res = grid.resolution
    far = distance_transform_edt(~occupied) * res > clearance
    rows, cols = np.nonzero(far)
    if rows.size == 0:
        raise ValueError("occupied leaves no free cell farther than clearance from every obstacle")
    k = rng.integers(0, rows.size, n)
    x0, y0 = grid.origin
    theta = np.pi - rng.random(n) * 2 * np.pi  # (-pi, pi]
    return np.column_stack([x0 + (cols[k] + rng.random(n)) * res, y0 + (rows[k] + rng.random(n)) * res, theta])


def field_features(grid: OccupancyGrid2D, pose: np.ndarray, ranges: np.ndarray, beam_angles: np.ndarray,
                   max_range: float, half_angle: float) -> Tuple[np.ndarray, np.ndarray]:
    """The cells inside the perceptual field of one scan and their inputs.

    A cell is in the field when its centre lies closer than ``max_range`` m and within
    ``half_angle`` rad of its nearest beam (beam_angles (B,) relative to the heading, a ring in
    increasing order). Returns (cells (n,) row-major indices, inputs (n, 2 + NEIGHBOURS)): the
    cell's range (m) and its angle off the nearest beam's axis (rad, eq. 9.14 in polar form,
    relative to the beam so that identical sensors share the model), then the readings of the
    nearest beam and its neighbours in ring order (min(z, max_range), m).

    Errors: TypeError or ValueError naming the argument for a grid of the wrong class, a pose
    that is not 3 finite numbers, beam angles that are empty or not finite, ranges of another
    length or NaN or negative (inf: no return), max_range or half_angle not finite and > 0.
    Memory: the cells are visited in chunks of at most FIELD_CHUNK_PAIRS (cell, beam) pairs."""
    pose, ranges, beam_angles, max_range, half_angle = _scan_arguments(grid, pose, ranges, beam_angles,
                                                                       max_range, half_angle)
    h, w = grid.shape
    c_lo, c_hi = _cells_within(pose[0], max_range, grid.origin[0], grid.resolution, w)
    r_lo, r_hi = _cells_within(pose[1], max_range, grid.origin[1], grid.resolution, h)
    if c_lo > c_hi or r_lo > r_hi:
        return np.empty(0, dtype=np.int64), np.empty((0, 2 + NEIGHBOURS))
    box = (r_lo, c_lo, c_hi - c_lo + 1)
    count = (r_hi - r_lo + 1) * box[2]
    step = max(1, FIELD_CHUNK_PAIRS // beam_angles.size)
    parts = [_field_chunk(grid, pose, beam_angles, max_range, half_angle, box, np.arange(i, min(i + step, count)))
             for i in range(0, count, step)]
    cells, k, phi, r = (np.concatenate(p) for p in zip(*parts))
    b = len(beam_angles)
    z = np.minimum(np.nan_to_num(ranges, posinf=max_range), max_range)
    near = z[(k[:, None] + np.arange(-(NEIGHBOURS // 2), NEIGHBOURS // 2 + 1)[None, :]) % b]
    return cells, np.column_stack([r, phi, near])


def _scan_arguments(grid, pose, ranges, beam_angles, max_range, half_angle):
    """The arguments of field_features / insert_scan, checked and converted (see field_features)."""
    require_instance(grid, OccupancyGrid2D, "grid")
    pose = real_array(pose, "pose", (3,))
    beam_angles = _beam_angles(beam_angles)
    ranges = real_array(ranges, "ranges", beam_angles.shape, finite=False)  # inf: no return
    if np.any(np.isnan(ranges)) or np.any(ranges < 0):
        raise ValueError("ranges must be >= 0 and not NaN (inf: no return)")
    return pose, ranges, beam_angles, positive_real(max_range, "max_range"), positive_real(half_angle, "half_angle")


def _beam_angles(value: object) -> np.ndarray:
    """beam_angles as a checked (B,) float array, B >= 1."""
    beam_angles = real_array(value, "beam_angles", (None,))
    if beam_angles.size == 0:
        raise ValueError("beam_angles: expected at least one beam")
    return beam_angles


def _cells_within(v: float, reach: float, v0: float, res: float, n: int) -> Tuple[int, int]:
    """The first and last of the n lattice cells (origin v0, size res) that [v - reach, v + reach]
    touches along one axis, clipped to [0, n - 1] (first > last: none); never overflows."""
    lo = np.clip(np.floor(((v - reach) - v0) / res), 0, n)
    hi = np.clip(np.floor(((v + reach) - v0) / res), -1, n - 1)
    return int(lo), int(hi)


def _field_chunk(grid, pose, beam_angles, max_range, half_angle, box, idx):
    """field_features over the cells ``idx`` (row-major positions in the box (first row, first
    column, width)): (cells, nearest beam, angle off it, range) of those inside the field."""
    r0, c0, box_w = box
    rows, cols = r0 + idx // box_w, c0 + idx % box_w
    res = grid.resolution
    x0, y0 = grid.origin
    dx = x0 + (cols + 0.5) * res - pose[0]
    dy = y0 + (rows + 0.5) * res - pose[1]
    r = np.hypot(dx, dy)
    inside = r < max_range  # cells beyond the range never enter the field: skip their beam search
    rows, cols, dx, dy, r = rows[inside], cols[inside], dx[inside], dy[inside], r[inside]
    bearing = np.arctan2(dy, dx) - pose[2]
    k, phi = _nearest_beam(bearing, beam_angles)
    keep = np.abs(phi) <= half_angle
    return (rows * grid.shape[1] + cols)[keep], k[keep], phi[keep], r[keep]


def _nearest_beam(bearing: np.ndarray, beam_angles: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """For each bearing (rad, relative to the heading) the index of the beam nearest on the
    circle (the lowest index on a tie) and the wrapped angle off that beam's axis. The nearest
    beam on the circle is one of the two that enclose the bearing in the beams' circular order,
    so a sorted search replaces the comparison with every beam (O(log B) per cell, not O(B));
    beams whose wrapped angles repeat fall back to comparing every beam (ties by index)."""
    order = np.argsort(np.angle(np.exp(1j * beam_angles)), kind="stable")
    sorted_wrapped = np.angle(np.exp(1j * beam_angles[order]))
    b = beam_angles.size
    if b > 1 and np.any(np.diff(sorted_wrapped) == 0):
        off = np.angle(np.exp(1j * (bearing[:, None] - beam_angles[None, :])))
        k = np.argmin(np.abs(off), axis=1)
        return k, off[np.arange(k.size), k]
    pos = np.searchsorted(sorted_wrapped, np.angle(np.exp(1j * bearing)))
    lo, hi = order[(pos - 1) % b], order[pos % b]
    # the same expression as over every beam, so that the angles are bit for bit those of the comparison
    off_lo = np.angle(np.exp(1j * (bearing - beam_angles[lo])))
    off_hi = np.angle(np.exp(1j * (bearing - beam_angles[hi])))
    a_lo, a_hi = np.abs(off_lo), np.abs(off_hi)
    take_lo = (a_lo < a_hi) | ((a_lo == a_hi) & (lo < hi))
    return np.where(take_lo, lo, hi), np.where(take_lo, off_lo, off_hi)


@dataclass
class TrainingSet:
    """inputs (n, 2 + NEIGHBOURS) as field_features; occupied (n,) bool, the true occupancy."""

    inputs: np.ndarray
    occupied: np.ndarray


def sample_training_set(grid: OccupancyGrid2D, model: BeamSensorModel, beam_angles: np.ndarray, maps: int,
                        poses_per_map: int, rng: np.random.Generator, cells_per_scan: int = 400,
                        half_angle: Optional[float] = None, world: Callable = random_map) -> TrainingSet:
    """9.3.2 steps 1-4: ``maps`` random maps (:func:`random_map`) on ``grid``'s lattice,
    ``poses_per_map`` poses uniform in free space each, one scan per pose sampled from ``model``,
    and up to ``cells_per_scan`` cells drawn uniformly from the scan's perceptual field with their
    true occupancy. half_angle: the field's half width around a beam (rad), default beta/2 for a
    sonar and half the beam spacing for a laser. world: the prior the maps are drawn from, a
    callable (grid, rng) -> (H, W) bool such as :func:`random_map` (default) or :func:`pillar_map`."""
    require_instance(grid, OccupancyGrid2D, "grid")
    require_instance(model, BeamSensorModel, "model")
    require_instance(rng, np.random.Generator, "rng")
    maps, poses_per_map = require_integer(maps, "maps", 1), require_integer(poses_per_map, "poses_per_map", 1)
    cells_per_scan = require_integer(cells_per_scan, "cells_per_scan", 1)
    beam_angles = _beam_angles(beam_angles)
    half = _half_angle(model, beam_angles, half_angle)
    inputs, labels = [], []
    if not callable(world):
        raise TypeError(f"world: expected a callable (grid, rng) -> map, got {type(world).__name__}")
    for _ in range(maps):
        occ = world(grid, rng)
        bmap = BinaryMap2D(grid, occ)
        for pose in free_poses(grid, occ, poses_per_map, rng):
            z = model.sample(pose, beam_angles, bmap, rng)
            cells, x = field_features(grid, pose, z, beam_angles, model.max_range, half)
            if cells.size > cells_per_scan:
                pick = rng.choice(cells.size, cells_per_scan, replace=False)
                cells, x = cells[pick], x[pick]
            inputs.append(x)
            labels.append(occ.ravel()[cells])
    return TrainingSet(np.concatenate(inputs), np.concatenate(labels))


def _half_angle(model: BeamSensorModel, beam_angles: np.ndarray, half_angle: Optional[float]) -> float:
    if half_angle is not None:
        return positive_real(half_angle, "half_angle")
    if model.shape == "sonar":
        return model.beta / 2
    return np.pi / len(beam_angles)  # half the spacing of a ring; a fan should pass half_angle


def sample_scans(grid: OccupancyGrid2D, model: BeamSensorModel, beam_angles: np.ndarray, maps: int,
                 poses_per_map: int, rng: np.random.Generator, world: Callable = random_map) -> List[tuple]:
    """``maps`` worlds drawn from ``world`` (as in :func:`sample_training_set`), each with
    ``poses_per_map`` poses uniform in free space and one scan sampled from ``model`` at each:
    a list of (occupied (H, W) bool, poses (n, 3), ranges (n, B)). What :meth:`LearnedInverseModel.
    fit_evidence_scale` and the studies map."""
    require_instance(grid, OccupancyGrid2D, "grid")
    require_instance(model, BeamSensorModel, "model")
    require_instance(rng, np.random.Generator, "rng")
    maps, poses_per_map = require_integer(maps, "maps", 1), require_integer(poses_per_map, "poses_per_map", 1)
    beam_angles = _beam_angles(beam_angles)
    if not callable(world):
        raise TypeError(f"world: expected a callable (grid, rng) -> map, got {type(world).__name__}")
    out = []
    for _ in range(maps):
        occ = world(grid, rng)
        bmap = BinaryMap2D(grid, occ)
        poses = free_poses(grid, occ, poses_per_map, rng)
        out.append((occ, poses, np.array([model.sample(p, beam_angles, bmap, rng) for p in poses])))
    return out


def map_cross_entropy(log_odds: np.ndarray, occupied: np.ndarray) -> float:
    """Mean cross-entropy (nats per cell) of occupancy log-odds (n,) against the true occupancy
    (n,) bool: -mean(y log p + (1 - y) log(1 - p)), p = sigmoid(l), computed from l without
    rounding p to 0 or 1."""
    l = np.asarray(log_odds, dtype=float)
    y = np.asarray(occupied, dtype=float)
    return float(np.mean(np.logaddexp(0.0, l) - y * l))


#: A cell of a known map built from a log (:func:`known_map`) is decided when its log-odds differs
#: from the prior by at least this much: more than one hit (insert_rays adds logit(0.7) = 0.85
#: per hit) or about three passes, so that one stray beam never labels a cell for training.
KNOWN_LOG_ODDS = 1.5


def known_map(scans, resolution: float, max_range: float, grid: Optional[OccupancyGrid2D] = None):
    """ch. 9.3.4's known map: the scans of a corrected log (:class:`probslam.io.LaserScans`, poses
    taken as true) mapped with Table 9.1 and the ray model (:func:`probslam.mapping.map_laser_log`,
    readings at the sensor's no-return value skipped). Returns (grid, occupied (H, W) bool: the
    log-odds above the prior, known (H, W) bool: decided by KNOWN_LOG_ODDS); a given grid is
    grown to fit and mapped into, else one is sized from the data."""
    from .mapping import map_laser_log

    grid = map_laser_log(scans, resolution=resolution, max_range=max_range, grid=grid, progress=False).grid
    l = np.asarray(grid.log_odds)
    return grid, l > grid.l0, np.abs(l - grid.l0) >= KNOWN_LOG_ODDS


def real_training_set(grid: OccupancyGrid2D, occupied: np.ndarray, known: np.ndarray, poses: np.ndarray,
                      ranges: np.ndarray, beam_angles: np.ndarray, max_range: float, half_angle: float,
                      no_return: float = math.inf) -> TrainingSet:
    """9.3.4, training from real data: for each scan (poses (S, 3) from a corrected log, ranges
    (S, B), NaN for a missing beam, beam_angles (B,)) the cells of its perceptual field
    (:func:`field_features`) that the known map decides, labelled with the known map's
    occupancy. Readings >= ``no_return`` and NaN mean no return (inf, then max_range in the
    inputs), as the forward model's max readings do in simulation."""
    require_instance(grid, OccupancyGrid2D, "grid")
    occupied, known = np.asarray(occupied), np.asarray(known)
    for name, a in (("occupied", occupied), ("known", known)):
        if a.dtype != bool or a.shape != tuple(grid.shape):
            raise ValueError(f"{name}: expected a bool array of the grid's shape {tuple(grid.shape)}, got "
                             f"{a.dtype} {a.shape}")
    poses = real_array(poses, "poses", (None, 3))
    beam_angles = _beam_angles(beam_angles)
    ranges = real_array(ranges, "ranges", (poses.shape[0], beam_angles.size), finite=False)
    inputs, labels = [], []
    for pose, z in zip(poses, ranges):
        z = np.where(np.isnan(z) | (z >= no_return), np.inf, z)
        cells, x = field_features(grid, pose, z, beam_angles, max_range, half_angle)
        keep = known.ravel()[cells]
        inputs.append(x[keep])
        labels.append(occupied.ravel()[cells[keep]])
    if not inputs:
        return TrainingSet(np.empty((0, 2 + NEIGHBOURS)), np.empty(0, dtype=bool))
    return TrainingSet(np.concatenate(inputs), np.concatenate(labels))


class LearnedInverseModel:
    """p(m_i = 1 | z, x) learned from samples (ch. 9.3): f(input, W) = sigmoid(v . tanh(A s(input)
    + a) + b) with s the inputs standardised by the training set's mean and deviation.
    Untrained until :meth:`train` or :meth:`load`."""

    def __init__(self, hidden: int = 16):
        hidden = require_integer(hidden, "hidden")
        if hidden < 1:
            raise ValueError("hidden must be >= 1")
        self.hidden = hidden
        self.weights: Optional[np.ndarray] = None
        self.mean = self.scale = None
        self.prior = None  # occupied fraction of the training cells: p(m_i) of the sampled maps
        self.final_objective = None  # J(W) / n at the end of training (nats per cell)
        # The factor on each scan's log-odds in Table 9.1 (1: the single-scan model as trained);
        # fit_evidence_scale chooses it on training worlds, so that many overlapping scans, added
        # as if independent, do not make the map overconfident (docs/occupancy_mapping.md).
        self.evidence_scale = 1.0
        # The grid's cell size and the readings' range (m) the model was trained at (None: not
        # recorded): map_laser_log_learned's defaults, since the field's features were learned on
        # that lattice and range (the bundled Intel model: 0.1 m, 10 m).
        self.resolution: Optional[float] = None
        self.max_range: Optional[float] = None

    # --- the network and J(W) (eq. 9.20) ---

    def _unpack(self, w: np.ndarray, d: int):
        h = self.hidden
        a_mat = w[:h * d].reshape(h, d)
        a = w[h * d:h * d + h]
        v = w[h * d + h:h * d + 2 * h]
        return a_mat, a, v, w[-1]

    def n_weights(self, d: int) -> int:
        """Number of network weights for d input features (one hidden layer, one output)."""
        return self.hidden * d + 2 * self.hidden + 1

    def _forward(self, w: np.ndarray, s: np.ndarray):
        a_mat, a, v, b = self._unpack(w, s.shape[1])
        hid = np.tanh(s @ a_mat.T + a)
        return hid, hid @ v + b  # hidden activations, output logit

    def objective(self, w: np.ndarray, s: np.ndarray, y: np.ndarray) -> Tuple[float, np.ndarray]:
        """J(W) of eq. 9.20 divided by the number of samples, and its gradient in W; s the
        standardised inputs (n, d), y (n,) in {0, 1}."""
        hid, u = self._forward(w, s)
        # -[y log f + (1 - y) log(1 - f)] with f = sigmoid(u), written stably via logaddexp.
        j = np.mean(np.logaddexp(0.0, u) - y * u)
        g_u = (1.0 / (1.0 + np.exp(-u)) - y) / len(y)  # dJ/du
        a_mat, a, v, b = self._unpack(w, s.shape[1])
        g_v = hid.T @ g_u
        g_pre = np.outer(g_u, v) * (1.0 - hid ** 2)  # through tanh
        g_amat = g_pre.T @ s
        g_a = g_pre.sum(axis=0)
        return float(j), np.concatenate([g_amat.ravel(), g_a, g_v, [g_u.sum()]])

    def train(self, data: TrainingSet, rng: np.random.Generator, max_iterations: int = 300) -> "LearnedInverseModel":
        """Minimises J(W) (eq. 9.20) over ``data`` with L-BFGS from small random weights.
        Returns self; on an error the model is left as it was.

        Errors: TypeError naming ``data`` (not a TrainingSet), ``rng`` (not a numpy Generator) or
        ``max_iterations`` (not an integer >= 1); ValueError for inputs that are not (n, d) finite
        numbers with one bool label each, or labels of one class only."""
        require_fields(data, ("inputs", "occupied"), "data", "a TrainingSet")
        require_instance(rng, np.random.Generator, "rng")
        max_iterations = require_integer(max_iterations, "max_iterations", 1)
        x = real_array(data.inputs, "inputs", (None, None))
        y = np.asarray(data.occupied)
        if x.shape[0] == 0 or x.shape[1] == 0 or y.shape != (x.shape[0],):
            raise ValueError(f"inputs must be (n, d) with one label each, got {x.shape} and {y.shape}")
        if y.dtype.kind not in "biuf":
            raise TypeError(f"occupied: expected bool labels, got dtype {y.dtype}")
        y = y.astype(float)
        if not np.all((y == 0) | (y == 1)):
            raise ValueError("occupied: expected bool labels (0 or 1)")
        if y.min() == y.max():
            raise ValueError("occupied must hold both classes")
        with np.errstate(over="ignore", invalid="ignore"):
            mean, scale = x.mean(axis=0), x.std(axis=0) + 1e-12
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(scale))):
            raise ValueError("inputs: too large to standardise (their mean or deviation overflows)")
        s = (x - mean) / scale
        w0 = rng.normal(0.0, 0.3, self.n_weights(s.shape[1]))
        # Imported here, as scipy.ndimage below: scipy.optimize is about 50 MB of the process and
        # 3-5 s of `import probslam` for every program, most of which never trains a model.
        from scipy.optimize import minimize

        res = minimize(self.objective, w0, args=(s, y), jac=True, method="L-BFGS-B",
                       options={"maxiter": max_iterations})
        if not (np.all(np.isfinite(res.x)) and np.isfinite(res.fun)):
            raise ValueError("inputs: training diverged (non-finite weights)")
        self.mean, self.scale, self.weights = mean, scale, res.x
        self.prior = float(y.mean())
        self.final_objective = float(res.fun)
        return self

    def _check_trained(self):
        if self.weights is None:
            raise RuntimeError("the model is untrained: call train() or load() first")

    def probability(self, inputs: np.ndarray) -> np.ndarray:
        """f(input, W) (n,) for inputs (n, 2 + NEIGHBOURS), clipped to [EPS, 1 - EPS]."""
        self._check_trained()
        x = np.asarray(inputs, dtype=float)
        if x.ndim != 2 or x.shape[1] != self.mean.shape[0]:
            raise ValueError(f"inputs must have shape (n, {self.mean.shape[0]}), got {x.shape}")
        _, u = self._forward(self.weights, (x - self.mean) / self.scale)
        return np.clip(1.0 / (1.0 + np.exp(-u)), EPS, 1.0 - EPS)

    def scan_evidence(self, grid: OccupancyGrid2D, pose, ranges, beam_angles, max_range: float,
                      half_angle: float) -> Tuple[np.ndarray, np.ndarray]:
        """The cells of one scan's perceptual field (:func:`field_features`) and the single-scan
        evidence logit(f) - logit(prior) of each (before evidence_scale): the term Table 9.1 adds
        for this model, the prior being the training maps' occupied fraction (what f returns
        where the scan tells nothing). Arguments are checked as by field_features."""
        self._check_trained()
        if self.mean.shape[0] != 2 + NEIGHBOURS:
            raise ValueError(f"insert_scan needs a model of {2 + NEIGHBOURS} inputs (field_features), this one "
                             f"has {self.mean.shape[0]}")
        cells, x = field_features(grid, pose, ranges, beam_angles, max_range, half_angle)
        if cells.size == 0:
            return cells, np.empty(0)
        return cells, logit(self.probability(x)) - logit(self.prior)

    def insert_scan(self, grid: OccupancyGrid2D, pose, ranges, beam_angles, max_range: float,
                    half_angle: float) -> int:
        """Table 9.1 lines 3-4 with this model as inverse_sensor_model: for each cell in the
        perceptual field, l += evidence_scale (logit(f) - logit(prior)) (:meth:`scan_evidence`).
        Updates the grid through ``add_log_odds`` (clamped, under the grid's lock). Returns the
        cells changed. Arguments are checked as by :func:`field_features`, before the grid is
        touched. Time and memory per scan: linear in the cells within max_range of the pose
        (each cell's nearest beam by a sorted search), in chunks (FIELD_CHUNK_PAIRS)."""
        cells, evidence = self.scan_evidence(grid, pose, ranges, beam_angles, max_range, half_angle)
        if cells.size == 0:
            return 0
        return grid.add_log_odds(cells, self.evidence_scale * evidence)

    def fit_evidence_scale(self, worlds: Sequence[tuple], grid: OccupancyGrid2D, beam_angles: np.ndarray,
                           max_range: float, half_angle: float, bounds: Tuple[float, float] = (0.0, 2.0)) -> float:
        """Chooses evidence_scale s to minimise the cross-entropy of the maps Table 9.1 makes
        from many scans: over ``worlds`` (as :func:`sample_scans` returns; training worlds, never
        the test ones), each cell's map log-odds is logit(prior) + s * (sum of its scans'
        evidence), scored against the truth over the cells some scan covers (and, when a world
        is given as (occupied, poses, ranges, known), that ``known`` marks). The cross-entropy
        is convex in s, so a bounded scalar search finds its minimum. Sets and returns s; on an
        error the model is left as it was."""
        self._check_trained()
        require_instance(grid, OccupancyGrid2D, "grid")
        lo, hi = (float(b) for b in bounds)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
            raise ValueError(f"bounds: expected 0 <= low < high, got {bounds}")
        totals, labels = [], []
        for world in worlds:
            occupied, poses, scans = world[:3]
            truth = np.asarray(occupied, dtype=bool).ravel()
            if truth.size != grid.shape[0] * grid.shape[1]:
                raise ValueError(f"worlds: a map of {truth.size} cells on a grid of shape {tuple(grid.shape)}")
            total, seen = np.zeros(truth.size), np.zeros(truth.size, dtype=bool)
            for pose, z in zip(poses, scans):
                cells, evidence = self.scan_evidence(grid, pose, z, beam_angles, max_range, half_angle)
                np.add.at(total, cells, evidence)
                seen[cells] = True
            if len(world) > 3:  # a mask of the cells the truth decides (a known map built from a log)
                seen &= np.asarray(world[3], dtype=bool).ravel()
            totals.append(total[seen])
            labels.append(truth[seen])
        total, truth = np.concatenate(totals), np.concatenate(labels)
        if total.size == 0:
            raise ValueError("worlds: no scan covers any cell")
        l0 = float(logit(self.prior))
        from scipy.optimize import minimize_scalar

        res = minimize_scalar(lambda k: map_cross_entropy(l0 + k * total, truth), bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-4})
        self.evidence_scale = float(res.x)
        return self.evidence_scale

    def save(self, path: str) -> None:
        """The weights and standardisation as a .npz file (numpy adds ``.npz`` to a str path
        without it): the float arrays ``weights``, ``mean`` and ``scale`` and the JSON text
        ``meta`` = {"hidden": int, "prior": float, "evidence_scale": float, and "resolution" and
        "max_range" (m) when set}, what :meth:`load` checks (files without evidence_scale, written
        before it existed, load with 1; without resolution or max_range, with None)."""
        self._check_trained()
        meta = {"hidden": self.hidden, "prior": self.prior, "evidence_scale": self.evidence_scale}
        for name in _TRAINED_AT:
            value = getattr(self, name)
            if value is not None:
                meta[name] = positive_real(value, name)
        np.savez(file_path(path), weights=self.weights, mean=self.mean, scale=self.scale, meta=json.dumps(meta))

    @classmethod
    def load(cls, path: str) -> "LearnedInverseModel":
        """A model written by :meth:`save`.

        Errors: TypeError for a path that is no path; FileNotFoundError for a missing file;
        ValueError("path: ...") for anything but a regular file, and for every file that is not
        what save writes: not a .npz archive (or larger than MAX_MODEL_BYTES), a missing or extra
        array, a wrong dtype or shape, non-finite weights or standardisation, a deviation <= 0,
        hidden not an integer >= 1, a prior outside (0, 1)."""
        path = file_path(path)
        require_regular_file(path)
        arrays = _read_model_arrays(path)
        hidden, prior, evidence_scale, trained_at = _model_meta(path, arrays.pop("meta"))
        m = cls(hidden)
        d = arrays["mean"].shape[0]
        if d == 0 or arrays["scale"].shape != (d,) or arrays["weights"].shape != (m.n_weights(d),):
            raise ValueError(f"{path}: weights do not match hidden = {hidden}: weights "
                             f"{arrays['weights'].shape}, mean {arrays['mean'].shape}, scale {arrays['scale'].shape}")
        for name, values in arrays.items():
            if not np.all(np.isfinite(values)):
                raise ValueError(f"{path}: {name} holds NaN or inf")
        if np.any(arrays["scale"] <= 0):
            raise ValueError(f"{path}: scale holds a deviation <= 0")
        m.weights, m.mean, m.scale, m.prior = arrays["weights"], arrays["mean"], arrays["scale"], prior
        m.evidence_scale = evidence_scale
        m.resolution, m.max_range = (trained_at.get(name) for name in _TRAINED_AT)
        return m


#: OccupancyGrid2D's default clamp (probabilities), and how far in log-odds its lower bound lies
#: below the 0.5 prior it is made for.
DEFAULT_CLAMP = (0.1192, 0.971)
CLAMP_BELOW_PRIOR = 2.0


def learned_map_clamp(prior: float) -> Tuple[float, float]:
    """The clamp of a map with a learned model's prior: OccupancyGrid2D's default, its lower
    bound moved to CLAMP_BELOW_PRIOR log-odds below the prior when the prior lies near or below
    it (a real laser's prior is ~0.09: the default's 0.119 would hold every free cell above the
    prior, more occupied than unknown)."""
    lower = 1.0 / (1.0 + math.exp(CLAMP_BELOW_PRIOR - math.log(prior / (1.0 - prior))))
    return min(DEFAULT_CLAMP[0], lower), DEFAULT_CLAMP[1]


def learned_map_geometry(model: LearnedInverseModel, resolution: Optional[float] = None,
                         max_range: Optional[float] = None) -> Tuple[float, float]:
    """(resolution, max_range) in metres for mapping with ``model``: each one given, else the
    model's own (what it was trained at: :attr:`LearnedInverseModel.resolution` / ``max_range``),
    else map_laser_log's (``probslam.mapping.DEFAULT_RESOLUTION`` / ``DEFAULT_MAX_RANGE``)."""
    from .mapping import DEFAULT_MAX_RANGE, DEFAULT_RESOLUTION

    resolution = resolution if resolution is not None else model.resolution or DEFAULT_RESOLUTION
    max_range = max_range if max_range is not None else model.max_range or DEFAULT_MAX_RANGE
    return positive_real(resolution, "resolution"), positive_real(max_range, "max_range")


def map_laser_log_learned(model: LearnedInverseModel, scans, resolution: Optional[float] = None,
                          max_range: Optional[float] = None, progress: Optional[bool] = None):
    """Table 9.1 over a laser log (:class:`probslam.io.LaserScans`, poses taken as true) with a
    learned inverse model (:meth:`LearnedInverseModel.insert_scan`), the counterpart of
    :func:`probslam.mapping.map_laser_log`, at ``resolution`` and ``max_range`` (m; None: the
    model's own, :func:`learned_map_geometry`): a grid sized from the data with the model's prior
    (clamped by :func:`learned_map_clamp`), readings at the sensor's no-return value and NaN
    meaning no return (inf), each scan's field half a beam spacing either side of its beams.
    Returns a :class:`probslam.mapping.MappingResult` (``.grid`` the map). Memory: the grid plus one scan's
    field in chunks (FIELD_CHUNK_PAIRS); time linear in the cells within max_range of each pose."""
    from tqdm import tqdm

    from .io.carmen import LaserScans
    from .mapping import MappingResult, scan_bounds

    model._check_trained()
    require_instance(scans, LaserScans, "scans")
    if len(scans) == 0:
        raise ValueError("scans must not be empty")
    resolution, max_range = learned_map_geometry(model, resolution, max_range)
    if not np.all(np.isfinite(scans.laser_poses)):
        raise ValueError("scans.laser_poses must contain only finite values")
    angles = scans.beam_angles()
    if not np.all(np.isfinite(angles)):
        raise ValueError("scans.start_angles and angular_resolutions must be finite")
    no_return = scans.no_return_range()
    grid = OccupancyGrid2D.covering(scan_bounds(scans, max_range), resolution, p_prior=model.prior,
                                    clamp=learned_map_clamp(model.prior))
    updated, seconds, beams = 0, 0.0, 0
    for i in tqdm(range(len(scans)), unit="scan", disable=(None if progress is None else not progress)):
        n = int(scans.num_beams[i])
        z = scans.ranges[i, :n]
        valid = np.isfinite(z) & (z >= 0) & (z < no_return)
        beams += int(valid.sum())
        t0 = time.perf_counter()
        updated += model.insert_scan(grid, scans.laser_poses[i], np.where(valid, z, np.inf), angles[i, :n], max_range,
                                     abs(float(scans.angular_resolutions[i])) / 2)
        seconds += time.perf_counter() - t0
    return MappingResult(grid, len(scans), beams, updated, seconds)


#: The largest model file :meth:`LearnedInverseModel.load` reads, and the most bytes one of its
#: arrays may decompress to: a model of d inputs and h hidden units holds (d + 2) h + 1 + 2 d
#: doubles, so 64 MiB leave room for ~8 million weights (the models here have a few hundred),
#: while a crafted header could otherwise make numpy allocate any shape it claims.
MAX_MODEL_BYTES = 64 << 20
#: The arrays save writes (each a ``NAME.npy`` member of the archive): dtype kind and dimensions.
_MODEL_ARRAYS = {"weights": ("f", 1), "mean": ("f", 1), "scale": ("f", 1), "meta": ("U", 0)}
#: What a damaged archive raises inside zipfile and its decompressors.
_ARCHIVE_ERRORS = (zipfile.BadZipFile, zlib.error, lzma.LZMAError, struct.error, EOFError, OSError,
                   NotImplementedError, RuntimeError, ValueError)


class _MalformedModel(ValueError):
    """A model file that is not what save writes (raised with the path and the reason)."""


def _read_model_arrays(path: str) -> dict:
    """The arrays of a model file, each checked against _MODEL_ARRAYS before it is read."""
    size = os.path.getsize(path)
    if size > MAX_MODEL_BYTES:
        raise ValueError(f"{path}: {size} bytes, larger than a model file (MAX_MODEL_BYTES = {MAX_MODEL_BYTES})")
    try:
        with zipfile.ZipFile(path) as archive:
            names, expected = sorted(archive.namelist()), sorted(f"{k}.npy" for k in _MODEL_ARRAYS)
            if names != expected:
                raise _MalformedModel(f"{path}: expected the arrays {expected}, got {names[:10]}")
            return {k: _read_model_array(path, archive, k) for k in _MODEL_ARRAYS}
    except _MalformedModel:
        raise
    except _ARCHIVE_ERRORS as exc:
        raise ValueError(f"{path}: not a model file ({type(exc).__name__}: {_first_line(exc)})") from None


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else "no detail"


def _read_model_array(path: str, archive: zipfile.ZipFile, name: str) -> np.ndarray:
    """One .npy member: its header checked (dtype kind, dimensions, data length) before numpy
    allocates the array it describes."""
    with archive.open(f"{name}.npy") as f:
        data = f.read(MAX_MODEL_BYTES + 1)
    if len(data) > MAX_MODEL_BYTES:
        raise _MalformedModel(f"{path}: {name} decompresses to more than MAX_MODEL_BYTES = {MAX_MODEL_BYTES}")
    buffer = io.BytesIO(data)
    try:
        version = np.lib.format.read_magic(buffer)
        if version not in ((1, 0), (2, 0)):
            raise ValueError(f".npy version {version}")
        read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read_header(buffer)
    except ValueError as exc:
        raise _MalformedModel(f"{path}: {name}: not a numpy array ({_first_line(exc)})") from None
    kind, ndim = _MODEL_ARRAYS[name]
    if dtype.kind != kind or len(shape) != ndim:
        raise _MalformedModel(f"{path}: {name}: expected a {ndim}-D array of dtype kind '{kind}', "
                              f"got {dtype} {shape}")
    if math.prod(shape) * dtype.itemsize != len(data) - buffer.tell():
        raise _MalformedModel(f"{path}: {name}: the data do not fill the shape {shape} (truncated or padded)")
    buffer.seek(0)
    values = np.lib.format.read_array(buffer, allow_pickle=False)
    return values if kind == "U" else values.astype(float)


#: The optional meta fields of a model file: the cell size and range (m) it was trained at.
_TRAINED_AT = ("resolution", "max_range")


def _model_meta(path: str, meta: np.ndarray) -> Tuple[int, float, float, dict]:
    """(hidden, prior, evidence_scale, {resolution, max_range: m, those present}) from a model
    file's meta text, checked (evidence_scale 1 when absent: files written before it existed)."""
    try:
        fields = json.loads(str(meta))
    except (ValueError, RecursionError) as exc:
        raise ValueError(f"{path}: meta: not JSON ({_first_line(exc)})") from None
    allowed = {"hidden", "prior", "evidence_scale", *_TRAINED_AT}
    if not isinstance(fields, dict) or not {"hidden", "prior"} <= set(fields) <= allowed:
        raise ValueError(f"{path}: meta: expected {{\"hidden\": ..., \"prior\": ..., \"evidence_scale\": ...}}, "
                         f"got {str(meta)[:80]!r}")
    trained_at = {name: fields[name] for name in _TRAINED_AT if name in fields}
    for name, value in trained_at.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
            raise ValueError(f"{path}: meta: {name} must be a finite length > 0 (m), got {value!r}")
    hidden, prior, scale = fields["hidden"], fields["prior"], fields.get("evidence_scale", 1.0)
    if isinstance(hidden, bool) or not isinstance(hidden, int) or hidden < 1:
        raise ValueError(f"{path}: meta: hidden must be an integer >= 1, got {hidden!r}")
    if isinstance(prior, bool) or not isinstance(prior, (int, float)) or not 0 < prior < 1:
        raise ValueError(f"{path}: meta: prior must lie in (0, 1), got {prior!r}")
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0 <= scale < math.inf:
        raise ValueError(f"{path}: meta: evidence_scale must be finite and >= 0, got {scale!r}")
    return hidden, float(prior), float(scale), {name: float(value) for name, value in trained_at.items()}


__all__ = [
    "CLAMP_BELOW_PRIOR",
    "DEFAULT_CLAMP",
    "EPS",
    "FIELD_CHUNK_PAIRS",
    "KNOWN_LOG_ODDS",
    "MAX_MODEL_BYTES",
    "NEIGHBOURS",
    "LearnedInverseModel",
    "TrainingSet",
    "WORLDS",
    "field_features",
    "free_poses",
    "known_map",
    "learned_map_clamp",
    "learned_map_geometry",
    "real_training_set",
    "map_cross_entropy",
    "map_laser_log_learned",
    "pillar_map",
    "random_map",
    "sample_scans",
    "sample_training_set",
]
