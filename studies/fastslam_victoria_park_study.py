"""Landmark FastSLAM on Victoria Park with hidden associations: versions x odometry noise scale x
negative information, over seeds. Per run: the best particle's landmark count (151 in the
dataset), the share of its sightings that went to their landmark's majority tree, its path RMSE
against the GraphSLAM optimum (chi2 6184.12, bench_fastslam.graphslam_optimum) and the CPU time.

    .venv/bin/python studies/fastslam_victoria_park_study.py [--jobs 2] [--seeds 0 1 2 3]

Needs ../shared/data/landmark_slam/victoria_park (skips with a message without it).
"""

import argparse
import concurrent.futures
import pathlib
import sys
import time

import numpy as np

import probslam as ps
from probslam import eval as ev
from probslam.datasets import victoria_park
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))  # common.py and the benchmarks reused here
import bench_fastslam as bf
from common import heading, report

# (label, options of datasets.victoria_park.run_fastslam)
CONFIGS = [
    ("v1, scale 3", dict(version=1, odometry_noise_scale=3.0)),
    ("v2, scale 3", dict(version=2, odometry_noise_scale=3.0)),
    ("v1, scale 5", dict(version=1, odometry_noise_scale=5.0)),
    ("v2, scale 5", dict(version=2, odometry_noise_scale=5.0)),
    ("v1, scale 7", dict(version=1, odometry_noise_scale=7.0)),
    ("v2, scale 7", dict(version=2, odometry_noise_scale=7.0)),
    ("v1, scale 10", dict(version=1, odometry_noise_scale=10.0)),
    ("v2, scale 10", dict(version=2, odometry_noise_scale=10.0)),
    ("v2, scale 5, negative information (20 m, 180 deg)",
     dict(version=2, odometry_noise_scale=5.0,
          filter_options=dict(negative_information=True, sensor_range=20.0, sensor_fov=np.pi))),
]
# Known associations, for reference: what the noise scale costs when association is not at stake.
KNOWN = [("known, v1, scale 3", dict(version=1, odometry_noise_scale=3.0)),
         ("known, v1, scale 7", dict(version=1, odometry_noise_scale=7.0)),
         ("known, v2, scale 7", dict(version=2, odometry_noise_scale=7.0))]

_cache = {}  # per worker process: the file and the GraphSLAM optimum, read and solved once


def run_one(job):
    label, options, seed = job
    if not _cache:
        _cache["data"] = ps.io.read_victoria_park(str(bf.VICTORIA_PARK))
        _cache["optimum"] = bf.graphslam_optimum(bf.VictoriaPark(str(bf.VICTORIA_PARK)))
    data, optimum = _cache["data"], _cache["optimum"]
    t0 = time.process_time()
    known = label.startswith("known")
    run = victoria_park.run_fastslam(data, known=known, seed=seed, **options)
    cpu = time.process_time() - t0
    return dict(label=label, seed=seed, landmarks=len(run.landmarks),
                correct=1.0 if known else ev.association_accuracy(run),
                rmse=bf.path_rmse(run.poses, optimum), cpu=cpu)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    args = parser.parse_args()
    if not bf.VICTORIA_PARK.exists():
        print(f"skipped: {bf.VICTORIA_PARK} not found")
        return 0
    jobs = [(label, options, seed) for label, options in CONFIGS + KNOWN for seed in args.seeds]
    with concurrent.futures.ProcessPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(run_one, jobs))
    lines = heading("Landmark FastSLAM, Victoria Park, hidden associations",
                    "100 particles, p_new 1e-3 (`probslam.datasets.victoria_park.run_fastslam`); odometry covariance "
                    "times scale^2; per cell the values of seeds " + " / ".join(map(str, args.seeds)) +
                    ". RMSE: best particle's path against the GraphSLAM optimum; correct: sightings whose landmark's "
                    f"majority tree is their own. `{' '.join(sys.argv)}`",
                    ["configuration", "landmarks (151)", "correct", "path RMSE (m)", "median path RMSE (m)", "CPU s"])
    for label, _ in CONFIGS + KNOWN:
        rs = [r for r in rows if r["label"] == label]
        landmarks = " / ".join(str(r["landmarks"]) for r in rs)
        correct = " / ".join(f"{r['correct']:.1%}" for r in rs)
        rmse = " / ".join(f"{r['rmse']:.1f}" for r in rs)
        lines.append(f"| {label} | {landmarks} | {correct} | {rmse} | {np.median([r['rmse'] for r in rs]):.1f} | "
                     f"{np.mean([r['cpu'] for r in rs]):.2f} |")
    report(lines, record=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
