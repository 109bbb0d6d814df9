"""Laser robots in simulated worlds: line-segment maps of several kinds (offices, corridors, open
halls, repeated look-alike shapes), a loop driven through each, range sensors as data (SICK,
Hokuyo, LDS, RPLidar, Stage-like), odometry of four kinds (none, perfect, good, poor) with slip,
and the exact ground truth; reproducible by seed. Writes CARMEN logs, ROS 1 / ROS 2 bags and the
truth as TUM, so that tests and benchmarks run a matrix of robots x worlds x odometry.

Units: metres, radians, seconds. Poses ``(x, y, theta)``; the laser sits at the robot pose.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple, Union

import numpy as np

from ._args import require_instance
from . import geometry
from ._core import wrap_angle
from .io.carmen import ODOMETRY_NOISE_PARAM, LaserScans

PathLike = Union[str, "os.PathLike[str]"]

#: Readings are reported in millimetres, as the drivers and CARMEN logs do (a float32 LaserScan
#: holds a mm value exactly after ``rosbag.widen_float32``). Rounded as k / 1000 (k an integer),
#: the nearest double to the decimal a log prints, so that it reads back bit for bit.
RANGE_DECIMALS = 3

#: Parallel rays and segments (|cross| below this, in m^2 of the unit direction times the
#: segment length) never meet: a ray along a wall does not see it.
PARALLEL_EPS = 1e-12

#: Rays x segments evaluated at once by ``cast_rays`` (bounds its memory to ~10 arrays of this).
CAST_CHUNK = 1 << 21

#: The least noise (m and rad per step) an odometry states (``OdometryModel.stated_noise``): the
#: truth as odometry states none, and the frontend's prior needs a spread. 0.1 mm and 0.1 mrad lie
#: far below a matched step's error (the Stage-like robot in the office: 5 mm ATE with it, 9 mm
#: with 1 mm / 1 mrad) and far above rounding; the chain of them along a 10 m submap (200 steps:
#: 1.4 mm) keeps the graph's consecutive edges within 1e4 of a loop closure's information.
STATED_NOISE_FLOOR = 1e-4


@dataclass(frozen=True)
class LaserSensor:
    """A 2D laser scanner as its data sheet and driver describe it.

    fov rad (full opening; 2 pi for a spinning lidar), beams, max_range / range_min m,
    sigma_abs m and sigma_rel (fraction of the range) of its Gaussian range noise (the larger
    applies), no_return the value its driver reports when a beam sees nothing within range
    (max_range, 0.0 or inf), rate Hz of its scans.
    """

    name: str
    fov: float
    beams: int
    max_range: float
    range_min: float
    sigma_abs: float
    sigma_rel: float
    no_return: float
    rate: float = 10.0

    @property
    def step(self) -> float:
        """The angle between beams: a full circle has ``beams`` steps, a sector ``beams - 1``."""
        return self.fov / self.beams if self.fov >= 2 * math.pi - 1e-9 else self.fov / (self.beams - 1)

    @property
    def start(self) -> float:
        """The first beam's bearing (the scan is centred on the heading)."""
        return -self.fov / 2 if self.fov < 2 * math.pi - 1e-9 else -math.pi

    def angles(self) -> np.ndarray:
        """(beams,) the beams' bearings relative to the laser heading."""
        return self.start + self.step * np.arange(self.beams)


def _deg(d: float) -> float:
    return math.radians(d)


