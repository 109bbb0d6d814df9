"""Mapping speed of Table 9.1 with a learned inverse model (ch. 9.3, LearnedInverseModel.insert_scan
through inverse_learning.map_laser_log_learned) beside Table 9.2's insert_cone_scan and the ray
model's insert_rays (map_laser_log), on the whole Intel corrected log (910 scans x 180 beams),
0.1 m cells, readings used to 10 m. The learned model is a 16-unit network with fixed weights:
its cost does not depend on the weights' values. Peak memory of the learned mapping by tracemalloc
(in a second run: tracemalloc slows the first several times). Then the training time of each
sensor's model with the study's settings (studies/eval_inverse_models.py: 8 maps x 40 poses,
300 cells per scan, 16 hidden units; the evidence scale fitted on 3 maps x 60 scans).

    .venv/bin/python benchmarks/bench_inverse_mapping.py [--record] [--no-training]
"""

import argparse
import os
import pathlib
import sys
import time
import tracemalloc

import numpy as np

import probslam as ps
from probslam import inverse_learning as il
from probslam import io
from common import heading, report

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "studies"))
import eval_inverse_models as study  # noqa: E402  (its sensors and world size: the same training)

# ../shared/data beside the repository, or $PROBSLAM_SHARED_DATA (as the other benchmarks).
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"))
LOG = SHARED / "laser_2d" / "intel" / "intel-corrected.log.gz"
RES, MAX_RANGE = 0.1, 10.0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--record", action="store_true")
    parser.add_argument("--no-training", action="store_true", help="the mapping table only")
    args = parser.parse_args()
    if not LOG.exists():
        print(f"{LOG} absent: nothing to measure")
        return
    scans = io.read_carmen_log(str(LOG)).scans
    m = il.LearnedInverseModel(16)
    m.weights = np.linspace(-0.5, 0.5, m.n_weights(2 + il.NEIGHBOURS))
    m.mean, m.scale, m.prior = np.zeros(2 + il.NEIGHBOURS), np.ones(2 + il.NEIGHBOURS), 0.1
    rows = []
    t0 = time.perf_counter()
    grid = ps.map_laser_log(scans, resolution=RES, max_range=MAX_RANGE, progress=False).grid
    rows.append(("ray model (insert_rays, map_laser_log)", time.perf_counter() - t0, None))
    cone = ps.OccupancyGrid2D(RES, grid.width, grid.height, origin=grid.origin)
    no_return = scans.no_return_range()
    angles = scans.beam_angles()
    t0 = time.perf_counter()
    for pose, z, a, step in zip(scans.laser_poses, scans.ranges, angles, scans.angular_resolutions):
        cone.insert_cone_scan(pose, np.where(z >= no_return, np.inf, z), a, MAX_RANGE, RES, abs(step), 0.85, -0.85)
    rows.append(("Table 9.2 (insert_cone_scan)", time.perf_counter() - t0, None))
    t0 = time.perf_counter()
    il.map_laser_log_learned(m, scans, resolution=RES, max_range=MAX_RANGE, progress=False)
    seconds = time.perf_counter() - t0
    tracemalloc.start()  # a second run for the memory: tracemalloc slows numpy's allocations several times
    il.map_laser_log_learned(m, scans, resolution=RES, max_range=MAX_RANGE, progress=False)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    rows.append(("learned (insert_scan, 16 hidden units)", seconds, peak))
    lines = heading("Learned inverse model mapping vs Table 9.2, Intel corrected log",
                    f"One thread; {len(scans)} scans x 180 beams, {RES} m cells, readings to {MAX_RANGE} m "
                    f"(grid {grid.width} x {grid.height}). Peak memory: a second learned run under tracemalloc.",
                    ["implementation", "total (s)", "ms per scan", "scans/s", "peak Python memory (MB)"])
    for name, s, peak in rows:
        lines.append(f"| {name} | {s:.2f} | {1e3 * s / len(scans):.2f} | {len(scans) / s:.0f} | "
                     f"{'-' if peak is None else f'{peak / 2 ** 20:.0f}'} |")
    if not args.no_training:
        lines += [""] + training_table()
    report(lines + [""], args.record)


def training_table():
    """Seconds to sample the training set, train the network and fit the evidence scale, per
    sensor, with the study's settings and seed."""
    maps, poses, fit_maps, fit_poses = 8, 40, 3, 60
    grid = ps.OccupancyGrid2D(study.RES, study.SIZE, study.SIZE)
    lines = ["Training (studies/eval_inverse_models.py's settings: "
             f"{maps} maps x {poses} poses, 300 cells per scan, 16 hidden units; evidence scale on {fit_maps} maps x "
             f"{fit_poses} scans), one thread, seed 0:", "",
             "| sensor | training cells | sampling (s) | training (s) | final J (nats/cell) | scale fit (s) | scale |",
             "|---|---|---|---|---|---|---|"]
    for name, model, angles, half in study.sensors():
        rng = np.random.default_rng(0)
        t0 = time.perf_counter()
        data = il.sample_training_set(grid, model, angles, maps, poses, rng, cells_per_scan=300, half_angle=half)
        t1 = time.perf_counter()
        learned = il.LearnedInverseModel(16).train(data, rng)
        t2 = time.perf_counter()
        worlds = il.sample_scans(grid, model, angles, fit_maps, fit_poses, rng)
        scale = learned.fit_evidence_scale(worlds, grid, angles, model.max_range, half)
        t3 = time.perf_counter()
        lines.append(f"| {name} | {data.occupied.size} | {t1 - t0:.1f} | {t2 - t1:.1f} | "
                     f"{learned.final_objective:.4f} | {t3 - t2:.1f} | {scale:.3f} |")
        print(lines[-1], flush=True)
    return lines


if __name__ == "__main__":
    main()
