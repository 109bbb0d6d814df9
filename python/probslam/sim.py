"""A landmark world, a robot driving velocity controls, and a range-bearing sensor with range
and field-of-view limits, Gaussian noise, optional clutter and signatures. Reproducible by seed.

Units: metres, radians, seconds. Noise matrices are covariances (variances on the diagonal).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional

import numpy as np

from ._core import velocity_motion, wrap_angle
from ._args import real_array, require_instance

CLUTTER_ID = -1  # id of a false detection


@dataclass
class LandmarkWorld:
    """Point landmarks (N, 2) m with a signature (N,) each."""

    landmarks: np.ndarray  # (N, 2) metres
    signatures: np.ndarray  # (N,)

    @classmethod
    def random(cls, n: int, extent: float, rng: np.random.Generator, min_separation: float = 0.0) -> "LandmarkWorld":
        """n landmarks uniform in [-extent, extent]^2, at least min_separation apart."""
        points: List[np.ndarray] = []
        while len(points) < n:
            p = rng.uniform(-extent, extent, 2)
            if all(np.hypot(*(p - q)) >= min_separation for q in points):
                points.append(p)
        return cls(np.array(points), np.arange(n, dtype=float))


@dataclass
class Sensor:
    """A range-bearing sensor: noise (2, 2) of (range m, bearing rad) or (3, 3) with the
    signature, max_range m, fov rad (full opening angle), optional clutter."""

    measurement_noise: np.ndarray  # (2, 2) or (3, 3) with the signature's variance
    max_range: float = 10.0
    fov: float = 2 * np.pi  # full opening angle
    clutter_rate: float = 0.0  # expected false detections per scan (Poisson)
    signatures: bool = False


@dataclass
class SimRun:
    """One simulated run: true poses, commanded controls, dt s, and the measurements."""

    poses: np.ndarray  # (T + 1, 3) true poses
    controls: np.ndarray  # (T, 2) commanded (v, w)
    dt: float
    measurements: List[np.ndarray] = field(default_factory=list)  # per step (k, 2 or 3), after the motion
    ids: List[np.ndarray] = field(default_factory=list)  # per step (k,), CLUTTER_ID for clutter


def circle_controls(steps: int, v: float = 1.0, w: float = 0.2) -> np.ndarray:
    """(steps, 2) constant (v, w): a circle of radius v / w."""
    return np.tile([v, w], (steps, 1)).astype(float)


def observe(pose: np.ndarray, world: LandmarkWorld, sensor: Sensor, rng: np.random.Generator):
    """Noisy measurements (k, 2/3) and ids (k,) of the landmarks in range and field of view."""
    pose = real_array(pose, "pose", (3,))
    require_instance(world, LandmarkWorld, "world")
    require_instance(sensor, Sensor, "sensor")
    require_instance(rng, np.random.Generator, "rng")
    d = world.landmarks - pose[:2]
    r = np.hypot(d[:, 0], d[:, 1])
    phi = wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - pose[2])
    seen = (r <= sensor.max_range) & (np.abs(phi) <= sensor.fov / 2) & (r > 0)
    cols = [r[seen], phi[seen]] + ([world.signatures[seen]] if sensor.signatures else [])
    z = np.column_stack(cols) if seen.any() else np.empty((0, len(cols)))
    q = np.asarray(sensor.measurement_noise, float)
    z = z + rng.multivariate_normal(np.zeros(q.shape[0]), q, size=len(z)) if len(z) else z
    ids = np.flatnonzero(seen)
    n_clutter = rng.poisson(sensor.clutter_rate) if sensor.clutter_rate > 0 else 0
    if n_clutter:
        fake = [rng.uniform(0, sensor.max_range, n_clutter), rng.uniform(-sensor.fov / 2, sensor.fov / 2, n_clutter)]
        if sensor.signatures:
            fake.append(rng.uniform(world.signatures.min(), world.signatures.max() + 1, n_clutter))
        z = np.vstack([z, np.column_stack(fake)])
        ids = np.concatenate([ids, np.full(n_clutter, CLUTTER_ID)])
    if len(z):
        z[:, 0] = np.abs(z[:, 0])
        z[:, 1] = wrap_angle(z[:, 1])
    order = rng.permutation(len(z))
    return z[order], ids[order]


def simulate(world: LandmarkWorld, controls: np.ndarray, dt: float, sensor: Sensor, motion_noise: np.ndarray,
             rng: np.random.Generator, initial_pose=(0.0, 0.0, 0.0)) -> SimRun:
    """Drive the commanded controls (T, 2). ``motion_noise`` is (2, 2) control-space (the robot
    executes v + e_v, w + e_w) or (3, 3) pose-space (added to the noise-free motion)."""
    controls = np.asarray(controls, float)
    m = np.asarray(motion_noise, float)
    poses = [np.asarray(initial_pose, float)]
    run = SimRun(np.empty((0, 3)), controls, dt)
    for v, w in controls:
        x = poses[-1]
        if m.shape == (2, 2):
            ev, ew = rng.multivariate_normal(np.zeros(2), m)
            nxt = velocity_motion(x, v + ev, w + ew, dt)
        else:
            nxt = velocity_motion(x, v, w, dt) + rng.multivariate_normal(np.zeros(3), m)
            nxt[2] = wrap_angle(nxt[2])
        poses.append(nxt)
        z, ids = observe(nxt, world, sensor, rng)
        run.measurements.append(z)
        run.ids.append(ids)
    run.poses = np.array(poses)
    return run


def pose_error(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """estimate - truth with the heading difference wrapped, (..., 3)."""
    estimate, truth = np.asarray(estimate), np.asarray(truth)
    for name, a in (("estimate", estimate), ("truth", truth)):
        if a.dtype.kind not in "iuf":
            raise TypeError(f"{name}: expected real numbers, got dtype {a.dtype}")
        if a.ndim == 0 or a.shape[-1] != 3:
            raise ValueError(f"{name}: expected shape (..., 3), got {a.shape}")
    e = np.asarray(estimate, float) - np.asarray(truth, float)
    e[..., 2] = wrap_angle(e[..., 2])
    return e


def filter_known(run: SimRun, motion_noise: np.ndarray, measurement_noise: np.ndarray):
    """EKF SLAM with known correspondences over a simulated run (without signatures), started at
    its true initial pose with zero covariance. Returns the pose NEES after each step (T,) and
    each step's finite NIS values (a list of T arrays, empty where nothing was updated)."""
    require_instance(run, SimRun, "run")
    from .ekf import EkfSlam

    ekf = EkfSlam(motion_noise, measurement_noise, use_signatures=False, initial_pose=run.poses[0])
    nees, nis = np.zeros(len(run.controls)), []
    for t, ((v, w), z, ids) in enumerate(zip(run.controls, run.measurements, run.ids)):
        ekf.predict(v, w, run.dt)
        r = ekf.update(z, ids) if len(z) else None
        nis.append(r.nis[np.isfinite(r.nis)] if r is not None else np.empty(0))
        e = pose_error(ekf.pose, run.poses[t + 1])
        nees[t] = e @ np.linalg.pinv(ekf.covariance[:3, :3]) @ e
    return nees, nis


