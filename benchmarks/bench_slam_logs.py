"""SLAM on the raw laser logs: probslam.slam.run_slam with its default options on each raw CARMEN
log of ../shared/data/laser_2d (ACES, Intel, FR079, MIT CSAIL), one after the other, one thread.

Per log: scans, submaps, loop closures (accepted, i.e. active at the end / rejected / dissolved),
processing seconds (reading the log not included: run_slam's own clock, from the first scan to
the map), the log's duration and the real-time factor (duration / processing time on one core).

Accuracy, for the GraphSLAM trajectory (result.poses) and for incremental scan matching alone
(result.frontend_poses):
- ACES: the relations error of Kuemmerle et al. 2009 against aces.relations
  (probslam.eval.relations_error; translational mean +- std m, rotational mean +- std deg).
- Intel, FR079: agreement with the folder's corrected log (another system's output, GMapping-style;
  a reference, not ground truth). A corrected scan is paired with the raw scan of identical range
  vector whose logger timestamp (last field of a CARMEN line) is within 0.01 s of its own (the
  corrected logs print 6 significant digits; Intel's raw timestamps are not monotonic, so the
  timestamp alone is not used). The SLAM positions are aligned to the corrected ones by the best
  rigid 2-D transform (Kabsch / Umeyama without scale); reported: mean / median / max position
  error and mean / median heading error after that alignment. When no pair is found the output
  says so.

    .venv/bin/python benchmarks/bench_slam_logs.py [--logs aces intel fr079 mit_csail]
        [--figures DIR] [--quick] [--record]

--figures DIR writes DIR/slam_<log>.png (probslam.io.write_png of the map with the GraphSLAM
trajectory in red). --quick runs the first 1500 scans of each log (a CI-time check; not recorded).
Missing logs are skipped with a message.
"""

import argparse
import bz2
import dataclasses
import gzip
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
LASER = SHARED / "laser_2d"

#: name -> (title, raw log, relations file or None, corrected log for the agreement or None)
LOGS = {
    "aces": ("ACES", "aces/aces.clf.bz2", "aces/aces.relations", None),
    "intel": ("Intel", "intel/intel.clf", None, "intel/intel-corrected.log.gz"),
    "fr079": ("FR079", "fr079/fr079.clf.bz2", None, "fr079/freiburg-079-corrected.log.gz"),
    "mit_csail": ("MIT CSAIL", "mit_csail/mit-csail.clf.bz2", None, None),
}
QUICK_SCANS = 1500
#: Relations spanning less than this (s) are "short": consecutive-scan geometry, no loop in them.
SHORT_RELATION = 1.0
#: Largest |logger timestamp difference| of a corrected scan and its raw twin (s).
PAIR_TOLERANCE = 0.01


def first_scans(scans: ps.io.LaserScans, n: int) -> ps.io.LaserScans:
    """The first n scans: every field of LaserScans is an array with one row per scan."""
    return ps.io.LaserScans(**{f.name: getattr(scans, f.name)[:n] for f in dataclasses.fields(scans)})


# --- pairing with a corrected log -------------------------------------------------------------

def logger_timestamps(path: pathlib.Path) -> np.ndarray:
    """The logger timestamp (last field) of every FLASER line, in file order."""
    opener = bz2.open if path.suffix == ".bz2" else gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as f:
        return np.array([float(line.rsplit(None, 1)[1]) for line in f if line.startswith("FLASER ")])


