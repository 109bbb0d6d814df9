"""The original Victoria Park run (ACFR: 1,549 s of encoder speed and steering at 40 Hz, 52,974
tree detections without identities, GPS) as the SLAM lecture measured it: EKF SLAM and FastSLAM
1.0 / 2.0 with 100 particles, the defaults of ``datasets.victoria_park_acfr_run``, each FastSLAM
variant over seeds 0-9; RMS against the GPS (as it is and SE(2)-aligned, evo's convention),
landmarks in the map and CPU seconds of the whole run. Prints a table and, with --record, writes
it into benchmarks/RESULTS.md.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_victoria_park_acfr.py [DIR] [--seeds N] [--provisional] [--refine] [--record]

--provisional runs every filter with the provisional-landmark rule (victoria_park_acfr_run.PROVISIONAL_*).
--refine adds GraphSLAM's refinement of each run (victoria_park_acfr_run.refine, docs/landmark_refine.md)
beside it: its RMS against the GPS (aligned), landmarks and CPU seconds (of the worker that refined it: the
refinements run in --jobs worker processes while the filters go on; the table is complete at the end).
"""

import argparse
import concurrent.futures
import dataclasses
import datetime
import multiprocessing
import os
import pathlib
import time

import numpy as np

import probslam as ps
from common import commit, machine, report
from probslam.datasets import refine_run, victoria_park_acfr, victoria_park_acfr_run

DEFAULT = pathlib.Path(__file__).resolve().parents[2] / "shared/data/landmark_slam/victoria_park_acfr"


def scored(data, run_method):
    """(run, CPU seconds of the run, PositionError against the GPS)."""
    c0 = time.process_time()
    run = run_method()
    cpu = time.process_time() - c0
    return run, cpu, ps.eval.position_error(run.times, run.poses, data.gps[:, 0], data.gps[:, 1:])


def refined_scores(data, run):
    """(the table's refine columns for ``run``, the refined aligned RMS): GraphSLAM's refinement
    of the run against the GPS, its landmarks and CPU seconds."""
    refined, cpu, e = scored(data, lambda: victoria_park_acfr_run.refined_result(
        refine_run(run, data), run))
    return f" {e.rmse_aligned:.2f} m | {len(refined.landmarks)} | {cpu:.1f} s |", e.rmse_aligned


def refine_columns(pool, data, run):
    """The refinement of ``run`` handed to ``pool`` (a future of ``refined_scores``; the filter
    object stays here), None without --refine; dead reckoning has nothing to refine."""
    if pool is None:
        return None
    if run.associations is None:
        return _done((" - | - | - |", None))
    future = pool.submit(refined_scores, data, dataclasses.replace(run, filter=None))
    label = f"{run.method} {getattr(run.filter, 'version', '')}".strip()
    future.add_done_callback(lambda f: print(f"refined ({label}):{f.result()[0]}", flush=True))
    return future


