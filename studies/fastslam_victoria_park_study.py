"""Landmark FastSLAM on Victoria Park with hidden associations: versions x odometry noise scale x
negative information, over seeds. Per run: the best particle's landmark count (151 in the
dataset), the share of its sightings that went to their landmark's majority tree, its path RMSE
against the GraphSLAM optimum (chi2 6184.12, bench_fastslam.graphslam_optimum) and the CPU time.

    .venv/bin/python studies/fastslam_victoria_park_study.py [--jobs 2] [--seeds 0 1 2 3]
    .venv/bin/python studies/fastslam_victoria_park_study.py --figure [--jobs 2]

--figure draws docs/fastslam_victoria_park.png instead: the seeds' spread (seeds 0-9) of the
defaults (version 1 and 2, hidden associations, scale 7) and of the file's own noise (scale 1,
known associations), beside the issue's 5 m median and 10 m bounds.

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

# The figure's runs: (label, hidden associations?, options of datasets.victoria_park.run_fastslam).
FIGURE_CONFIGS = [("hidden, version 1, scale 7 (default)", True, dict(version=1, odometry_noise_scale=7.0)),
                  ("hidden, version 2, scale 7", True, dict(version=2, odometry_noise_scale=7.0)),
                  ("known, version 1, file noise", False, dict(version=1, odometry_noise_scale=1.0)),
                  ("known, version 2, file noise", False, dict(version=2, odometry_noise_scale=1.0))]
FIGURE_SEEDS = range(10)
FIGURE = pathlib.Path(__file__).resolve().parents[1] / "docs" / "fastslam_victoria_park.png"

_cache = {}  # per worker process: the file and the GraphSLAM optimum, read and solved once


def shared():
    """(the file, the GraphSLAM optimum's poses), read and solved once per worker process."""
    if not _cache:
        _cache["data"] = ps.io.read_victoria_park(str(bf.VICTORIA_PARK))
        _cache["optimum"] = bf.graphslam_optimum(bf.VictoriaPark(str(bf.VICTORIA_PARK)))
    return _cache["data"], _cache["optimum"]


def run_one(job):
    label, options, seed = job
    data, optimum = shared()
    t0 = time.process_time()
    known = label.startswith("known")
    run = victoria_park.run_fastslam(data, known=known, seed=seed, **options)
    cpu = time.process_time() - t0
    return dict(label=label, seed=seed, landmarks=len(run.landmarks),
                correct=1.0 if known else ev.association_accuracy(run),
                rmse=bf.path_rmse(run.poses, optimum), cpu=cpu)


def figure_run(job):
    """One run of the figure: (label, seed, best particle's path, its RMSE against the optimum)."""
    label, hidden, options, seed = job
    data, optimum = shared()
    run = victoria_park.run_fastslam(data, known=not hidden, seed=seed, **options)
    return label, seed, run.poses[:, :2], bf.path_rmse(run.poses, optimum)


def draw_figure(jobs: int) -> None:
    """docs/fastslam_victoria_park.png: left, the default's best paths of seeds 0-9 over the
    GraphSLAM optimum; right, every configuration's path RMSE per seed."""
    from probslam.plot import require_matplotlib

    plt = require_matplotlib()
    work = [(label, hidden, options, seed) for label, hidden, options in FIGURE_CONFIGS for seed in FIGURE_SEEDS]
    with concurrent.futures.ProcessPoolExecutor(max_workers=jobs) as pool:
        runs = list(pool.map(figure_run, work))
    optimum = shared()[1]
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw=dict(width_ratios=[1.1, 1]))
    for label, seed, path, _ in runs:
        if label == FIGURE_CONFIGS[0][0]:
            left.plot(path[:, 0], path[:, 1], lw=0.6, alpha=0.8, label=f"seed {seed}")
    left.plot(optimum[:, 0], optimum[:, 1], "k", lw=1.2, label="GraphSLAM optimum")
    left.set_title("hidden associations, version 1, scale 7: best paths")
    left.set_aspect("equal")
    left.set_xlabel("x [m]")
    left.set_ylabel("y [m]")
    left.legend(fontsize="x-small", ncol=2, loc="best")
    for k, (label, _, _) in enumerate(FIGURE_CONFIGS):
        rmse = np.array([r for lab, _, _, r in runs if lab == label])
        right.plot(np.full(len(rmse), k) + np.linspace(-0.15, 0.15, len(rmse)), rmse, "o", ms=5,
                   label=f"{label}: median {np.median(rmse):.1f} m")
    right.axhline(5.0, color="tab:green", ls="--", lw=1, label="issue: median under 5 m")
    right.axhline(10.0, color="tab:red", ls=":", lw=1, label="issue: none over 10 m")
    right.set_yscale("log")
    right.set_xticks(range(len(FIGURE_CONFIGS)))
    right.set_xticklabels([label.replace(", ", "\n", 1) for label, _, _ in FIGURE_CONFIGS], fontsize="small")
    right.set_ylabel("best path's RMSE against the optimum [m]")
    right.set_title(f"path RMSE, seeds {FIGURE_SEEDS.start}-{FIGURE_SEEDS.stop - 1}, 100 particles")
    right.legend(fontsize="x-small", loc="upper left")
    fig.suptitle("Landmark FastSLAM on Victoria Park (probslam.datasets.victoria_park.run_fastslam)")
    fig.tight_layout()
    fig.savefig(FIGURE, dpi=110)
    print(f"wrote {FIGURE}")
    for label, _, _ in FIGURE_CONFIGS:
        print(label, " ".join(f"{r:.1f}" for lab, _, _, r in runs if lab == label))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--figure", action="store_true", help=f"draw {FIGURE.name} (seeds 0-9) instead of the table")
    args = parser.parse_args()
    if not bf.VICTORIA_PARK.exists():
        print(f"skipped: {bf.VICTORIA_PARK} not found")
        return 0
    if args.figure:
        draw_figure(args.jobs)
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
