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

MRPT (Debian's mrpt-apps 2.5.8) runs beside probslam when `icp-slam` / `rbpf-slam` are on PATH
(methods mrpt-icp, mrpt-rbpf; skipped with a note otherwise): icp-slam with its shipped
icp-slam_demo_classic.ini (no loop closure), rbpf-slam with gridmapping_optimal_sampling.ini and
30 particles, each only with its input, output directory and no windows / images / 3-D scenes
changed. Their input is written by probslam.io.mrpt_rawlog: MRPT 2.5.8's own
carmen2rawlog does not serve, as it stamps every observation with the conversion time, assumes
0.5 degree beams and an 81 m maximum range, and writes an observations-only rawlog rbpf-slam
cannot read; probslam.io.mrpt_rawlog writes action / sensory-frame pairs (the odometry increment, the
scan) with the FLASER timestamps, the log's 1 degree beams and max-range readings invalid. CPU s
and peak RSS are the MRPT process's own (os.wait4's resource usage; the conversion excluded);
the relations error scores MRPT's log_estimated_path.txt (its pose after each scan; for the RBPF
the particles' estimate at that step, as MRPT writes it).

    .venv/bin/python benchmarks/bench_slam_cost.py [--logs aces intel fr079]
        [--methods graph rbpf mrpt-icp mrpt-rbpf] [--scans N] [--record]

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
    options = ps.slam.default_options(log, method).replace(**METHODS[method])
    r = ps.slam.run_slam(log, progress=False, method=method, options=options)
    cpu = time.process_time() - c0
    out = dict(scans=len(log), cpu=cpu, wall=time.perf_counter() - w0, duration=r.log_duration,
               rss_read=after_read, rss_peak=peak_rss_mib(), timings=r.timings.as_dict(),
               memory=None if r.memory is None else r.memory.as_dict(),
               map_bytes=12.0 * r.grid.width * r.grid.height, relations=None)
    if method == "rbpf":
        out["tiles"] = dict(references=r.tile_sharing.references, distinct=r.tile_sharing.distinct,
                            bytes=r.tile_sharing.bytes)
    if name == "aces" and RELATIONS.exists():
        try:
            e = ps.eval.relations_error(r.timestamps, r.poses, ps.eval.relations_on_logger_time(RELATIONS, log))
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


MRPT_CONFIGS = pathlib.Path(os.environ.get("MRPT_CONFIG_FILES", "/usr/share/mrpt/config_files"))
#: MRPT's runs: (binary, shipped config, the settings changed besides input and output, label).
MRPT = {"mrpt-icp": ("icp-slam", "icp-slam/icp-slam_demo_classic.ini", {}, "MRPT icp-slam (no loop closure)"),
        "mrpt-rbpf": ("rbpf-slam", "rbpf-slam/gridmapping_optimal_sampling.ini",
                      {"sampleSize": 30, "verbosity_level": "INFO"},
                      "MRPT rbpf-slam, optimal sampling, 30 particles")}
#: Display and output switches turned off where a config has them: no windows, images or 3-D
#: scenes (the apps' own work is what is timed).
MRPT_QUIET = {"SHOW_PROGRESS_3D_REAL_TIME": 0, "SHOW_PROGRESS_IN_WINDOW": 0, "SAVE_3D_SCENE": 0,
              "SAVE_MAP_IMAGES": 0, "SAVE_POSE_LOG": 0, "LOG_FREQUENCY": 0}


def mrpt_config(template: pathlib.Path, out: pathlib.Path, values: dict, required=()) -> None:
    """Copy an MRPT .ini, setting the [MappingApplication] keys in `values` that it has (those in
    `required` must be there)."""
    import re

    lines, section, seen = [], None, set()
    for line in template.read_text().splitlines():
        head = re.match(r"\s*\[(.*)\]", line)
        key = re.match(r"\s*([A-Za-z_0-9]+)\s*=", line)
        if head:
            section = head.group(1)
        elif section == "MappingApplication" and key and key.group(1) in values:
            line = f"{key.group(1)}={values[key.group(1)]}"
            seen.add(key.group(1))
        lines.append(line)
    missing = set(required) - seen
    if missing:
        raise SystemExit(f"bench_slam_cost: {template} has no {sorted(missing)} in [MappingApplication]")
    out.write_text("\n".join(lines) + "\n")