#: The sensors of issue 51, from their data sheets and drivers. SICK LMS 2xx: 1 deg, 80 m,
#: ~1 cm noise, the max range for no return (as CARMEN logs). Hokuyo UTM-30LX: 0.25 deg,
#: 30 m, +-30 mm, 0.1 m minimum, inf for no return (REP 117). ROBOTIS LDS-01 (TurtleBot 3):
#: 1 deg, 3.5 m, +-5 % beyond 0.5 m, 0.12 m minimum, 0 for no return (its driver). RPLidar A2:
#: 1 deg here, 12 m, 1 % of range, 0.15 m minimum, inf (rplidar_ros turns 0 into inf). Stage:
#: 270 deg / 90 beams / 5 m, a small noise, the max range for no return (stage_ros).
SENSORS: Dict[str, LaserSensor] = {
    "sick": LaserSensor("sick", _deg(180), 181, 80.0, 0.0, 0.01, 0.0, 80.0, 10.0),
    "hokuyo": LaserSensor("hokuyo", _deg(270), 1081, 30.0, 0.1, 0.015, 0.0, math.inf, 10.0),
    "lds": LaserSensor("lds", _deg(360), 360, 3.5, 0.12, 0.015, 0.025, 0.0, 5.0),
    "rplidar": LaserSensor("rplidar", _deg(360), 360, 12.0, 0.15, 0.005, 0.005, math.inf, 10.0),
    "stage": LaserSensor("stage", _deg(270), 90, 5.0, 0.0, 0.005, 0.0, 5.0, 10.0),
}


@dataclass(frozen=True)
class OdometryModel:
    """Wheel odometry as a systematic and a random error per step.

    scale: the reported distance over the true one minus 1 (0.03: 3 % too long); drift rad of
    heading error per metre driven; sigma_dist (fraction of the step's distance) and
    sigma_turn (rad per sqrt(m) driven plus the same fraction of the step's turn) of the
    random error; slip_rate: the chance per step that the wheels slip, reporting up to
    slip_max more distance than was driven (and a heading error of slip_max rad per metre).
    """

    scale: float = 0.0
    drift: float = 0.0
    sigma_dist: float = 0.0
    sigma_turn: float = 0.0
    slip_rate: float = 0.0
    slip_max: float = 0.0

    def stated_noise(self) -> Tuple[float, float, float, float, float, float]:
        """The noise this odometry states, in the frontend's terms (``OdometryNoise``: sd_xy =
        trans_per_metre d + trans_per_radian a + trans_floor, sd_theta = rot_per_radian a +
        rot_per_metre d + rot_floor, per step of d metres and a radians), what a log or bag
        written from it says of its odometry (``LaserScans.odometry_noise``).

        Per step: the distance's error is the scale plus the random sigma_dist and the slips'
        (a slip of U(0, slip_max) with chance slip_rate: sd sqrt(slip_rate slip_max^2 / 3)), per
        metre; the heading's is the drift plus the slips' per metre and sigma_turn (sqrt(d) +
        a), with sqrt(d) bounded by the linear d + 1/4 (the frontend's model is linear in d).
        Floors: what the model leaves at zero motion, at least ``STATED_NOISE_FLOOR``."""
        slip = math.sqrt(self.slip_rate * self.slip_max ** 2 / 3.0)
        trans = self.scale + math.hypot(self.sigma_dist, slip)
        return (trans, 0.0, STATED_NOISE_FLOOR, self.sigma_turn, self.drift + slip + self.sigma_turn,
                max(STATED_NOISE_FLOOR, self.sigma_turn / 4.0))


#: The odometry kinds: none (the log has no odometry), perfect (the truth), good (a well
#: calibrated robot: 0.5 % scale, 0.2 deg/m drift), poor (3 % scale, 1.5 deg/m drift, issue 51).
ODOMETRY: Dict[str, Optional[OdometryModel]] = {
    "none": None,
    "perfect": OdometryModel(),
    "good": OdometryModel(scale=0.005, drift=_deg(0.2), sigma_dist=0.01, sigma_turn=_deg(0.5), slip_rate=0.005,
                          slip_max=0.2),
    "poor": OdometryModel(scale=0.03, drift=_deg(1.5), sigma_dist=0.03, sigma_turn=_deg(1.5), slip_rate=0.02,
                          slip_max=0.5),
}