def fastslam_known(run: SimRun, motion_noise: np.ndarray, measurement_noise: np.ndarray, num_particles: int,
                   version: int = 1, seed: int = 0, threads: int = 1):
    """FastSLAM (``probslam.FastSlam``, version 1 or 2) with known correspondences over a simulated
    run without signatures or clutter, started at its true initial pose (every particle there).

    Returns, after each step (predict, then the scan's update and any resampling), T steps:
    poses (T, 3): the particles' weighted mean (heading by circular mean, ``FastSlam.mean_pose``);
    covariances (T, 3, 3): their weighted covariance about it (``pose_covariance``; singular when
    the particles collapse onto fewer than three distinct poses); n_eff (T,): the effective sample
    size. The pose NEES is ``probslam.eval.nees(pose_error(poses, run.poses[1:]), covariances)``."""
    require_instance(run, SimRun, "run")
    from ._core import FastSlam

    f = FastSlam(motion_noise, measurement_noise, initial_pose=run.poses[0], num_particles=num_particles,
                 version=version, seed=seed, threads=threads, record_path=False)
    steps = len(run.controls)
    poses, covariances, n_eff = np.zeros((steps, 3)), np.zeros((steps, 3, 3)), np.zeros(steps)
    for t, ((v, w), z, ids) in enumerate(zip(run.controls, run.measurements, run.ids)):
        f.predict(v, w, run.dt)
        if len(z):
            f.update(z, ids)
        poses[t], covariances[t], n_eff[t] = f.mean_pose, f.pose_covariance, f.effective_sample_size
    return poses, covariances, n_eff