def pair_scans(raw_path, raw_scans, corrected_path):
    """(raw indices, corrected laser poses, corrected scan count, note): the corrected scans that
    have exactly one raw scan with identical ranges and logger timestamp within PAIR_TOLERANCE."""
    corrected = ps.io.read_carmen_log(corrected_path).scans
    t_raw, t_cor = logger_timestamps(raw_path), logger_timestamps(corrected_path)
    if len(t_raw) != len(raw_scans) or len(t_cor) != len(corrected):
        return None, None, len(corrected), (f"FLASER lines ({len(t_raw)}, {len(t_cor)}) differ from the scans read "
                                            f"({len(raw_scans)}, {len(corrected)}): pairing not attempted")
    if raw_scans.ranges.shape[1] != corrected.ranges.shape[1]:
        return None, None, len(corrected), "beam counts differ: pairing not possible"
    by_ranges = {}
    for i, r in enumerate(raw_scans.ranges):
        by_ranges.setdefault(r.tobytes(), []).append(i)
    raw_index, cor_index, ambiguous = [], [], 0
    for k, r in enumerate(corrected.ranges):
        near = [i for i in by_ranges.get(r.tobytes(), ()) if abs(t_raw[i] - t_cor[k]) <= PAIR_TOLERANCE]
        if len(near) == 1:
            raw_index.append(near[0])
            cor_index.append(k)
        ambiguous += len(near) > 1
    note = f"{len(raw_index)}/{len(corrected)} corrected scans paired"
    if ambiguous:
        note += f", {ambiguous} ambiguous left out"
    return np.array(raw_index, int), corrected.laser_poses[cor_index], len(corrected), note


def relations_breakdown(timestamps, poses, rel):
    """Where a trajectory's relations error comes from: mean translational error (m) of the short
    (|t2 - t1| < SHORT_RELATION) and the other relations, and for the short ones the mean absolute
    error along the reference displacement and across it."""
    e = ps.eval.relations_error(timestamps, poses, rel)
    t1, t2, ref = rel.t1[e.used], rel.t2[e.used], rel.delta[e.used]
    x1, x2 = (ps.eval.interpolate_poses(timestamps, poses, t) for t in (t1, t2))
    err = ps.eval.relative_poses(x1, x2)[:, :2] - ref[:, :2]
    u = ref[:, :2] / np.maximum(np.linalg.norm(ref[:, :2], axis=1, keepdims=True), 1e-12)
    along, across = np.abs(np.sum(err * u, axis=1)), np.abs(err[:, 1] * u[:, 0] - err[:, 0] * u[:, 1])
    short = np.abs(t2 - t1) < SHORT_RELATION
    mean = lambda v: float(v.mean()) if v.size else float("nan")
    return (f"short ({short.sum()}): {mean(e.translational[short]):.3f} m (along {mean(along[short]):.3f}, "
            f"across {mean(across[short]):.3f}); longer ({(~short).sum()}): {mean(e.translational[~short]):.3f} m")


def agreement(poses: np.ndarray, reference: np.ndarray):
    """Position errors (m) and absolute heading errors (rad) after the best rigid alignment."""
    r, t = ps.eval.align_rigid(poses[:, :2], reference[:, :2])
    pos = np.linalg.norm(poses[:, :2] @ r.T + t - reference[:, :2], axis=1)
    head = np.abs(ps.wrap_angle(poses[:, 2] + np.arctan2(r[1, 0], r[0, 0]) - reference[:, 2]))
    return pos, head


# --- the run ----------------------------------------------------------------------------------