@dataclass
class World:
    """A map of walls: segments (N, 4) ``x1 y1 x2 y2`` m, and the loop driven in it
    (waypoints (K, 2), the first repeated at the end); kind names the generator."""

    kind: str
    segments: np.ndarray
    waypoints: np.ndarray


def _box(x0: float, y0: float, x1: float, y1: float) -> List[Tuple[float, float, float, float]]:
    return [(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)]


def _wall(a: Tuple[float, float], b: Tuple[float, float], doors: List[float], width: float):
    """A straight wall from a to b with door gaps of ``width`` centred at the fractions ``doors``."""
    a_, b_ = np.asarray(a, float), np.asarray(b, float)
    length = float(np.hypot(*(b_ - a_)))
    cuts = [0.0]
    for f in sorted(doors):
        cuts += [f * length - width / 2, f * length + width / 2]
    cuts.append(length)
    u = (b_ - a_) / length
    out = []
    for s, e in zip(cuts[0::2], cuts[1::2]):
        if e - s > 1e-6:
            p, q = a_ + u * s, a_ + u * e
            out.append((p[0], p[1], q[0], q[1]))
    return out


def _rectangle_loop(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """Waypoints around a rectangle, counter-clockwise, back to the start."""
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]])


def _office(rng: np.random.Generator) -> World:
    """A 24 x 16 m floor: rooms on both sides of a ring corridor around a central block of rooms,
    doors placed by the seed, a box of furniture in some rooms."""
    W, H, c = 24.0, 16.0, 2.0  # floor, corridor width
    segs = _box(0, 0, W, H)
    inner = (5.0, 5.0, W - 5.0, H - 5.0)  # the central block; the corridor runs around it
    # The corridor's outer side at 3 m from the walls: rooms between it and the outer walls.
    o = (inner[0] - c, inner[1] - c, inner[2] + c, inner[3] + c)
    for (a, b) in (((o[0], o[1]), (o[2], o[1])), ((o[2], o[1]), (o[2], o[3])), ((o[2], o[3]), (o[0], o[3])),
                   ((o[0], o[3]), (o[0], o[1]))):
        n = int(rng.integers(2, 4))
        segs += _wall(a, b, list(rng.uniform(0.15, 0.85, n)), 0.9)
    for (a, b) in (((inner[0], inner[1]), (inner[2], inner[1])), ((inner[2], inner[1]), (inner[2], inner[3])),
                   ((inner[2], inner[3]), (inner[0], inner[3])), ((inner[0], inner[3]), (inner[0], inner[1]))):
        segs += _wall(a, b, [float(rng.uniform(0.2, 0.8))], 0.9)
    # Room partitions: from the outer corridor wall to the outer walls, and across the block.
    for x in np.sort(rng.uniform(o[0] + 1.5, o[2] - 1.5, 3)):
        segs += [(x, 0, x, o[1]), (x, o[3], x, H)]
    for y in np.sort(rng.uniform(o[1] + 1.5, o[3] - 1.5, 1)):
        segs += [(0, y, o[0], y), (o[2], y, W, y)]
    mid = float(rng.uniform(inner[0] + 3, inner[2] - 3))
    segs += [(mid, inner[1], mid, inner[3])]
    for _ in range(4):  # furniture in the outer rooms
        x, y = rng.uniform(0.5, W - 1.5), float(rng.choice([rng.uniform(0.4, 1.2), rng.uniform(H - 2.0, H - 1.2)]))
        w, h = rng.uniform(0.5, 1.0, 2)
        segs += _box(x, y, x + w, y + h)
    cx0, cy0, cx1, cy1 = inner[0] - c / 2, inner[1] - c / 2, inner[2] + c / 2, inner[3] + c / 2
    return World("office", np.array(segs, float), _rectangle_loop(cx0, cy0, cx1, cy1))


