"""SLAM on the raw laser logs: probslam.slam.run_slam with its default options on each raw CARMEN
log of ../shared/data/laser_2d (ACES, Intel, FR079, MIT CSAIL), one after the other, one thread.

Per log: scans, submaps, loop closures (accepted, i.e. active at the end / rejected / dissolved),
processing seconds (reading the log not included: run_slam's own clock, from the first scan to
the map), the log's duration and the real-time factor (duration / processing time on one core).

Accuracy: benchmarks/sweeps/laser_logs.toml makes the same GraphSLAM runs with their references
(ACES' relations; Intel's and FR079's corrected logs, paired scan for scan by
probslam.eval.pair_corrected_scans) through `probslam batch`, and scores scan matching alone with
them. This script keeps what needs a timing harness: the logs one after the other on one core of
a quiet machine.

    .venv/bin/python benchmarks/bench_slam_logs.py [--logs aces intel fr079 mit_csail]
        [--figures DIR] [--quick] [--record]

--figures DIR writes DIR/slam_<log>.png (probslam.io.write_png of the map with the GraphSLAM
trajectory in red). --quick runs the first 1500 scans of each log (a CI-time check; not recorded).
Missing logs are skipped with a message.
"""

import argparse
import ast
import dataclasses
import os
import pathlib
import sys

import probslam as ps
import probslam.slam
from common import heading, report

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
LASER = SHARED / "laser_2d"

#: name -> (title, raw log)
LOGS = {
    "aces": ("ACES", "aces/aces.clf.bz2"),
    "intel": ("Intel", "intel/intel.clf"),
    "fr079": ("FR079", "fr079/fr079.clf.bz2"),
    "mit_csail": ("MIT CSAIL", "mit_csail/mit-csail.clf.bz2"),
}
QUICK_SCANS = 1500


def first_scans(scans: ps.io.LaserScans, n: int) -> ps.io.LaserScans:
    """The first n scans: every field of LaserScans is an array with one row per scan."""
    return ps.io.LaserScans(**{f.name: getattr(scans, f.name)[:n] for f in dataclasses.fields(scans)})


def run_log(name, quick, figures, method="graph", options=None):
    """(row of the run table, notes), or None when the log is absent."""
    title, raw = LOGS[name]
    path = LASER / raw
    if not path.exists():
        print(f"bench_slam_logs: {path} not found; {title} skipped")
        return None
    scans = ps.io.read_carmen_log(path).scans
    scans = first_scans(scans, QUICK_SCANS) if quick else scans
    print(f"bench_slam_logs: {title}: {len(scans)} scans ...", file=sys.stderr, flush=True)
    result = ps.slam.run_slam(scans, progress=False, method=method,
                              options=ps.slam.with_fields(ps.slam.default_options(scans, method), options or {}))
    s = result.summary
    print(f"bench_slam_logs: {title}: {result.seconds:.1f} s", file=sys.stderr, flush=True)
    if method == "rbpf":
        run_row = (f"| {title} | {s.scans} | {s.updates} updates, {s.resamples} resamplings | "
                   f"{s.matched} matched / {s.fallbacks} fallbacks | {result.seconds:.1f} | "
                   f"{result.log_duration:.0f} | {result.real_time_factor:.1f}x |")
    else:
        run_row = (f"| {title} | {s.scans} | {s.submaps} | {s.closures_accepted} / {s.closures_rejected} / "
                   f"{s.closures_dissolved} | {result.seconds:.1f} | {result.log_duration:.0f} | "
                   f"{result.real_time_factor:.1f}x |")
    notes = []
    if figures is not None:
        png = figures / (f"slam_{name}.png" if method == "graph" else f"rbpf_{name}.png")
        ps.io.write_png(result.grid, png, trajectory=result.poses)
        kb = png.stat().st_size / 1024
        notes.append(f"{title}: map picture {png.name} ({result.grid.width} x {result.grid.height} cells, {kb:.0f} KB).")
    return run_row, notes


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--logs", nargs="+", choices=list(LOGS), default=list(LOGS), help="logs to run (default: all)")
    parser.add_argument("--figures", type=pathlib.Path, help="write DIR/slam_<log>.png for each log")
    parser.add_argument("--quick", action="store_true",
                        help=f"the first {QUICK_SCANS} scans of each log (a smoke run; not recorded)")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    parser.add_argument("--method", choices=ps.slam.METHODS, default="graph",
                        help="graph (GraphSLAM over submaps, default) or rbpf (grid-based FastSLAM)")
    parser.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                        help="an option of run_slam's options by its path (a Python literal), e.g. num_particles=30 or "
                             "closures.enabled=False; repeatable")
    args = parser.parse_args()
    options = {}
    for o in args.option:
        name, _, value = o.partition("=")
        options[name.strip()] = ast.literal_eval(value.strip())
    if args.figures is not None:
        args.figures.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()[0]
    shown = args.figures
    if shown is not None:
        try:
            shown = args.figures.resolve().relative_to(HERE.parent)
        except ValueError:
            pass
    runs, notes = [], []
    for name in args.logs:
        out = run_log(name, args.quick, args.figures, args.method, options)
        if out is None:
            notes.append(f"{LOGS[name][0]}: {LASER / LOGS[name][1]} not found; skipped.")
            continue
        runs.append(out[0])
        notes += out[1]
    if not runs:
        print(f"bench_slam_logs: no raw log found under {LASER}; nothing to run")
        return
    # A run over some of the logs is its own RESULTS.md section (--record replaces by title).
    subset = "" if set(args.logs) == set(LOGS) else f" ({', '.join(LOGS[n][0] for n in args.logs)})"
    title = ("SLAM on raw laser logs" if args.method == "graph" else "Grid-based FastSLAM on raw laser logs") + \
        subset + (f" (quick: first {QUICK_SCANS} scans)" if args.quick else "")
    shown_options = ", ".join(f"{k}={v!r}" for k, v in options.items()) or "default options"
    columns = (["log", "scans", "submaps", "closures accepted / rejected / dissolved"] if args.method == "graph" else
               ["log", "scans", "filter", "particle updates scan-matched / fallbacks"])
    lines = heading(title, f"probslam.slam.run_slam(method={args.method!r}) with {shown_options}, one thread, logs "
                    "one after the other.", columns + ["processing (s)", "log duration (s)", "real-time factor"])
    lines += runs
    lines += ["", *notes,
              f"Load average at the start: {load:.2f} (on {os.cpu_count()} cores). Processing time: run_slam's clock "
              "(matching, closures, optimisation, the final map), reading the log excluded; real-time factor = log "
              "duration / processing time.",
              "Closures: accepted = active at the end; rejected = failed the quality or consistency test; dissolved "
              "= added, then undone by the optimised graph.",
              "Accuracy against the references: `probslam batch benchmarks/sweeps/laser_logs.toml`.",
              f"Command: `python benchmarks/bench_slam_logs.py{' --quick' if args.quick else ''}"
              f"{' --method ' + args.method if args.method != 'graph' else ''}"
              f"{''.join(' --option ' + o for o in args.option)}"
              f" --logs {' '.join(args.logs)}{' --figures ' + str(shown) if shown else ''}`.", ""]
    report(lines, record=args.record and not args.quick)


if __name__ == "__main__":
    main()