def mrpt_available(method: str):
    """None if MRPT's `method` can run here, else why not."""
    binary, config = MRPT[method][:2]
    if shutil.which(binary) is None:
        return f"`{binary}` is not on PATH (Debian's mrpt-apps is not installed)"
    if not (MRPT_CONFIGS / config).exists():
        return f"{MRPT_CONFIGS / config} not found (Debian's mrpt-common holds MRPT's shipped configs)"
    return None


def mrpt_run(name: str, method: str, scans: int):
    """One MRPT run on the log converted by probslam.io.mrpt_rawlog; the measurements as run() returns."""
    import dataclasses
    import tempfile

    import numpy as np

    import probslam as ps
    import probslam.eval
    from probslam.geometry import compose
    from probslam.io.mrpt_rawlog import laser_mount, write_rawlog

    log = ps.io.read_carmen_log(LASER / LOGS[name][1]).scans
    if scans:
        log = ps.io.LaserScans(**{f.name: getattr(log, f.name)[:scans] for f in dataclasses.fields(log)})
    binary, config, settings, _ = MRPT[method]
    with tempfile.TemporaryDirectory(prefix="bench_slam_cost_mrpt_") as tmp:
        tmp = pathlib.Path(tmp)
        rawlog, ini, output = tmp / f"{name}.rawlog", tmp / "config.ini", tmp / "out"
        with open(rawlog, "wb") as f:
            write_rawlog(log, f)
        mrpt_config(MRPT_CONFIGS / config, ini, dict(MRPT_QUIET, rawlog_file=rawlog, logOutput_dir=output, **settings),
                    required=["rawlog_file", "logOutput_dir", *settings])
        with open(tmp / "console.txt", "wb") as console:
            w0 = time.perf_counter()
            child = subprocess.Popen([binary, str(ini)], stdout=console, stderr=subprocess.STDOUT, cwd=tmp)
            # The child's own resource usage (its CPU time and peak RSS), not the sum over this
            # script's children that RUSAGE_CHILDREN would give.
            _, status, usage = os.wait4(child.pid, 0)
            wall = time.perf_counter() - w0
        child.returncode = os.waitstatus_to_exitcode(status)
        if child.returncode != 0:
            print((tmp / "console.txt").read_text(errors="replace")[-3000:], file=sys.stderr)
            raise SystemExit(f"bench_slam_cost: {binary} on {name} failed ({child.returncode})")
        # Rows: step (the rawlog's action / sensory-frame pair, i.e. the scan), x, y, heading
        # (icp-slam: step x y phi; rbpf-slam: step x y z yaw pitch roll time).
        path = np.loadtxt(output / "log_estimated_path.txt", ndmin=2)
    steps = path[:, 0].astype(int)
    robot = path[:, [1, 2, 3 if path.shape[1] == 4 else 4]]
    out = dict(scans=len(log), cpu=usage.ru_utime + usage.ru_stime, wall=wall,
               duration=float(log.timestamps[-1] - log.timestamps[0]), rss_read=None,
               rss_peak=usage.ru_maxrss / 1024.0, relations=None, path_rows=len(steps))
    if name == "aces" and RELATIONS.exists():
        try:
            poses = compose(robot, laser_mount(log))
            e = ps.eval.relations_error(log.timestamps[steps], poses, ps.eval.relations_on_logger_time(RELATIONS, log))
            out["relations"] = [e.trans_mean, e.trans_std, len(e.used)]
        except ValueError:
            pass
    return out


