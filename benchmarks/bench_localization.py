"""Monte Carlo localization (probslam.localize) of the raw laser logs in the maps probslam built.

For each log (ACES, Intel, FR079 of ../shared/data/laser_2d) the map and the SLAM trajectory come
from ``probslam slam LOG -o MAPS/<name>`` (MAPS/<name>.yaml and MAPS/<name>_trajectory.tum, one
row per scan; made here when missing). The SLAM trajectory is the reference: the map is in its
frame, so no alignment is applied.

The runs are benchmarks/sweeps/localization.toml's, made by ``probslam.batch`` on a local Dask
cluster (the localize kind: ``pipelines.localize_log`` on a ``LogPiece`` of the log, scored by
``LocalizationRun.reference_metrics``); this script makes the maps, runs the sweep (for --logs,
with --option set on every run) and formats its rows as the tables of benchmarks/RESULTS.md:

- Tracking: the whole raw log from the SLAM start pose (seed 1); ATE against the SLAM trajectory
  (align none), the real-time factor of the filter on one core (log duration / its processing
  time: the one figure that wants a quiet machine; --workers 1 gives each run the machine's
  second core to itself), particles over time (KLD sampling: median, max, last).
- Global: 20 start scans per log (drawn once with numpy's default_rng(0), written in the sweep),
  each run for 120 s of log from a global start, seeded by its start scan. A run converged when
  the position error against the SLAM pose falls below eval.CONVERGED_POSITION m (and the
  heading's below eval.CONVERGED_HEADING rad) and stays there to the segment's end
  (``eval.convergence``); reported: the fraction converged, median / max log time and travel to
  converge.
- Kidnapped robot: 120 s from 1/5 of the log spliced onto 120 s from 3/5 (``pipelines.splice``:
  the second piece's odometry continued from the first's end, so odometry does not see the jump)
  while the true pose jumps; the filter tracks from the true start (seed 3); time (s of log) and
  travel to recover (the same criterion after the jump).
- Beam model: the tracking run again with sensor_model="beam" (Table 6.1 on the ray walk).

    .venv/bin/python benchmarks/bench_localization.py [--logs aces intel fr079] [--maps DIR]
        [--option KEY=VALUE ...] [--no-beam] [--workers N] [-o OUT] [--record]

``--option`` sets a MonteCarloLocalizationOptions field on every run (e.g. recovery_ratio=0.7),
for comparing settings on the same runs; the last line printed sums a run up for such comparisons.
-o OUT keeps the sweep's table there (a run already there is not made again).

Missing logs are skipped with a message.
"""

import argparse
import dataclasses
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

from common import heading, report
from probslam import batch
from probslam import eval as evaluation

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
SWEEP = HERE / "sweeps" / "localization.toml"
#: The sweep's folder of maps and SLAM trajectories (its prerequisite, made here when missing).
MAPS = "PROBSLAM_LOCALIZATION_MAPS"
LOGS = {
    "aces": ("ACES", "aces/aces.clf.bz2"),
    "intel": ("Intel", "intel/intel.clf"),
    "fr079": ("FR079", "fr079/fr079.clf.bz2"),
}


def make_maps(name, path, maps: pathlib.Path) -> None:
    """MAPS/<name>.yaml and MAPS/<name>_trajectory.tum by ``probslam slam`` when missing."""
    prefix = maps / name
    if not (prefix.with_suffix(".yaml").exists() and pathlib.Path(f"{prefix}_trajectory.tum").exists()):
        print(f"{name}: running probslam slam (map and reference trajectory)", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "probslam", "slam", str(path), "-o", str(prefix), "--no-progress",
                        "--no-plot"], check=True)


def parse_options(pairs):
    """KEY=VALUE pairs as options (an int, else a float, else the text)."""
    options = {}
    for kv in pairs:
        key, _, value = kv.partition("=")
        for kind in (int, float, str):
            try:
                options[key] = kind(value)
                break
            except ValueError:
                continue
    return options