def _done(value):
    future = concurrent.futures.Future()
    future.set_result(value)
    return future


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", nargs="?", default=str(DEFAULT))
    parser.add_argument("--seeds", type=int, default=10, help="FastSLAM seeds 0..N-1 per variant (default 10)")
    parser.add_argument("--provisional", action="store_true", help="new landmarks wait on the provisional list")
    parser.add_argument("--refine", action="store_true", help="also GraphSLAM's refinement of each run")
    parser.add_argument("--jobs", type=int, default=2, help="--refine: worker processes refining (default 2)")
    parser.add_argument("--record", action="store_true")
    parser.add_argument("--save", metavar="NPZ", help="also save every run's path and seed 0's maps (for "
                                                      "docs/make_victoria_park_acfr_figure.py)")
    args = parser.parse_args()
    data = victoria_park_acfr.load(args.folder)
    rows = ["| method | seed | RMS vs GPS | aligned | landmarks | CPU |" +
            (" refined: aligned | landmarks | CPU |" if args.refine else ""), "|---|---|---|---|---|---|" +
            ("---|---|---|" if args.refine else "")]
    summary, saved = [], {"gps": data.gps}
    pool = concurrent.futures.ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("fork")) \
        if args.refine else None
    pending = []  # (row, future of its refine columns, the filter's aligned RMS, list the refined RMS joins)
    for name, method in (("dead reckoning", lambda: victoria_park_acfr_run.run_ekf(data, dead_reckoning=True)),
                         ("EKF SLAM (JCBB)", lambda: victoria_park_acfr_run.run_ekf(data, provisional=args.provisional))):
        run, cpu, e = scored(data, method)
        saved[name] = np.column_stack([run.times, run.poses])
        rows.append(f"| {name} | - | {e.rmse:.2f} m | {e.rmse_aligned:.2f} m | {len(run.landmarks)} | {cpu:.1f} s |")
        if pool is not None:
            pending.append((len(rows) - 1, refine_columns(pool, data, run), e.rmse_aligned, name))
        print(rows[-1], flush=True)
    for version in (1, 2):
        aligned, cpus, refined = [], [], []
        for seed in range(args.seeds):
            run, cpu, e = scored(data, lambda: victoria_park_acfr_run.run_fastslam(data, version=version, seed=seed,
                                                                                    provisional=args.provisional))
            aligned.append(e.rmse_aligned)
            saved[f"fastslam{version}_seed{seed}"] = np.column_stack([run.times, run.poses])
            if seed == 0:
                saved[f"fastslam{version}_map"] = np.array(list(run.landmarks.values())).reshape(-1, 2)
            cpus.append(cpu)
            rows.append(f"| FastSLAM {version}.0, 100 particles | {seed} | {e.rmse:.2f} m | {e.rmse_aligned:.2f} m | "
                        f"{len(run.landmarks)} | {cpu:.1f} s |")
            if pool is not None:
                pending.append((len(rows) - 1, refine_columns(pool, data, run), e.rmse_aligned, refined))
            print(rows[-1], flush=True)
        summary.append((f"FastSLAM {version}.0: aligned RMS median {np.median(aligned):.2f} m, max "
                        f"{np.max(aligned):.2f} m over {args.seeds} seeds; CPU median {np.median(cpus):.1f} s.",
                        aligned, refined))
    # The refinements, as they finish: their columns joined to the rows, their RMS to the summary.
    notes = []
    for row, future, before, into in pending:
        columns, after = future.result()
        rows[row] += columns
        print(rows[row], flush=True)
        if isinstance(into, str) and after is not None:
            notes.append(f"{into}: aligned RMS {before:.2f} m, refined {after:.2f} m.")
        elif after is not None:
            into.append(after)
    summary = notes + [text + (f" Refined: median {np.median(refined):.2f} m, max {np.max(refined):.2f} m; no worse "
                               f"on {int(np.sum(np.array(refined) <= np.array(aligned)))} of {len(refined)} seeds."
                               if refined else "") for text, aligned, refined in summary]
    rule = (", provisional landmarks" if args.provisional else "") + (", GraphSLAM refinement" if args.refine else "")
    lines = [f"## Victoria Park (ACFR run) against GPS, EKF and FastSLAM{rule}, {datetime.date.today()}", "",
             f"Machine: {machine()}; load average {os.getloadavg()[0]:.1f} at the end (shared machine: CPU "
             f"seconds, not wall time), BLAS threads: OPENBLAS_NUM_THREADS="
             f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}.", "",
             f"{len(data.inputs)} inputs (40 Hz, {data.inputs[-1, 0] - data.inputs[0, 0]:.0f} s), "
             f"{len(data.measurements)} detections on {len(data.scan_times)} scans, {len(data.gps)} GPS fixes; "
             "unknown correspondences, the trunk's diameter as signature, the defaults of "
             "datasets.victoria_park_acfr_run (noise: RFS-SLAM's published configuration for this run)"
             + (f"; provisional landmarks: seen in {victoria_park_acfr_run.PROVISIONAL_SIGHTINGS} scans before "
                f"{victoria_park_acfr_run.PROVISIONAL_MAX_AGE} pass unseen" if args.provisional else "") + ".", "",
             f"Commit: {commit()}.", ""]
    lines += rows + [""] + summary + ["", "Command: `OPENBLAS_NUM_THREADS=1 python benchmarks/bench_victoria_park_acfr.py "
                                          f"{'--provisional ' if args.provisional else ''}"
                                          f"{'--refine ' if args.refine else ''}"
                                          f"{'' if args.seeds == 10 else f'--seeds {args.seeds} '}--record`."]
    report(lines, args.record)
    if args.save:
        np.savez_compressed(args.save, **saved)


if __name__ == "__main__":
    main()