def cast_ranges(pose: np.ndarray, angles: np.ndarray, segments) -> np.ndarray:
    """A simulated laser scan: the range (metres) from ``pose`` (x, y, theta) along each beam
    ``angles`` (B,) radians relative to the heading to the nearest of ``segments`` (an iterable
    of ((x0, y0), (x1, y1)) walls, metres), inf where a beam meets none. Vectorised over beams."""
    pose = real_array(pose, "pose", (3,))
    angles = real_array(angles, "angles", (None,))
    d = np.stack([np.cos(pose[2] + angles), np.sin(pose[2] + angles)], axis=1)  # (B, 2)
    out = np.full(len(angles), np.inf)
    for p, q in segments:
        p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
        e = q - p
        det = d[:, 1] * e[0] - d[:, 0] * e[1]  # beam x wall; 0 when parallel
        ok = np.abs(det) > _PARALLEL
        w = p - pose[:2]
        safe = np.where(ok, det, 1.0)
        t = (w[1] * e[0] - w[0] * e[1]) / safe  # along the beam
        u = (d[:, 0] * w[1] - d[:, 1] * w[0]) / safe  # along the wall, 0..1 inside it
        hit = ok & (t > 0) & (u >= 0) & (u <= 1)
        out = np.where(hit, np.minimum(out, t), out)
    return out


#: |sin| of the angle between a beam and a wall below which they count as parallel (no hit).
_PARALLEL = 1e-12



@dataclass
class OpenDoorScenario:
    """The book's open-door example (Figs. 9.7, 9.8): a robot drives along a corridor past an open
    door with a ring of noise-free sonars. Units: metres, radians.

    ``grid``: an empty OccupancyGrid2D giving the lattice (and the prior ``p_prior``);
    ``truth`` (H, W) bool: the true map; ``door`` (H, W) bool: the cells of the door opening
    (free in ``truth``); ``poses`` (T, 3); ``beam_angles`` (B,); ``scans`` (T, B): each sonar's
    range, the distance to the nearest occupied cell centre in its cone (``model.max_range``
    where there is none); ``model``: the sonar's forward model (ch. 6.3), used to make the
    readings (its expected range) and by Table 9.3 (with the prior ``grid.p_prior``);
    ``alpha``, ``l_occ``, ``l_free``, ``standard_prior``: the inverse model of Table 9.2 and the
    prior of the standard algorithm (Table 9.1), whose cells at the prior are "unknown"."""

    grid: "OccupancyGrid2D"
    truth: np.ndarray
    door: np.ndarray
    poses: np.ndarray
    beam_angles: np.ndarray
    scans: np.ndarray
    model: "BeamSensorModel"
    alpha: float
    l_occ: float
    l_free: float
    standard_prior: float

    def standard_map(self) -> "OccupancyGrid2D":
        """Table 9.1 with the cone model of Table 9.2 (the textbook update, no clamping)."""
        from ._core import OccupancyGrid2D

        g = self.grid
        out = OccupancyGrid2D(g.resolution, g.width, g.height, g.origin, p_prior=self.standard_prior, clamp=None)
        for pose, ranges in zip(self.poses, self.scans):
            out.insert_cone_scan(pose, ranges, self.beam_angles, self.model.max_range, self.alpha,
                                 self.model.beta, self.l_occ, self.l_free)
        return out


