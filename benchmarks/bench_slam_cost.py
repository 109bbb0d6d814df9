"""What laser SLAM costs (issue 40): processor time, real-time factor per core and peak memory of
probslam.slam.run_slam on the raw CARMEN logs ACES, Intel and FR079 (../shared/data/laser_2d), for
both methods (GraphSLAM over submaps, default options; grid FastSLAM with 30 particles), with the
time per stage (the SLAM objects' `timings`) and what holds the memory.

Each (log, method) runs in a fresh Python process, so that its peak resident set size
(resource.getrusage ru_maxrss) is its own: the process reads the log, runs run_slam from the first
scan to the final map, and reports. CPU s: the process's processor time over run_slam
(time.process_time, all threads; reading the log excluded); real-time factor per core: the log's
duration over that. Stage columns: processor seconds from the object's timings (the stages do not
add up to CPU s: the bindings, Python and the summary are outside them).

MRPT (icp-slam, rbpf-slam from Debian's mrpt-apps) is compared only when `icp-slam` is on PATH; it
is not installed here, so those rows are skipped with a note. (MRPT 2.5.8's carmen2rawlog does not
serve for that comparison: it stamps every observation with the same time, assumes 0.5 degree beams
and an 81 m maximum range, and writes observation-only rawlogs rbpf-slam cannot read; a converter
writing action / sensory-frame pairs with the FLASER timestamps, 1 degree beams and max-range
readings invalid is needed, and not written yet.)

    .venv/bin/python benchmarks/bench_slam_cost.py [--logs aces intel fr079] [--methods graph rbpf]
        [--scans N] [--record]

--scans N runs the first N scans of each log (a smoke run; not recorded). Missing logs are skipped.
--runs FILE appends each run's measurements to FILE (JSON lines) and takes the runs FILE holds
already instead of running them again: runs split over several invocations (e.g. one per log, at
the same time on a machine with cores to spare) make one table.
"""

import argparse
import json
import os
import pathlib
import resource
import shutil
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
LASER = SHARED / "laser_2d"
LOGS = {"aces": ("ACES", "aces/aces.clf.bz2"), "intel": ("Intel", "intel/intel.clf"),
        "fr079": ("FR079", "fr079/fr079.clf.bz2")}
METHODS = {"graph": {}, "rbpf": {"num_particles": 30}}
RELATIONS = LASER / "aces" / "aces.relations"
MIB = 1024.0 * 1024.0


