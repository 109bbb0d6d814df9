"""2-D occupancy grid benchmark: insert_rays and insert_cone_scan next to plain-Python and numpy
implementations of the same updates, in the same run. Prints a table; --record writes it
into benchmarks/RESULTS.md.

    .venv/bin/python benchmarks/bench_grid2d.py [--quick] [--record]
"""

import argparse
import os
import pathlib
import time

import numpy as np

import probslam as ps
from common import heading, report
from peers import numpy_cone, numpy_rays, python_rays

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
L_HIT, L_MISS = ps.logit(0.7), ps.logit(0.4)


def office_world(rng):
    """Wall segments (n, 4) of a 40 x 30 m floor with rooms, and pillars (m, 3) x y radius."""
    walls = [(-20, -15, 20, -15), (20, -15, 20, 15), (20, 15, -20, 15), (-20, 15, -20, -15)]
    for x in range(-16, 17, 4):  # rooms along both long sides, with doors
        walls += [(x, 15, x, 6), (x, -15, x, -6)]
    walls += [(-20, 6, -1, 6), (1, 6, 20, 6), (-20, -6, -3, -6), (-1, -6, 20, -6)]
    pillars = np.column_stack([rng.uniform(-18, 18, 12), rng.uniform(-4, 4, 12), rng.uniform(0.15, 0.4, 12)])
    return np.array(walls, float), pillars


def cast(pose, angles, walls, pillars, max_reading=81.83):
    """Range of every beam to the nearest wall or pillar (numpy, vectorised over beams)."""
    d = np.column_stack([np.cos(pose[2] + angles), np.sin(pose[2] + angles)])
    best = np.full(len(angles), max_reading)
    p = np.array(pose[:2])
    for x1, y1, x2, y2 in walls:
        e = np.array([x2 - x1, y2 - y1])
        denom = d[:, 0] * e[1] - d[:, 1] * e[0]
        w = np.array([x1, y1]) - p
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[0] * e[1] - w[1] * e[0]) / denom
            u = (w[0] * d[:, 1] - w[1] * d[:, 0]) / denom
        ok = (t > 0) & (u >= 0) & (u <= 1)
        best = np.where(ok & (t < best), t, best)
    for cx, cy, rad in pillars:
        c = np.array([cx, cy]) - p
        b = d @ c
        disc = b * b - (c @ c - rad * rad)
        t = b - np.sqrt(np.maximum(disc, 0))
        best = np.where((disc > 0) & (t > 0) & (t < best), t, best)
    return best


def synthetic_scans(n_scans, rng):
    walls, pillars = office_world(rng)
    angles = np.linspace(-3 * np.pi / 4, 3 * np.pi / 4, 1081)  # 270 degrees, 0.25 degree steps
    s = np.linspace(0, 2 * np.pi, n_scans, endpoint=False)
    poses = np.column_stack([17 * np.cos(s), 2.5 * np.sin(2 * s), s + np.pi / 2])
    ranges = np.array([cast(p, angles, walls, pillars) for p in poses])
    ranges += rng.normal(0, 0.01, ranges.shape)
    return poses, ranges, angles


def timed(fn, repeat=1):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def ray_cells(poses, ranges, angles, max_range, origin, res):
    """Cells the exact walk visits: |dkx| + |dky| per valid ray (origin's cell in, end's out)."""
    ok = np.isfinite(ranges) & (ranges >= 0)
    length = np.minimum(np.where(ok, ranges, 0.0), max_range)
    a = poses[:, 2:3] + angles
    k = lambda v, o: np.floor((v - o) / res)
    dx = np.abs(k(poses[:, :1] + length * np.cos(a), origin[0]) - k(poses[:, :1], origin[0]))
    dy = np.abs(k(poses[:, 1:2] + length * np.sin(a), origin[1]) - k(poses[:, 1:2], origin[1]))
    return float(((dx + dy) * ok).sum())