def open_door_scenario(resolution: float = 0.1, corridor_width: float = 2.0, door_width: float = 0.6,
                       sonars: int = 24, beta: float = np.radians(60.0), max_range: float = 5.0,
                       step: float = 0.1, p_prior: float = 0.3) -> OpenDoorScenario:
    """The open-door scenario of Figs. 9.7/9.8 on a grid of ``resolution`` m cells (10 m x 6 m):
    a corridor ``corridor_width`` m wide (walls one cell thick) with a door ``door_width`` m wide
    in its upper wall, opening on a 4 m x 2.4 m room; the robot drives along the corridor's
    centre line from x = 1 to x = 9 m every ``step`` m, heading +x, with a ring of ``sonars``
    sonars of cone opening ``beta`` rad and range ``max_range`` m. Readings are noise-free:
    each is the forward model's expected range on the true map. ``p_prior``: the prior of Table
    9.3 (eq. 9.24); the standard algorithm uses 0.5, l_occ = logit(0.7), l_free = logit(0.3) and
    alpha = one cell."""
    from ._core import BeamSensorModel, BinaryMap2D, OccupancyGrid2D

    width, height = int(round(10.0 / resolution)), int(round(6.0 / resolution))
    grid = OccupancyGrid2D(resolution, width, height, p_prior=p_prior, clamp=None)
    truth = np.zeros((height, width), dtype=bool)
    row = lambda y: int(np.floor(y / resolution + 1e-9))  # noqa: E731 - the row holding height y
    col = lambda x: int(np.floor(x / resolution + 1e-9))  # noqa: E731
    y_low = 1.0
    y_high = y_low + corridor_width + resolution  # the upper wall's row starts here
    truth[row(y_low), :] = True
    truth[row(y_high), :] = True
    door_x0 = 5.0 - door_width / 2
    door = np.zeros_like(truth)
    door[row(y_high), col(door_x0):col(door_x0 + door_width)] = True
    truth[door] = False
    # The room beyond the door: side walls at x = 3 and 7 m, back wall 2.4 m above the corridor.
    room_top = row(y_high) + int(round(2.4 / resolution))
    truth[room_top, col(3.0):col(7.0) + 1] = True
    truth[row(y_high):room_top, col(3.0)] = True
    truth[row(y_high):room_top, col(7.0)] = True

    model = BeamSensorModel("sonar", max_range, beta=beta, z_hit=0.85, z_short=0.05, z_max=0.05, z_rand=0.05,
                            sigma_hit=resolution / 2, lambda_short=1.0)
    truth_map = BinaryMap2D(grid, truth)
    y_mid = (row(y_low) + 1 + row(y_high)) * resolution / 2
    xs = np.arange(1.0, 9.0 + step / 2, step)
    poses = np.column_stack([xs, np.full_like(xs, y_mid), np.zeros_like(xs)])
    angles = np.array([wrap_angle(a) for a in np.arange(sonars) * 2 * np.pi / sonars])
    scans = np.stack([model.expected_ranges(p, angles, truth_map) for p in poses])
    return OpenDoorScenario(grid=grid, truth=truth, door=door, poses=poses, beam_angles=angles, scans=scans,
                            model=model, alpha=resolution, l_occ=float(np.log(0.7 / 0.3)),
                            l_free=float(np.log(0.3 / 0.7)), standard_prior=0.5)


__all__ = [
    "CLUTTER_ID",
    "LandmarkWorld",
    "OpenDoorScenario",
    "Sensor",
    "SimRun",
    "cast_ranges",
    "circle_controls",
    "fastslam_known",
    "filter_known",
    "observe",
    "open_door_scenario",
    "pose_error",
    "simulate",
]
