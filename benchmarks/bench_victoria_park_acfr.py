"""The original Victoria Park run (ACFR: 1,549 s of encoder speed and steering at 40 Hz, 52,974
tree detections without identities, GPS) as the SLAM lecture measured it: EKF SLAM and FastSLAM
1.0 / 2.0 with 100 particles, the defaults of ``datasets.victoria_park_acfr_run``, each FastSLAM
variant over seeds 0-9; RMS against the GPS (as it is and SE(2)-aligned, evo's convention),
landmarks in the map and CPU seconds of the filter. The runs are a sweep
(benchmarks/sweeps/victoria_park_acfr.toml's, built here for --seeds and --refine) made by
``probslam.batch`` on a local Dask cluster; this script formats its table and, with --record,
writes it into benchmarks/RESULTS.md.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_victoria_park_acfr.py [DIR] [--seeds N] [--refine] [-o OUT] [--record]

--refine adds GraphSLAM's refinement of each run (``refine = "graphslam"``, docs/landmark_refine.md)
beside it: its RMS against the GPS (aligned), landmarks and CPU seconds (the refined run's, less its
filter's). -o OUT keeps the sweep's table and trajectories there (a run already there is not made
again; docs/make_victoria_park_acfr_figure.py draws them).
"""

import argparse
import datetime
import os
import pathlib
import tempfile

import numpy as np

import probslam as ps
from common import commit, machine, report
from probslam import batch
from probslam.datasets import victoria_park_acfr, victoria_park_acfr_run

DEFAULT = pathlib.Path(__file__).resolve().parents[2] / "shared/data/landmark_slam/victoria_park_acfr"
GPS = "gps.dat"


def sweep(folder: str, seeds: int, refine: bool) -> batch.Sweep:
    """The EKF once and FastSLAM 1.0 / 2.0 over ``seeds`` seeds, each filter alone (and refined)."""
    refine_values = ["none", "graphslam"] if refine else ["none"]
    reference = os.path.join(folder, GPS)
    return batch.Sweep([
        batch.RunGroup("ekf-slam", [folder], {"refine": refine_values}, reference=reference),
        batch.RunGroup("fastslam", [folder], {"version": [1, 2], "refine": refine_values}, seeds=list(range(seeds)),
                       reference=reference)])


def _failed(rows) -> str:
    bad = [r for r in rows if r["status"] != "ok"]
    return "; ".join(f"{r['kind']} {r.get('options.version', '')} seed {r['seed']}: {r['error']}" for r in bad)


def table(rows, refine: bool):
    """The RESULTS.md rows (one per filter run, its refinement beside it) and the summary lines."""
    key = lambda r: (r["kind"], r.get("options.version"), r["seed"])  # noqa: E731
    refined = {key(r): r for r in rows if r.get("options.refine") == "graphslam"}
    lines, summary = [], []
    for name, kind, version in (("EKF SLAM (JCBB)", "ekf-slam", None), ("FastSLAM 1.0, 100 particles", "fastslam", 1),
                                ("FastSLAM 2.0, 100 particles", "fastslam", 2)):
        mine = sorted((r for r in rows if r["kind"] == kind and r.get("options.version") == version
                       and r.get("options.refine") == "none"), key=lambda r: r["seed"] or 0)
        for r in mine:
            text = (f"| {name} | {'-' if r['seed'] is None else r['seed']} | {r['position_rmse_m']:.2f} m | "
                    f"{r['position_rmse_aligned_m']:.2f} m | {r['landmarks']} | {r['filter_cpu_s']:.1f} s |")
            if refine:
                g = refined[key(r)]
                text += (f" {g['position_rmse_aligned_m']:.2f} m | {g['landmarks']} | "
                         f"{g['cpu_s'] - g['filter_cpu_s']:.1f} s |")
            lines.append(text)
        if version is not None and mine:
            aligned = np.array([r["position_rmse_aligned_m"] for r in mine])
            text = (f"FastSLAM {version}.0: aligned RMS median {np.median(aligned):.2f} m, max {aligned.max():.2f} m "
                    f"over {len(mine)} seeds; CPU median {np.median([r['filter_cpu_s'] for r in mine]):.1f} s.")
            if refine:
                after = np.array([refined[key(r)]["position_rmse_aligned_m"] for r in mine])
                text += (f" Refined: median {np.median(after):.2f} m, max {after.max():.2f} m; no worse on "
                         f"{int(np.sum(after <= aligned))} of {len(mine)} seeds.")
            summary.append(text)
    return lines, summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", nargs="?", default=str(DEFAULT))
    parser.add_argument("--seeds", type=int, default=10, help="FastSLAM seeds 0..N-1 per variant (default 10)")
    parser.add_argument("--refine", action="store_true", help="also GraphSLAM's refinement of each run")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default: one per core)")
    parser.add_argument("-o", "--output-dir", help="keep the sweep's table and trajectories there")
    parser.add_argument("--record", action="store_true")
    args = parser.parse_args()
    folder = os.path.abspath(args.folder)
    data = victoria_park_acfr.load(folder)
    with tempfile.TemporaryDirectory(prefix="bench-vp-acfr-") as scratch:
        rows = batch.run(sweep(folder, args.seeds, args.refine), directory=args.output_dir or scratch,
                         workers=args.workers, trajectories=bool(args.output_dir))
    if _failed(rows):
        raise SystemExit(f"runs failed: {_failed(rows)}")
    # Dead reckoning: the car's model alone, one run without randomness or options.
    dr = victoria_park_acfr_run.run_ekf(data, dead_reckoning=True)
    e = ps.eval.position_error(dr.times, dr.poses, data.gps[:, 0], data.gps[:, 1:])
    header = ["| method | seed | RMS vs GPS | aligned | landmarks | CPU |" +
              (" refined: aligned | landmarks | CPU |" if args.refine else ""),
              "|---|---|---|---|---|---|" + ("---|---|---|" if args.refine else "")]
    first = f"| dead reckoning | - | {e.rmse:.2f} m | {e.rmse_aligned:.2f} m | 0 | - |" + (" - | - | - |" if args.refine
                                                                                         else "")
    lines, summary = table(rows, args.refine)
    refined = ", GraphSLAM refinement" if args.refine else ""
    text = [f"## Victoria Park (ACFR run) against GPS, EKF and FastSLAM{refined}, {datetime.date.today()}", "",
            f"Machine: {machine()}; load average {os.getloadavg()[0]:.1f} at the end (shared machine: CPU "
            f"seconds, not wall time), BLAS threads: OPENBLAS_NUM_THREADS="
            f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; the runs on probslam.batch's local cluster.", "",
            f"{len(data.inputs)} inputs (40 Hz, {data.inputs[-1, 0] - data.inputs[0, 0]:.0f} s), "
            f"{len(data.measurements)} detections on {len(data.scan_times)} scans, {len(data.gps)} GPS fixes; "
            "unknown correspondences, the trunk's diameter as signature, the defaults of "
            "datasets.victoria_park_acfr_run (noise: RFS-SLAM's published configuration for this run). "
            "CPU: the filter's CPU seconds (refined: the refinement's).", "",
            f"Commit: {commit()}.", ""]
    text += header + [first] + lines + [""] + summary + [
        "", "Command: `OPENBLAS_NUM_THREADS=1 python benchmarks/bench_victoria_park_acfr.py "
            f"{'--refine ' if args.refine else ''}{'' if args.seeds == 10 else f'--seeds {args.seeds} '}--record`."]
    report(text, args.record)


if __name__ == "__main__":
    main()
