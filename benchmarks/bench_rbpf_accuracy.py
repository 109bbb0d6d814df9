"""Grid-based FastSLAM accuracy on ACES: the relations error (Kuemmerle et al. 2009) of the whole
log for each proposal (scan-matching, improved-odometry, motion) and several particle counts,
over several seeds, next to GraphSLAM (run_slam's default method) on the same log.

A particle filter's result depends on its random stream, so each cell is given for every seed
(mean +- std of the relation errors, m) and the seeds' mean. Runs go in parallel processes
(--jobs): this table is about accuracy; bench_rbpf.py measures time on one core.

    .venv/bin/python benchmarks/bench_rbpf_accuracy.py [--jobs 2] [--seeds 0 1] [--record]
"""

import argparse
import concurrent.futures
import os
import pathlib
import sys

import numpy as np

import probslam as ps
import probslam.eval
import probslam.slam
from common import heading, report

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
ACES = SHARED / "laser_2d" / "aces" / "aces.clf.bz2"
RELATIONS = SHARED / "laser_2d" / "aces" / "aces.relations"
#: (label, options, particle counts): the motion model needs far more particles to have a chance.
RUNS = [("scan-matching", dict(proposal="scan-matching"), (10, 30)),
        ("scan-matching, climb from the raw odometry only", dict(proposal="scan-matching", corrected_start=False),
         (30,)),
        ("improved-odometry", dict(proposal="improved-odometry"), (10, 30)),
        ("motion", dict(proposal="motion"), (30, 100))]


def relations_error(method, fields):
    """(mean, std) of the ACES relation errors for one run_slam call: the log's default options
    for method with these fields replaced."""
    scans = ps.io.read_carmen_log(ACES).scans
    options = ps.slam.default_options(scans, method).replace(**fields)
    result = ps.slam.run_slam(scans, progress=False, options=options)
    e = ps.eval.relations_error(result.timestamps, result.poses, ps.eval.relations_on_logger_time(RELATIONS, scans))
    return e.trans_mean, e.trans_std


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--jobs", type=int, default=2, help="parallel processes (default 2)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="random seeds (default 0 1)")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    args = parser.parse_args()
    if not (ACES.exists() and RELATIONS.exists()):
        print(f"bench_rbpf_accuracy: {ACES} or {RELATIONS} not found; nothing to run")
        return
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    jobs = {("graph", 0, 0): ("graph", {})}
    for label, options, counts in RUNS:
        for m in counts:
            for seed in args.seeds:
                jobs[(label, m, seed)] = ("rbpf", dict(num_particles=m, seed=seed, **options))
    with concurrent.futures.ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = {key: pool.submit(relations_error, *job) for key, job in jobs.items()}
        results = {}
        for key, fut in futures.items():
            results[key] = fut.result()
            print(f"bench_rbpf_accuracy: {key}: {results[key][0]:.4f} m", file=sys.stderr, flush=True)
    columns = ["method", "particles"] + [f"seed {s}" for s in args.seeds] + ["mean over seeds"]
    lines = heading("Grid-based FastSLAM accuracy on ACES", "Relations error of the whole log (1279 relations), "
                    "mean +- std over the relations, m; default options except those named.", columns)
    g = results[("graph", 0, 0)]
    lines.append(f"| GraphSLAM (method='graph') | - | {g[0]:.3f} +- {g[1]:.3f} |" + " |" * len(args.seeds))
    for label, _, counts in RUNS:
        for m in counts:
            cells = [results[(label, m, s)] for s in args.seeds]
            lines.append(f"| rbpf, {label} | {m} | " + " | ".join(f"{a:.3f} +- {b:.3f}" for a, b in cells) +
                         f" | {np.mean([a for a, _ in cells]):.3f} |")
    lines += ["", "Published: GMapping-style RBPF, 50 particles, 0.060 m (Kuemmerle et al. 2009).",
              f"Command: `python benchmarks/bench_rbpf_accuracy.py --jobs {args.jobs} --seeds "
              f"{' '.join(map(str, args.seeds))}`.", ""]
    report(lines, record=args.record)


if __name__ == "__main__":
    main()