def _corridors(rng: np.random.Generator) -> World:
    """A ring of long, 2 m wide corridors (40 x 12 m) with few features: door recesses spaced by the seed."""
    L, H, c = 40.0, 12.0, 2.0
    segs = []
    for (a, b) in (((0, 0), (L, 0)), ((L, 0), (L, H)), ((L, H), (0, H)), ((0, H), (0, 0))):
        n = int(rng.integers(1, 3))
        segs += _wall(a, b, list(rng.uniform(0.2, 0.8, n)), 1.0)
    # Alcoves 0.4 m deep behind the door gaps keep the ring a corridor.
    segs = _close_gaps(segs, 0.4) + _box(c, c, L - c, H - c)
    cx0, cy0, cx1, cy1 = c / 2, c / 2, L - c / 2, H - c / 2
    return World("corridor", np.array(segs, float), _rectangle_loop(cx0, cy0, cx1, cy1))


def _close_gaps(segs, depth: float):
    """Closes every gap between consecutive collinear pieces of the outer walls with an alcove
    ``depth`` deep behind the wall (outward: away from the world's centre)."""
    a = np.array(segs, float)
    centre = np.array([(a[:, 0].min() + a[:, 0].max()) / 2, (a[:, 1].min() + a[:, 1].max()) / 2])
    out = list(segs)
    for s, t in zip(segs[:-1], segs[1:]):
        p, q = np.array(s[2:]), np.array(t[:2])
        gap = float(np.hypot(*(q - p)))
        if 1e-6 < gap < 3.0:
            d = (q - p) / gap
            n = np.array([-d[1], d[0]])
            if np.dot(n, p - centre) < 0:
                n = -n
            p2, q2 = p + n * depth, q + n * depth
            out += [(p[0], p[1], p2[0], p2[1]), (p2[0], p2[1], q2[0], q2[1]), (q2[0], q2[1], q[0], q[1])]
    return out


def _hall(rng: np.random.Generator) -> World:
    """An open 30 x 30 m hall with five 0.5 m pillars placed by the seed: few features."""
    S = 30.0
    segs = _box(0, 0, S, S)
    r = 9.0
    k = np.arange(9) * (2 * np.pi / 8)
    wp = np.c_[S / 2 + r * np.cos(k), S / 2 + r * np.sin(k)]
    wp[-1] = wp[0]
    pillars = 0
    while pillars < 5:  # pillars at least 2 m from the path circle (1 m from the octagon driven)
        x, y = rng.uniform(5, S - 5, 2)
        if abs(np.hypot(x + 0.25 - S / 2, y + 0.25 - S / 2) - r) > 2.0:
            segs += _box(x, y, x + 0.5, y + 0.5)
            pillars += 1
    return World("hall", np.array(segs, float), wp)


def _repeated(rng: np.random.Generator) -> World:
    """An 18 x 17 m room holding a 3 x 3 array of identical 2 x 2 m boxes (look-alike places),
    each shifted a few centimetres by the seed."""
    segs = _box(0, 0, 18, 17)
    xs, ys = [3.0, 8.0, 13.0], [2.5, 7.5, 12.5]
    for x in xs:
        for y in ys:
            dx, dy = rng.uniform(-0.05, 0.05, 2)
            segs += _box(x + dx, y + dy, x + dx + 2, y + dy + 2)
    # A loop through the lanes between the boxes: around the outside, then through the middle.
    wp = np.array([[1.5, 1.2], [16.5, 1.2], [16.5, 6.0], [6.5, 6.0], [6.5, 11.0], [16.5, 11.0], [16.5, 15.8],
                   [1.5, 15.8], [1.5, 1.2]])
    return World("repeated", np.array(segs, float), wp)


#: The world kinds of ``make_world``.
WORLDS = {"office": _office, "corridor": _corridors, "hall": _hall, "repeated": _repeated}


def make_world(kind: str, seed: int = 0) -> World:
    """A world of the kind ("office", "corridor", "hall", "repeated"), laid out by the seed."""
    if kind not in WORLDS:
        raise ValueError(f"kind must be one of {tuple(WORLDS)}, got {kind!r}")
    return WORLDS[kind](np.random.default_rng(seed))