def rays_rows(name, poses, ranges, angles, max_range, res, bounds, python_scans):
    grid = ps.OccupancyGrid2D.covering(bounds, res)
    x0, y0 = grid.origin
    beams = np.count_nonzero(np.isfinite(ranges))
    steps = ray_cells(poses, ranges, angles, max_range, grid.origin, res)
    t_ours, changed = timed(lambda: grid.insert_scans(poses, ranges, angles, max_range), repeat=3)
    rows = [(name, "probslam insert_rays", beams / t_ours, steps / t_ours, changed / t_ours, 1.0)]
    lo = np.zeros(grid.shape)
    k = python_scans
    t_np, n_np = timed(lambda: sum(numpy_rays(lo, x0, y0, res, p, r, angles, max_range, L_HIT, L_MISS)
                                   for p, r in zip(poses[:k * 4], ranges[:k * 4])))
    b_np = np.count_nonzero(np.isfinite(ranges[:k * 4]))
    s_np = ray_cells(poses[:k * 4], ranges[:k * 4], angles, max_range, grid.origin, res)
    rows.append((name, "numpy (sampled rays)", b_np / t_np, s_np / t_np, n_np / t_np, (beams / t_ours) / (b_np / t_np)))
    t_py, n_py = timed(lambda: sum(python_rays(lo, x0, y0, res, p, r, angles, max_range, L_HIT, L_MISS)
                                   for p, r in zip(poses[:k], ranges[:k])))
    b_py = np.count_nonzero(np.isfinite(ranges[:k]))
    s_py = ray_cells(poses[:k], ranges[:k], angles, max_range, grid.origin, res)
    rows.append((name, "plain Python DDA", b_py / t_py, s_py / t_py, n_py / t_py, (beams / t_ours) / (b_py / t_py)))
    return rows


def cone_rows(poses, ranges, angles, z_max, res, bounds):
    params = dict(z_max=z_max, alpha=0.1, beta=np.radians(0.5), l_occ=0.85, l_free=-0.4)
    disc = np.pi * (z_max / res) ** 2
    grid = ps.OccupancyGrid2D.covering(bounds, res)
    t_ours, _ = timed(lambda: [grid.insert_cone_scan(p, r, angles, **params) for p, r in zip(poses, ranges)], 3)
    lo = np.zeros(grid.shape)
    x0, y0 = grid.origin
    t_np, _ = timed(lambda: [numpy_cone(lo, x0, y0, res, p, r, angles, **params) for p, r in zip(poses, ranges)])
    n = len(poses)
    return [("synthetic 1081 beams, z_max 20 m", "probslam insert_cone_scan", n * disc / t_ours, n / t_ours, 1.0),
            ("synthetic 1081 beams, z_max 20 m", "numpy Table 9.2 (searchsorted)", n * disc / t_np, n / t_np,
             t_np / t_ours)]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="fewer scans (for a smoke run)")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    n = 20 if args.quick else 200
    poses, ranges, angles = synthetic_scans(n, rng)
    res, max_range = 0.05, 20.0
    bounds = (-21, -16, 21, 16)
    ray_rows = rays_rows("synthetic 1081 beams, 270 deg, 20 m", poses, ranges, angles, max_range, res, bounds,
                         python_scans=2)
    log_path = SHARED / "laser_2d/intel/intel-corrected.log.gz"
    if log_path.exists():
        log = ps.io.read_carmen_log(log_path)
        s = log.scans
        r = np.where(s.ranges >= s.no_return_range(), np.nan, s.ranges)
        b = ps.mapping.scan_bounds(ps.io.LaserScans(**{**s.__dict__, "ranges": r}), 30.0)
        ray_rows += rays_rows("Intel corrected log (910 x 180 beams)", s.laser_poses, r, s.beam_angles()[0], 30.0,
                              res, b, python_scans=20)
    cone = cone_rows(poses[: max(4, n // 10)], ranges[: max(4, n // 10)], angles, 20.0, res, bounds)

    lines = heading("2-D grid updates", "One thread.", ["workload", "implementation", "M beams/s", "M ray cells/s",
                                                         "M cells changed/s", "probslam speed-up"])
    lines += [f"| {w} | {impl} | {b / 1e6:.3f} | {st / 1e6:.1f} | {c / 1e6:.1f} | {ratio:.0f}x |"
              for w, impl, b, st, c, ratio in ray_rows]
    lines += ["", "| workload | implementation | M disc cells/s | scans/s | probslam speed-up |", "|---|---|---|---|---|"]
    lines += [f"| {w} | {impl} | {c / 1e6:.1f} | {s:.1f} | {ratio:.1f}x |" for w, impl, c, s, ratio in cone]
    lines += ["", "Ray cells: cells the exact walks visit, |dkx| + |dky| per beam (an update each, de-duplicated per scan);",
              "Disc cells: the pi (z_max / res)^2 cells of the perceptual field a Table 9.1 loop must consider;",
              "cells changed: cells whose log-odds a scan updated (each at most once per scan for insert_rays).", ""]
    report(lines, record=args.record and not args.quick)


if __name__ == "__main__":
    main()
