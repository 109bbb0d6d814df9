"""Grid-based FastSLAM (probslam.slam.run_slam(method="rbpf")) on the raw laser logs: time per
update step and real-time factor against the particle count, the memory the particles' maps take
(distinct tiles) against what unshared maps would take (tiles held), and two threads against one.

Table 1, particle sweep on the first SWEEP_SCANS scans of ACES (one thread, scan-matching
proposal): updates, seconds per update step, real-time factor, tiles held / distinct and their
memory, and the relations error of those scans (ACES relations within the excerpt).
Table 2, each raw log whole (ACES, Intel, FR079), 30 particles, scan-matching proposal, one thread:
time, real-time factor, memory, and the ACES relations error.
Table 3, threads: 30 particles on the ACES excerpt with 1 and 2 threads (identical results).

    .venv/bin/python benchmarks/bench_rbpf.py [--quick] [--record] [--figures DIR]

--quick: the sweep only, on 500 scans (a smoke run; not recorded). Missing logs are skipped.
--figures DIR: the best particle's map and path of each whole log as DIR/rbpf_<log>.png.
"""

import argparse
import dataclasses
import functools
import os
import pathlib
import sys

import numpy as np

import probslam as ps
import probslam.eval
import probslam.slam
from probslam.mapping import map_laser_log
from common import heading, report

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
LASER = SHARED / "laser_2d"
LOGS = {"aces": ("ACES", "aces/aces.clf.bz2"), "intel": ("Intel", "intel/intel.clf"),
        "fr079": ("FR079", "fr079/fr079.clf.bz2")}
RELATIONS = LASER / "aces" / "aces.relations"
#: The corrected logs the Intel and FR079 paths are compared with (ps.eval.corrected_log_error).
CORRECTED = {"intel": "intel/intel-corrected.log.gz", "fr079": "fr079/freiburg-079-corrected.log.gz"}
SWEEP_SCANS = 2000
PARTICLES = (1, 3, 10, 30, 100)
TILE_BYTES = 32 * 32 * 12  # log-odds (double) and scan stamp (uint32) of 32 x 32 cells


def first_scans(scans, n):
    return ps.io.LaserScans(**{f.name: getattr(scans, f.name)[:n] for f in dataclasses.fields(scans)})


@functools.lru_cache(maxsize=1)
def aces_relations():
    """aces.relations on the ACES log's logger time (the file is stamped with its ipc time)."""
    return ps.eval.relations_on_logger_time(RELATIONS, ps.io.read_carmen_log(LASER / LOGS["aces"][1]).scans)


def relations(result):
    if not RELATIONS.exists():
        return "-"
    try:
        e = ps.eval.relations_error(result.timestamps, result.poses, aces_relations())
    except ValueError:
        return "-"
    return f"{e.trans_mean:.3f} +- {e.trans_std:.3f} m ({len(e.used)})"


def corrected_agreement(name, path, result):
    """Mean position difference (m) from the log's corrected log after a rigid alignment, or "-"."""
    corrected = CORRECTED.get(name)
    if corrected is None or not (LASER / corrected).exists():
        return "-"
    try:
        e = ps.eval.corrected_log_error(result.poses, ps.io.read_carmen_log(path).scans,
                                        ps.io.read_carmen_log(LASER / corrected).scans)
    except ValueError:  # fewer than ps.eval.MIN_PAIRS pairs
        return "-"
    return f"corrected log: mean {e.errors.mean():.3f} m ({e.matched} scans)"


def write_figure(path, result, png):
    """The best particle's path and every scan mapped along it (no-return readings left out, as
    the GraphSLAM map and `probslam map` do; the particles' own maps clear along them)."""
    scans = ps.io.read_carmen_log(path).scans
    grid = map_laser_log(dataclasses.replace(scans, laser_poses=result.poses), progress=False).grid
    png.parent.mkdir(parents=True, exist_ok=True)
    ps.io.write_png(grid, png, trajectory=result.poses)


def row(label, result, extra="", aces=True):
    s, t = result.summary, result.tile_sharing
    per_update = result.seconds / max(1, s.updates)
    return (f"| {label} | {s.scans} | {s.updates} | {1e3 * per_update:.1f} | {result.seconds:.1f} | "
            f"{result.real_time_factor:.1f}x | {t.references} / {t.distinct} | "
            f"{t.references * TILE_BYTES / 2 ** 20:.0f} / {t.bytes / 2 ** 20:.0f} | "
            f"{relations(result) + extra if aces else (extra or '-')} |")


def rbpf(log, **fields):
    """run_slam(method="rbpf") with the log's default options, these fields replaced."""
    scans = ps.slam.scans_of(log)
    return ps.slam.run_slam(scans, progress=False, options=ps.slam.default_options(scans, "rbpf").replace(**fields))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="the particle sweep on 500 scans (not recorded)")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    parser.add_argument("--figures", type=pathlib.Path, help="write rbpf_<log>.png map pictures into this folder")
    args = parser.parse_args()
    aces = LASER / LOGS["aces"][1]
    if not aces.exists():
        print(f"bench_rbpf: {aces} not found; nothing to run")
        return
    load = os.getloadavg()[0]
    columns = ["run", "scans", "updates", "ms / update", "s", "real-time factor", "tiles held / distinct",
               "MiB unshared / shared", "ACES relations (used); others: corrected log"]
    lines = heading("Grid-based FastSLAM (rbpf)", "run_slam(method='rbpf'), scan-matching proposal, one thread "
                    "unless stated.", columns)
    log = ps.io.read_carmen_log(aces)
    n = 500 if args.quick else SWEEP_SCANS
    excerpt = first_scans(log.scans, n)
    for m in PARTICLES:
        print(f"bench_rbpf: ACES first {n} scans, {m} particles ...", file=sys.stderr, flush=True)
        lines.append(row(f"ACES first {n} scans, {m} particles", rbpf(excerpt, num_particles=m)))
    if not args.quick:
        results = {}
        for threads in (1, 2):
            print(f"bench_rbpf: ACES excerpt, {threads} threads ...", file=sys.stderr, flush=True)
            results[threads] = rbpf(excerpt, num_particles=30, threads=threads)
        same = np.array_equal(results[1].poses, results[2].poses)
        lines.append(row(f"ACES first {n} scans, 30 particles, 2 threads", results[2],
                         f"; {results[1].seconds / results[2].seconds:.2f}x one thread, "
                         f"{'identical' if same else 'DIFFERENT'} poses"))
        for name, (title, raw) in LOGS.items():
            path = LASER / raw
            if not path.exists():
                lines.append(f"| {title} | - | - | - | - | - | - | - | not found |")
                continue
            print(f"bench_rbpf: {title}, 30 particles ...", file=sys.stderr, flush=True)
            result = rbpf(path, num_particles=30)
            lines.append(row(f"{title} whole log, 30 particles", result, aces=name == "aces",
                             extra="" if name == "aces" else corrected_agreement(name, path, result)))
            if args.figures is not None:
                write_figure(path, result, args.figures / f"rbpf_{name}.png")
    lines += ["", f"Load average at the start: {load:.2f} (on {os.cpu_count()} cores). ms / update: processing time "
              "over filter updates (one every 0.25 m or 0.25 rad). Tiles held: summed over the particles (what "
              "unshared maps would take); distinct: allocated once and shared.",
              f"Command: `python benchmarks/bench_rbpf.py{' --quick' if args.quick else ''}`.", ""]
    report(lines, record=args.record and not args.quick)


if __name__ == "__main__":
    main()