def drive_loop(waypoints: np.ndarray, dt: float, speed: float = 0.5, turn_rate: float = 0.6) -> np.ndarray:
    """The poses (T, 3) every dt s of a differential-drive robot that drives the waypoints'
    polyline: it turns on the spot towards the next waypoint at ``turn_rate`` rad/s, then drives
    straight at ``speed`` m/s; it starts at the first waypoint facing the second, and ends where
    it started (the waypoints form a loop)."""
    wp = np.asarray(waypoints, float)
    heading = math.atan2(wp[1, 1] - wp[0, 1], wp[1, 0] - wp[0, 0])
    out = [np.array([wp[0, 0], wp[0, 1], heading])]
    for p, q in zip(wp[:-1], wp[1:]):
        target = math.atan2(q[1] - p[1], q[0] - p[0])
        turn = math.remainder(target - heading, 2 * math.pi)
        n = int(math.ceil(abs(turn) / (turn_rate * dt)))
        for k in range(1, n + 1):
            out.append(np.array([p[0], p[1], heading + turn * k / n]))
        heading = target
        length = float(np.hypot(*(q - p)))
        n = max(1, int(math.ceil(length / (speed * dt))))
        for k in range(1, n + 1):
            xy = p + (q - p) * (k / n)
            out.append(np.array([xy[0], xy[1], heading]))
    poses = np.array(out)
    poses[:, 2] = wrap_angle(poses[:, 2])
    return poses


def simulate_odometry(truth: np.ndarray, model: Optional[OdometryModel], rng: np.random.Generator) -> np.ndarray:
    """Odometry poses (T, 3) for the true poses (T, 3), starting at the true start: each step's
    motion with the model's scale, drift, random error and slips (None: all zero, no odometry)."""
    if model is None:
        return np.zeros_like(truth)
    steps = geometry.steps(truth)
    dist = np.hypot(steps[:, 0], steps[:, 1])
    n = len(steps)
    factor = 1.0 + model.scale + model.sigma_dist * rng.standard_normal(n)
    turn = (steps[:, 2] + model.drift * dist
            + model.sigma_turn * (np.sqrt(dist) + np.abs(steps[:, 2])) * rng.standard_normal(n))
    slips = rng.random(n) < model.slip_rate
    slip = np.where(slips, rng.uniform(0.0, model.slip_max, n), 0.0)
    factor = factor + slip
    turn = turn + slip * dist * rng.choice([-1.0, 1.0], n)
    return geometry.accumulate(truth[0], np.column_stack([steps[:, 0] * factor, steps[:, 1] * factor, turn]))