def run_log(name, quick, figures, method="graph", options=None):
    """(row of the run table, rows of the accuracy table, notes), or None when the log is absent."""
    title, raw, relations, corrected = LOGS[name]
    path = LASER / raw
    if not path.exists():
        print(f"bench_slam_logs: {path} not found; {title} skipped")
        return None
    log = ps.io.read_carmen_log(path)
    scans = first_scans(log.scans, QUICK_SCANS) if quick else log.scans
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
    trajectories = ([("grid FastSLAM", result.poses)] if method == "rbpf" else
                    [("GraphSLAM", result.poses), ("scan matching alone", result.frontend_poses)])
    acc = []
    if relations is not None:
        rel = LASER / relations
        if rel.exists():
            # aces.relations is stamped with the raw log's ipc time, the scans with its logger time.
            relations_file = ps.eval.relations_on_logger_time(rel, scans)
            breakdown = []
            for label, poses in trajectories + [("raw odometry", scans.laser_poses)]:
                e = ps.eval.relations_error(result.timestamps, poses, relations_file)
                acc.append(f"| {title} | {label} | relations ({rel.name}) | {len(e.used)} used, {e.skipped} skipped | "
                           f"{e.trans_mean:.3f} +- {e.trans_std:.3f} m (mean +- std) | "
                           f"{e.rot_mean_deg:.2f} +- {e.rot_std_deg:.2f} deg (mean +- std) |")
                breakdown.append(f"{label}: " + relations_breakdown(result.timestamps, poses, relations_file))
            notes.append(f"{title} relations by span (< {SHORT_RELATION:g} s is short; along / across the reference "
                         "displacement): " + "; ".join(breakdown) + ".")
        else:
            notes.append(f"{title}: {rel} not found; relations error skipped.")
    if corrected is not None:
        cor = LASER / corrected
        if not cor.exists():
            notes.append(f"{title}: {cor} not found; no agreement with a corrected log.")
        else:
            raw_index, reference, total, note = pair_scans(path, log.scans, cor)
            if raw_index is not None:
                keep = raw_index < len(scans)  # --quick: the pairs within the scans run
                raw_index, reference = raw_index[keep], reference[keep]
                if not keep.all():
                    note += f" ({len(raw_index)} within the scans run)"
            if raw_index is None or len(raw_index) < 3:
                notes.append(f"{title}: pairing with {cor.name} not possible ({note}); no agreement reported.")
            else:
                notes.append(f"{title}: {note} with {cor.name} (identical ranges, logger timestamps within "
                             f"{PAIR_TOLERANCE} s).")
                for label, poses in trajectories:
                    pos, head = agreement(poses[raw_index], reference)
                    acc.append(f"| {title} | {label} | corrected log ({cor.name}), rigid 2-D alignment | "
                               f"{len(raw_index)} scans | mean {pos.mean():.3f} / median {np.median(pos):.3f} / "
                               f"max {pos.max():.3f} m | mean {np.degrees(head.mean()):.2f} / median "
                               f"{np.degrees(np.median(head)):.2f} deg |")
    return run_row, acc, notes


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
    import ast

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
    runs, acc, notes = [], [], []
    for name in args.logs:
        out = run_log(name, args.quick, args.figures, args.method, options)
        if out is None:
            notes.append(f"{LOGS[name][0]}: {LASER / LOGS[name][1]} not found; skipped.")
            continue
        runs.append(out[0])
        acc += out[1]
        notes += out[2]
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
    if acc:
        lines += ["", "| log | trajectory | reference | compared | translational | rotational |", "|---|---|---|---|---|---|",
                  *acc]
    lines += ["", *notes,
              f"Load average at the start: {load:.2f} (on {os.cpu_count()} cores). Processing time: run_slam's clock "
              "(matching, closures, optimisation, the final map), reading the log excluded; real-time factor = log "
              "duration / processing time.",
              "Closures: accepted = active at the end; rejected = failed the quality or consistency test; dissolved "
              "= added, then undone by the optimised graph.",
              *(["Corrected logs are another SLAM system's result (GMapping-style), not ground truth; their poses "
                 "are compared as laser poses (FR079's raw log has the laser 0.04 m from the robot pose, so up to that "
                 "much of the FR079 position error may be the convention)."] if any("corrected log" in r for r in acc)
                else []),
              f"Command: `python benchmarks/bench_slam_logs.py{' --quick' if args.quick else ''}"
              f"{' --method ' + args.method if args.method != 'graph' else ''}"
              f"{''.join(' --option ' + o for o in args.option)}"
              f" --logs {' '.join(args.logs)}{' --figures ' + str(shown) if shown else ''}`.", ""]
    report(lines, record=args.record and not args.quick)


if __name__ == "__main__":
    main()