GRAPH_STAGES = ("filter", "match", "insert", "closure_search", "closure_fields", "optimize", "final_map")
RBPF_STAGES = ("filter", "corrector", "proposal", "resample", "map_update", "table_copies", "final_map")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--logs", nargs="+", choices=list(LOGS), default=list(LOGS))
    parser.add_argument("--methods", nargs="+", choices=[*METHODS, *MRPT], default=[*METHODS, *MRPT])
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
    mrpt_skipped = set()
    for name in args.logs:
        title, raw = LOGS[name]
        if not (LASER / raw).exists():
            notes.append(f"{title}: {LASER / raw} not found; skipped.")
            continue
        for method in args.methods:
            r = saved.get((name, method, args.scans))
            if r is None and method in MRPT and method not in mrpt_skipped and mrpt_available(method):
                mrpt_skipped.add(method)
                notes.append(f"{MRPT[method][3]}: {mrpt_available(method)}; its rows are skipped.")
            if r is None and method in mrpt_skipped:
                continue
            if r is None:
                print(f"bench_slam_cost: {title} {method} ...", file=sys.stderr, flush=True)
                measured = mrpt_run(name, method, args.scans) if method in MRPT else run(name, method, args.scans)
                r = dict(measured, log=name, method=method, scans_asked=args.scans, load=os.getloadavg()[0])
                if args.runs is not None:
                    with open(args.runs, "a") as f:
                        f.write(json.dumps(r) + "\n")
            run_loads.append(r.get("load", load))
            rel = f"{r['relations'][0]:.3f} m" if r["relations"] else "-"
            if method in MRPT:
                rows.append(f"| {title} | {MRPT[method][3]} | {r['scans']} | {r['cpu']:.1f} | "
                            f"{r['duration'] / r['cpu']:.0f}x | {r['rss_peak']:.0f} MB | - | {rel} |")
                continue
            t = r["timings"]
            label = "GraphSLAM" if method == "graph" else "grid FastSLAM, 30 particles"
            rows.append(f"| {title} | {label} | {r['scans']} | {r['cpu']:.1f} | {r['duration'] / r['cpu']:.0f}x | "
                        f"{r['rss_peak']:.0f} MB | {r['rss_read']:.0f} MB | {rel} |")
            if method == "graph":
                graph_rows.append(f"| {title} | " + " | ".join(f"{t[s]:.2f}" for s in GRAPH_STAGES) +
                                  f" | {t['frontend_fields']} / {t['closure_fields_built']} / {t['closure_matches']}"
                                  f" / {t.get('frontend_local', '-')} / {t.get('frontend_searches', '-')} |")
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
    title = "SLAM cost on raw laser logs" + (f" (first {args.scans} scans)" if args.scans else "")
    lines = heading(title, "Each run in a fresh process, one thread (runs gathered with --runs may have run side by "
                    "side; CPU s is each process's own).",
                    ["log", "method", "scans", "CPU s", "real time per core", "peak RSS",
                     "RSS after reading the log", "ACES relations error"])
    lines += rows
    if graph_rows:
        lines += ["", "GraphSLAM, processor seconds per stage (counts: frontend fields / closure fields built / "
                  "closure matches / scans the frontend matched locally / by the search):", "", "| log | " + " | ".join(GRAPH_STAGES) + " | counts |",
                  "|" + "---|" * (len(GRAPH_STAGES) + 2), *graph_rows]
    if rbpf_rows:
        lines += ["", "Grid FastSLAM, processor seconds per stage (table_copies is part of map_update):", "",
                  "| log | " + " | ".join(RBPF_STAGES) + " |", "|" + "---|" * (len(RBPF_STAGES) + 1), *rbpf_rows]
    if memory_rows:
        lines += ["", "What holds the memory at the end (MiB):", "", "| log | method | held |", "|---|---|---|",
                  *memory_rows]
    lines += ["", *notes,
              f"Load average at the start: {load:.2f} (on {os.cpu_count()} cores; of the runs: "
              f"{', '.join(f'{v:.1f}' for v in run_loads)}); CPU s is processor time, "
              "which a shared machine's load inflates less than wall time. Real time per core = log duration / "
              "CPU s. Peak RSS: the whole process (Python, numpy, the log read: the column after it; MRPT's rows: "
              "the MRPT process, which reads the rawlog probslam.io.mrpt_rawlog wrote).",
              f"Command: `python benchmarks/bench_slam_cost.py --logs {' '.join(args.logs)} "
              f"--methods {' '.join(args.methods)}{f' --scans {args.scans}' if args.scans else ''}`.", ""]
    report(lines, record=args.record and not args.scans)


if __name__ == "__main__":
    main()