def cast_rays(segments: np.ndarray, origins: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Distances (R,) from origins (R, 2) along the world angles (R,) to the nearest of the
    segments (N, 4) ``x1 y1 x2 y2``; inf where a ray meets none. Vectorised over rays x
    segments in chunks of ``CAST_CHUNK`` pairs."""
    seg = np.asarray(segments, float).reshape(-1, 4)
    o = np.asarray(origins, float).reshape(-1, 2)
    a = np.asarray(angles, float).reshape(-1)
    p, e = seg[:, :2], seg[:, 2:] - seg[:, :2]
    out = np.full(len(o), np.inf)
    rows = max(1, CAST_CHUNK // max(1, len(seg)))
    for s in range(0, len(o), rows):
        oo, aa = o[s:s + rows], a[s:s + rows]
        dx, dy = np.cos(aa)[:, None], np.sin(aa)[:, None]
        den = dx * e[None, :, 1] - dy * e[None, :, 0]  # cross(d, e)
        wx, wy = p[None, :, 0] - oo[:, 0:1], p[None, :, 1] - oo[:, 1:2]  # p - o
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (wx * e[None, :, 1] - wy * e[None, :, 0]) / den  # cross(p - o, e) / den
            u = (wx * dy - wy * dx) / den  # cross(p - o, d) / den
            hit = (np.abs(den) > PARALLEL_EPS) & (t > 0) & (u >= 0) & (u <= 1)
        out[s:s + rows] = np.where(hit, t, np.inf).min(axis=1)
    return out


@dataclass
class LaserRun:
    """One simulated log.

    timestamps (S,) s; truth (S, 3) the exact poses; odometry (S, 3) what the wheel odometry
    says (all zero for kind "none"); ranges (S, B) as the sensor's driver reports them (its
    no-return value where a beam sees nothing); sensor, world, odometry_kind, seed.
    """

    timestamps: np.ndarray
    truth: np.ndarray
    odometry: np.ndarray
    ranges: np.ndarray
    sensor: LaserSensor
    world: World
    odometry_kind: str
    seed: int

    @property
    def stated_noise(self) -> Optional[Tuple[float, ...]]:
        """The noise the odometry states (``OdometryModel.stated_noise``); None without odometry."""
        model = ODOMETRY[self.odometry_kind]
        return None if model is None else model.stated_noise()

    @property
    def no_return(self) -> np.ndarray:
        """(S, B) which beams saw nothing within range."""
        v = self.sensor.no_return
        return np.isinf(self.ranges) if math.isinf(v) else self.ranges == v

    def scans(self, convention: str = "carmen") -> LaserScans:
        """The log as ``LaserScans``: convention "carmen" holds the no-return as max_range (what a
        CARMEN log, and ``read_rosbag``, give), "driver" the driver's value as written to a bag."""
        if convention not in ("carmen", "driver"):
            raise ValueError(f"convention must be 'carmen' or 'driver', got {convention!r}")
        r = self.ranges.copy()
        if convention == "carmen":
            r[self.no_return] = self.sensor.max_range
        s, sensor = len(r), self.sensor
        return LaserScans(ranges=r, laser_poses=self.odometry.copy(), robot_poses=self.odometry.copy(),
                          start_angles=np.full(s, sensor.start), angular_resolutions=np.full(s, sensor.step),
                          max_ranges=np.full(s, sensor.max_range), num_beams=np.full(s, sensor.beams),
                          timestamps=self.timestamps.copy(),
                          odometry_noise=None if self.stated_noise is None else np.tile(self.stated_noise, (s, 1)))


def simulate(world: Union[str, World], sensor: Union[str, LaserSensor], odometry: str = "good", seed: int = 0,
             speed: float = 0.5, start_time: float = 1000.0) -> LaserRun:
    """One log: the robot drives the world's loop at ``speed`` m/s, scanning at the sensor's rate.

    world: a ``World`` or a kind for ``make_world(kind, seed)``; sensor: a ``LaserSensor`` or a
    key of ``SENSORS``; odometry: a key of ``ODOMETRY``. Readings: the true distance plus the
    sensor's Gaussian noise, rounded to mm; beyond max_range or below range_min, the no-return
    value. The same arguments give the same log."""
    if isinstance(world, str):
        world = make_world(world, seed)
    require_instance(world, World, "world")
    if isinstance(sensor, str):
        if sensor not in SENSORS:
            raise ValueError(f"sensor must be one of {tuple(SENSORS)} or a LaserSensor, got {sensor!r}")
        sensor = SENSORS[sensor]
    require_instance(sensor, LaserSensor, "sensor")
    if odometry not in ODOMETRY:
        raise ValueError(f"odometry must be one of {tuple(ODOMETRY)}, got {odometry!r}")
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be finite and > 0, got {speed!r}")
    rng = np.random.default_rng([seed, 51])
    dt = 1.0 / sensor.rate
    truth = drive_loop(world.waypoints, dt, speed)
    odo = simulate_odometry(truth, ODOMETRY[odometry], rng)
    angles = truth[:, 2:3] + sensor.angles()[None, :]
    origins = np.repeat(truth[:, :2], sensor.beams, axis=0)
    d = cast_rays(world.segments, origins, angles.ravel()).reshape(angles.shape)
    sigma = np.maximum(sensor.sigma_abs, sensor.sigma_rel * np.where(np.isfinite(d), d, 0.0))
    with np.errstate(invalid="ignore"):
        scale = 10.0 ** RANGE_DECIMALS
        r = np.round((d + sigma * rng.standard_normal(d.shape)) * scale) / scale
        none = ~np.isfinite(d) | (r >= sensor.max_range) | (r < max(sensor.range_min, 1 / scale))
    r[none] = sensor.no_return
    times = start_time + dt * np.arange(len(truth))
    return LaserRun(times, truth, odo, r, sensor, world, odometry, seed)