def peak_rss_mib() -> float:
    """This process's peak resident set size (ru_maxrss is KiB on Linux)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def child(name: str, method: str, scans: int) -> None:
    """One run in this process; prints one JSON line."""
    import dataclasses

    import probslam as ps
    import probslam.eval
    import probslam.slam

    path = LASER / LOGS[name][1]
    log = ps.io.read_carmen_log(path).scans
    if scans:
        log = ps.io.LaserScans(**{f.name: getattr(log, f.name)[:scans] for f in dataclasses.fields(log)})
    after_read = peak_rss_mib()
    c0 = time.process_time()
    w0 = time.perf_counter()
    r = ps.slam.run_slam(log, progress=False, method=method, **METHODS[method])
    cpu = time.process_time() - c0
    out = dict(scans=len(log), cpu=cpu, wall=time.perf_counter() - w0, duration=r.log_duration,
               rss_read=after_read, rss_peak=peak_rss_mib(), timings=r.timings, memory=r.memory,
               map_bytes=12.0 * r.grid.width * r.grid.height, relations=None)
    if method == "rbpf":
        out["tiles"] = dict(references=r.tile_sharing.references, distinct=r.tile_sharing.distinct,
                            bytes=r.tile_sharing.bytes)
    if name == "aces" and RELATIONS.exists():
        try:
            e = ps.eval.relations_error(r.timestamps, r.poses, ps.eval.read_relations(RELATIONS))
            out["relations"] = [e.trans_mean, e.trans_std, len(e.used)]
        except ValueError:
            pass
    print(json.dumps(out))


def run(name: str, method: str, scans: int):
    cmd = [sys.executable, str(pathlib.Path(__file__).resolve()), "--child", name, method, str(scans)]
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=HERE)
    if done.returncode != 0:
        print(done.stderr, file=sys.stderr)
        raise SystemExit(f"bench_slam_cost: {name} {method} failed")
    return json.loads(done.stdout.strip().splitlines()[-1])


GRAPH_STAGES = ("filter", "match", "insert", "closure_search", "closure_fields", "optimize", "final_map")
RBPF_STAGES = ("filter", "corrector", "proposal", "resample", "map_update", "table_copies", "final_map")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--logs", nargs="+", choices=list(LOGS), default=list(LOGS))
    parser.add_argument("--methods", nargs="+", choices=list(METHODS), default=list(METHODS))
    parser.add_argument("--scans", type=int, default=0, help="the first N scans of each log (not recorded)")
    parser.add_argument("--record", action="store_true", help="write the tables into benchmarks/RESULTS.md")
    parser.add_argument("--runs", type=pathlib.Path, help="JSON lines of runs: taken when present, appended otherwise")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child[0], args.child[1], int(args.child[2]))
        return
    sys.path.insert(0, str(HERE))
    from common import heading, report

    load = os.getloadavg()[0]
    saved = {}
    if args.runs is not None and args.runs.exists():
        for line in args.runs.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                saved[(r["log"], r["method"], r["scans_asked"])] = r
    rows, graph_rows, rbpf_rows, memory_rows, notes, run_loads = [], [], [], [], [], []
    for name in args.logs:
        title, raw = LOGS[name]
        if not (LASER / raw).exists():
            notes.append(f"{title}: {LASER / raw} not found; skipped.")
            continue
        for method in args.methods:
            r = saved.get((name, method, args.scans))
            if r is None:
                print(f"bench_slam_cost: {title} {method} ...", file=sys.stderr, flush=True)
                r = dict(run(name, method, args.scans), log=name, method=method, scans_asked=args.scans,
                         load=os.getloadavg()[0])
                if args.runs is not None:
                    with open(args.runs, "a") as f:
                        f.write(json.dumps(r) + "\n")
            run_loads.append(r.get("load", load))
            t = r["timings"]
            rel = f"{r['relations'][0]:.3f} m" if r["relations"] else "-"
            label = "GraphSLAM" if method == "graph" else "grid FastSLAM, 30 particles"
            rows.append(f"| {title} | {label} | {r['scans']} | {r['cpu']:.1f} | {r['duration'] / r['cpu']:.0f}x | "
                        f"{r['rss_peak']:.0f} MB | {r['rss_read']:.0f} MB | {rel} |")
            if method == "graph":
                graph_rows.append(f"| {title} | " + " | ".join(f"{t[s]:.2f}" for s in GRAPH_STAGES) +
                                  f" | {t['frontend_fields']} / {t['closure_fields_built']} / {t['closure_matches']} |")
                m = r["memory"]
                memory_rows.append(f"| {title} | GraphSLAM | scans {m['scans'] / MIB:.0f}, open submap grid "
                                   f"{m['submap_grids'] / MIB:.0f}, finished submaps' obstacle cells "
                                   f"{m['closure_cells'] / MIB:.0f}, closure field cache {m['closure_fields'] / MIB:.0f}, "
                                   f"final map {r['map_bytes'] / MIB:.0f} |")
            else:
                rbpf_rows.append(f"| {title} | " + " | ".join(f"{t[s]:.2f}" for s in RBPF_STAGES) + " |")
                tiles = r["tiles"]
                memory_rows.append(f"| {title} | grid FastSLAM | tiles {tiles['bytes'] / MIB:.0f} ({tiles['distinct']} "
                                   f"distinct of {tiles['references']} held), final map {r['map_bytes'] / MIB:.0f} |")
    if not rows:
        print(f"bench_slam_cost: no raw log found under {LASER}; nothing to run")
        return
    if shutil.which("icp-slam") is None:
        notes.append("MRPT: `icp-slam` is not on PATH (Debian's mrpt-apps is not installed here): its rows are "
                     "skipped. issue 40's figures on ACES, measured elsewhere: icp-slam 2.8 CPU s (488x), "
                     "rbpf-slam 30 particles 19.5 CPU s (70x), 1.3 GB.")
    else:
        notes.append("MRPT: `icp-slam` is on PATH, but the CARMEN-to-rawlog converter its runs need is not "
                     "written yet (see the script's docstring): skipped.")
    title = "SLAM cost on raw laser logs" + (f" (first {args.scans} scans)" if args.scans else "")
    lines = heading(title, "Each run in a fresh process, one thread (runs gathered with --runs may have run side by "
                    "side; CPU s is each process's own).",
                    ["log", "method", "scans", "CPU s", "real time per core", "peak RSS",
                     "RSS after reading the log", "ACES relations error"])
    lines += rows
    if graph_rows:
        lines += ["", "GraphSLAM, processor seconds per stage (counts: frontend fields / closure fields built / "
                  "closure matches):", "", "| log | " + " | ".join(GRAPH_STAGES) + " | counts |",
                  "|" + "---|" * (len(GRAPH_STAGES) + 2), *graph_rows]
    if rbpf_rows:
        lines += ["", "Grid FastSLAM, processor seconds per stage (table_copies is part of map_update):", "",
                  "| log | " + " | ".join(RBPF_STAGES) + " |", "|" + "---|" * (len(RBPF_STAGES) + 1), *rbpf_rows]
    lines += ["", "What holds the memory at the end (MiB):", "", "| log | method | held |", "|---|---|---|",
              *memory_rows]
    lines += ["", *notes,
              f"Load average at the start: {load:.2f} (on {os.cpu_count()} cores; of the runs: "
              f"{', '.join(f'{v:.1f}' for v in run_loads)}); CPU s is processor time, "
              "which a shared machine's load inflates less than wall time. Real time per core = log duration / "
              "CPU s. Peak RSS: the whole process (Python, numpy, the log read: the column after it).",
              f"Command: `python benchmarks/bench_slam_cost.py --logs {' '.join(args.logs)} "
              f"--methods {' '.join(args.methods)}{f' --scans {args.scans}' if args.scans else ''}`.", ""]
    report(lines, record=args.record and not args.scans)


if __name__ == "__main__":
    main()