def sweep(logs, options, beam: bool) -> batch.Sweep:
    """localization.toml's groups of ``logs``, with ``options`` set on every run (and without the
    beam model's runs unless ``beam``)."""
    whole = batch.load(SWEEP)
    groups = []
    for group in whole.runs:
        if not any(LOGS[name][1] in d for name in logs for d in group.datasets):
            continue
        mine = {**group.options, **options}
        if not beam and isinstance(mine.get("sensor_model"), list):
            mine["sensor_model"] = [m for m in mine["sensor_model"] if m != "beam"]
        groups.append(dataclasses.replace(group, options=mine))
    return dataclasses.replace(whole, runs=groups)


def log_of(row):
    return next(name for name, (_, rel) in LOGS.items() if row["dataset"].endswith(rel))


def median_max(values) -> str:
    return f"{np.median(values):.1f} / {max(values):.1f}" if values else "-"


def tables(rows, logs):
    """The RESULTS.md tables' rows (tracking, beam, global, kidnapping) and the summary."""
    track, beam, glob, kidnap, summary = [], [], [], [], []
    for name in logs:
        title = LOGS[name][0]
        mine = [r for r in rows if log_of(r) == name]
        if not mine:
            continue
        for r in (r for r in mine if r.get("options.start_scan") is None):
            ate = f"{r['ate_rmse_m']:.3f} / {r['error_median_m']:.3f} / {r['error_max_m']:.3f}"
            duration = r["seconds"] * r["real_time_factor"]
            if r.get("options.sensor_model") == "beam":
                beam.append(f"| {title} | {ate} | {r['heading_error_median_deg']:.2f} | "
                            f"{int(r['particles_median'])} / {r['particles_max']} | {r['seconds']:.1f} | "
                            f"{r['real_time_factor']:.0f}x |")
                continue
            track.append(f"| {title} | {r['scans']} | {ate} | {r['heading_error_median_deg']:.2f} | "
                         f"{int(r['particles_median'])} / {r['particles_max']} / {r['particles_last']} | "
                         f"{r['seconds']:.1f} | {duration:.0f} | {r['real_time_factor']:.0f}x |")
            summary.append(f"{title}: track max {r['error_max_m']:.2f}")
        segments = [r for r in mine if r.get("options.start_scan") is not None and r.get("options.splice_scan") is None]
        if segments:
            done = [r for r in segments if r["converged_to_reference"]]
            seconds = sum(r["seconds"] for r in segments)
            log_seconds = sum(r["seconds"] * r["real_time_factor"] for r in segments)
            n = len(segments)
            summary.append(f"global {len(done)}/{n}")
            glob.append(f"| {title} | {n} x {segments[0]['options.segment_seconds']:.0f} s | {len(done)} / {n} "
                        f"({100.0 * len(done) / n:.0f}%) | {median_max([r['time_to_converge_s'] for r in done])} | "
                        f"{median_max([r['travel_to_converge_m'] for r in done])} | "
                        f"{log_seconds / seconds if seconds else 0:.0f}x |")
        for r in (r for r in mine if r.get("options.splice_scan") is not None):
            rec = (f"{r['time_to_converge_s']:.1f} s, {r['travel_to_converge_m']:.1f} m"
                   if r["converged_to_reference"] else "not recovered")
            summary.append(f"kidnap {rec}")
            kidnap.append(f"| {title} | {r['jump_m']:.1f} m | {'yes' if r['tracked_before_jump'] else 'no'} | {rec} | "
                          f"{r['particles_max']} |")
    return track, beam, glob, kidnap, summary


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--logs", nargs="+", choices=sorted(LOGS), default=["aces", "intel", "fr079"])
    p.add_argument("--maps", default=os.environ.get(MAPS, "/tmp/probslam_localization_maps"),
                   help=f"folder of <log>.yaml and <log>_trajectory.tum from probslam slam (made when missing; "
                        f"default ${MAPS} or /tmp/probslam_localization_maps)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="a MonteCarloLocalizationOptions field for every run (repeatable)")
    p.add_argument("--no-beam", action="store_true", help="skip the beam model's tracking runs")
    p.add_argument("--workers", type=int, default=None, help="worker processes (default: one per core)")
    p.add_argument("-o", "--output-dir", help="keep the sweep's table there")
    p.add_argument("--record", action="store_true")
    args = p.parse_args()
    maps = pathlib.Path(args.maps).resolve()
    maps.mkdir(parents=True, exist_ok=True)
    logs = []
    for name in args.logs:
        path = SHARED / "laser_2d" / LOGS[name][1]
        if not path.exists():
            print(f"{LOGS[name][0]}: {path} missing, skipped", file=sys.stderr)
            continue
        make_maps(name, path, maps)
        logs.append(name)
    os.environ[MAPS] = str(maps)
    os.environ["PROBSLAM_SHARED_DATA"] = str(SHARED)
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench-localization-") as scratch:
        rows = batch.run(sweep(logs, parse_options(args.option), not args.no_beam),
                         directory=args.output_dir or scratch, workers=args.workers)
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        raise SystemExit("runs failed: " + "; ".join(f"{r['dataset']} {r['run_id']}: {r['error']}" for r in failed))
    track, beam, glob, kidnap, summary = tables(rows, logs)
    lines = heading("Monte Carlo localization on raw laser logs",
                    "probslam.localize with default options (likelihood field, KLD sampling 500-20000 "
                    "particles, augmented MCL), one thread per run, the runs of benchmarks/sweeps/localization.toml "
                    "on probslam.batch's local cluster; maps and reference trajectories from `probslam slam`.",
                    ["log", "scans", "ATE rmse / median / max (m)", "median heading error (deg)",
                     "particles median / max / last", "processing (s)", "log duration (s)", "real-time factor"])
    lines += track
    if beam:
        lines += ["", "Beam model (`sensor_model=\"beam\"`), the tracking runs above:", "",
                  "| log | ATE rmse / median / max (m) | median heading error (deg) | particles median / max | "
                  "processing (s) | real-time factor |", "|---|---|---|---|---|---|"]
        lines += beam
    lines += ["", "| log | global runs | converged | time to converge median / max (s) | "
              "travel to converge median / max (m) | real-time factor |", "|---|---|---|---|---|---|"]
    lines += glob
    lines += ["", "| log | kidnapping jump | tracking before | recovery (log time, travel) | max particles |",
              "|---|---|---|---|---|"]
    lines += kidnap
    flags = (" --no-beam" if args.no_beam else "") + (f" --workers {args.workers}" if args.workers else "")
    lines += ["",
              f"Load average at the start: {load0:.2f} (on {os.cpu_count()} cores). Tracking starts at the SLAM "
              "trajectory's first pose; ATE is against the SLAM trajectory without alignment (the map is in its "
              f"frame). Converged: within {evaluation.CONVERGED_POSITION} m and {evaluation.CONVERGED_HEADING} rad of "
              "the SLAM pose from then to the segment's end. Global segments start at the sweep's start scans (drawn "
              "with numpy's default_rng(0)), each seeded by its start scan. Kidnapping: scans at 1/5 and 3/5 of the "
              "log, 120 s each, the second piece's odometry continued from the first's end.",
              f"Command: `python benchmarks/bench_localization.py --logs {' '.join(args.logs)}{flags}"
              + "".join(f" --option {kv}" for kv in args.option) + "` (the runs: "
              "`probslam batch benchmarks/sweeps/localization.toml`)."]
    report(lines, args.record)
    print("summary:", " ".join(args.option) or "defaults", "|", "; ".join(summary))


if __name__ == "__main__":
    main()