def write_carmen(run: LaserRun, path: PathLike) -> None:
    """The log as CARMEN text (``read_carmen_log`` reads it): ``ROBOTLASER1`` lines (start angle,
    field of view, step and max range of the sensor; ranges in mm, the no-return as max range as
    CARMEN logs hold it; the odometry as laser and robot pose), preceded by an ``ODOM`` line at
    each scan's stamp, none for odometry kind "none" (whose poses are all zero); the odometry's
    stated noise as ``PARAM probslam_odometry_noise`` (``read_carmen_log`` reads it back)."""
    from .io._files import file_path

    require_instance(run, LaserRun, "run")
    path = file_path(path)
    sc, s = run.scans("carmen"), run.sensor
    head = f"ROBOTLASER1 0 {s.start:.9f} {s.fov:.9f} {s.step:.12f} {s.max_range:.3f} 0.01 0 {s.beams}"
    with open(path, "w", encoding="ascii") as f:
        f.write(f"# probslam.sim_laser: world {run.world.kind}, sensor {s.name}, odometry {run.odometry_kind}, "
                f"seed {run.seed}\n")
        if run.stated_noise is not None:
            f.write(f"PARAM {ODOMETRY_NOISE_PARAM} {','.join(repr(float(v)) for v in run.stated_noise)}\n")
        for i in range(len(sc)):
            x, y, th = sc.laser_poses[i]
            t = sc.timestamps[i]
            pose = f"{x:.6f} {y:.6f} {th:.6f}"
            if run.odometry_kind != "none":
                f.write(f"ODOM {pose} 0 0 0 {t:.6f} sim {t:.6f}\n")
            ranges = " ".join(f"{v:.{RANGE_DECIMALS}f}" for v in sc.ranges[i])
            f.write(f"{head} {ranges} 0 {pose} {pose} 0 0 0 0 0 {t:.6f} sim {t:.6f}\n")


def write_bag(run: LaserRun, path: PathLike, format: str = "rosbag1") -> None:
    """The log as a ROS bag (``io.write_rosbag``'s formats): LaserScan messages with the ranges as
    the driver reports them (its no-return value, its range_min), the odometry on ``/odom``
    (none for kind "none")."""
    from .io.rosbag_writer import write_rosbag

    require_instance(run, LaserRun, "run")
    write_rosbag(run.scans("driver"), path, format=format, range_min=run.sensor.range_min,
                 odometry="none" if run.odometry_kind == "none" else "odometry")


def write_truth(run: LaserRun, path: PathLike) -> None:
    """The exact poses as a TUM trajectory file (``io.read_trajectory`` reads it)."""
    from .io.trajectory import write_trajectory

    require_instance(run, LaserRun, "run")
    write_trajectory(run.timestamps, run.truth, path, format="tum")


__all__ = ["LaserRun", "LaserSensor", "ODOMETRY", "OdometryModel", "SENSORS", "STATED_NOISE_FLOOR", "WORLDS", "World",
           "cast_rays", "drive_loop", "make_world", "simulate", "simulate_odometry", "write_bag",
           "write_carmen", "write_truth"]
