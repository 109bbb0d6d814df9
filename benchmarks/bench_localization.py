"""Monte Carlo localization (probslam.localize) of the raw laser logs in the maps probslam built.

For each log (ACES, Intel, FR079 of ../shared/data/laser_2d) the map and the SLAM trajectory come
from ``probslam slam LOG -o MAPS/<name>`` (MAPS/<name>.yaml and MAPS/<name>_trajectory.tum, one
row per scan; made here when missing). The SLAM trajectory is the reference: the map is in its
frame, so no alignment is applied.

- Tracking: the whole raw log from the SLAM start pose; ATE against the SLAM trajectory
  (probslam.eval.ate, align="none"), the real-time factor on one core (log duration / localize's
  processing time), particles over time (KLD sampling: median, max, last).
- Global: --segments random start scans per log (seeded), each run for --segment-seconds of log
  from a global start (no pose). A run converged when the position error against the SLAM pose
  falls below CONVERGED_ERROR m (and the heading's below CONVERGED_HEADING rad) and stays there to
  the segment's end; reported: the fraction converged, median / max log time and travel to converge.
- Kidnapped robot: a log cut at two places and spliced (the second piece's odometry continued from
  the first's end, so odometry does not see the jump) while the true pose jumps; the filter tracks
  from the true start; time (s of log) and travel to recover (the same criterion after the jump).

- Beam model: the tracking run again with sensor_model="beam" (Table 6.1 on the ray walk).

    .venv/bin/python benchmarks/bench_localization.py [--logs aces intel fr079] [--maps DIR]
        [--segments 20] [--segment-seconds 120] [--option KEY=VALUE ...] [--record]

``--option`` passes a MonteCarloLocalization keyword to every run (e.g. recovery_ratio=0.7), for
comparing settings on the same runs; the last line printed sums a run up for such comparisons.

Missing logs are skipped with a message.
"""

import argparse
import dataclasses
import os
import pathlib
import subprocess
import sys
import time

import numpy as np

import probslam as ps
import probslam.eval
from common import heading, report

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
LASER = SHARED / "laser_2d"
LOGS = {
    "aces": ("ACES", "aces/aces.clf.bz2"),
    "intel": ("Intel", "intel/intel.clf"),
    "fr079": ("FR079", "fr079/fr079.clf.bz2"),
}
#: A localization counts as right when within this of the SLAM pose (m, rad): a few map cells
#: and a few degrees, well inside the corridors' width, far below a wrong room's distance.
CONVERGED_ERROR = 0.5
CONVERGED_HEADING = 0.2


def subset(scans, idx):
    """The scans at indices idx (every LaserScans field has one row per scan)."""
    return ps.io.LaserScans(**{f.name: getattr(scans, f.name)[idx] for f in dataclasses.fields(scans)})


def errors(poses, ref):
    pos = np.hypot(poses[:, 0] - ref[:, 0], poses[:, 1] - ref[:, 1])
    head = np.abs(ps.wrap_angle(poses[:, 2] - ref[:, 2]))
    return pos, head


def mcl_options(scans, **fields):
    """The filter's options for the log (its no-return reading as max_range) with ``fields`` set."""
    return ps.localization.default_options(scans).replace(**fields)


def track(scans, grid, ref, t, opts):
    """Tracking from the SLAM trajectory's first pose: the result, its ATE against the SLAM
    trajectory (no alignment), position and heading errors per scan, particles per update."""
    r = ps.localize(scans, grid, initial_pose=ref[0], progress=False, options=mcl_options(scans, seed=1, **opts))
    ate = probslam.eval.ate(r.timestamps, r.poses, t, ref, align="none")
    pos, head = errors(r.poses, ref)
    return r, ate, pos, head, r.num_particles


def settled_index(pos, head):
    """First index from which the estimate stays right to the end; None if the last is wrong."""
    bad = np.flatnonzero((pos >= CONVERGED_ERROR) | (head >= CONVERGED_HEADING))
    k = 0 if bad.size == 0 else int(bad[-1]) + 1
    return k if k < len(pos) else None


def travel(odom, k):
    d = np.diff(odom[:k + 1, :2], axis=0)
    return float(np.sum(np.hypot(d[:, 0], d[:, 1])))


def compose(a, b):
    """a (3,) composed with each row of b (n, 3)."""
    c, s = np.cos(a[2]), np.sin(a[2])
    return np.stack([a[0] + c * b[:, 0] - s * b[:, 1], a[1] + s * b[:, 0] + c * b[:, 1],
                     ps.wrap_angle(a[2] + b[:, 2])], axis=1)


def relative(a, b):
    """Each row of b (n, 3) in the frame of a (3,)."""
    c, s = np.cos(a[2]), np.sin(a[2])
    dx, dy = b[:, 0] - a[0], b[:, 1] - a[1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, ps.wrap_angle(b[:, 2] - a[2])], axis=1)


def span_end(t, start, seconds):
    """Index one past the last scan within `seconds` of scan `start` (timestamps may jump back)."""
    k = start
    elapsed = 0.0
    while k + 1 < len(t) and elapsed < seconds:
        step = t[k + 1] - t[k]
        elapsed += step if 0 < step < 5.0 else 0.0  # a clock jump counts as nothing
        k += 1
    return k + 1


def maps_for(name, path, maps: pathlib.Path):
    prefix = maps / name
    if not (prefix.with_suffix(".yaml").exists() and pathlib.Path(f"{prefix}_trajectory.tum").exists()):
        print(f"{name}: running probslam slam (map and reference trajectory)", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "probslam", "slam", str(path), "-o", str(prefix), "--no-progress",
                        "--no-plot"], check=True)
    grid = ps.io.load_ros_map(f"{prefix}.yaml")
    traj = ps.io.read_trajectory(f"{prefix}_trajectory.tum")
    return grid, traj.poses


def run(args):
    maps = pathlib.Path(args.maps)
    maps.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    track_rows, beam_rows, global_rows, kidnap_rows, notes, summary = [], [], [], [], [], []
    opts = {}
    for kv in args.option:
        key, _, value = kv.partition("=")
        try:
            opts[key] = int(value)
        except ValueError:
            try:
                opts[key] = float(value)
            except ValueError:
                opts[key] = value
    load0 = os.getloadavg()[0]
    for name in args.logs:
        title, rel = LOGS[name]
        path = LASER / rel
        if not path.exists():
            print(f"{title}: {path} missing, skipped", file=sys.stderr)
            continue
        grid, ref = maps_for(name, path, maps)
        scans = ps.io.read_carmen_scans(path).scans
        if len(ref) != len(scans):
            notes.append(f"{title}: {len(ref)} SLAM poses for {len(scans)} scans: skipped")
            continue
        t = scans.timestamps
        # ---- tracking ----
        r, ate, pos, head, n = track(scans, grid, ref, t, opts)
        track_rows.append(f"| {title} | {len(scans)} | {ate.rmse:.3f} / {np.median(pos):.3f} / {pos.max():.3f} | "
                          f"{np.degrees(np.median(head)):.2f} | {int(np.median(n))} / {int(n.max())} / {int(n[-1])} | "
                          f"{r.seconds:.1f} | {r.log_duration:.0f} | {r.real_time_factor:.0f}x |")
        summary.append(f"{title}: track max {pos.max():.2f}")
        # ---- the beam model (Table 6.1), same run ----
        if not args.no_beam:
            rb, ateb, posb, headb, nb = track(scans, grid, ref, t, {"sensor_model": "beam", **opts})
            beam_rows.append(f"| {title} | {ateb.rmse:.3f} / {np.median(posb):.3f} / {posb.max():.3f} | "
                             f"{np.degrees(np.median(headb)):.2f} | {int(np.median(nb))} / {int(nb.max())} | "
                             f"{rb.seconds:.1f} | {rb.real_time_factor:.0f}x |")
        # ---- global, from random segments ----
        starts = rng.integers(0, max(1, len(scans) - 50), args.segments)
        done, times, travels, secs, log_secs = 0, [], [], 0.0, 0.0
        for s in starts:
            e = span_end(t, int(s), args.segment_seconds)
            idx = np.arange(int(s), e)
            g = ps.localize(subset(scans, idx), grid, progress=False, options=mcl_options(scans, seed=int(s), **opts))
            secs += g.seconds
            log_secs += g.log_duration
            pos, head = errors(g.poses, ref[idx])
            k = settled_index(pos, head)
            if k is not None:
                done += 1
                times.append(float(g.timestamps[k] - g.timestamps[0]))
                travels.append(travel(scans.laser_poses[idx], k))
        med = f"{np.median(times):.1f} / {max(times):.1f}" if times else "-"
        medt = f"{np.median(travels):.1f} / {max(travels):.1f}" if travels else "-"
        summary.append(f"global {done}/{args.segments}")
        global_rows.append(f"| {title} | {args.segments} x {args.segment_seconds:.0f} s | {done} / {args.segments} "
                           f"({100.0 * done / args.segments:.0f}%) | {med} | {medt} | "
                           f"{log_secs / secs if secs else 0:.0f}x |")
        # ---- kidnapped robot: splice two pieces far apart ----
        a = len(scans) // 5
        b = (3 * len(scans)) // 5
        ea = span_end(t, a, args.segment_seconds)
        eb = span_end(t, b, args.segment_seconds)
        i1, i2 = np.arange(a, ea), np.arange(b, eb)
        s1, s2 = subset(scans, i1), subset(scans, i2)
        odo2 = compose(s1.laser_poses[-1], relative(s2.laser_poses[0], s2.laser_poses))
        t2 = s2.timestamps - s2.timestamps[0] + s1.timestamps[-1] + 0.1
        spliced = ps.io.LaserScans(**{f.name: np.concatenate([getattr(s1, f.name), getattr(s2, f.name)])
                                      for f in dataclasses.fields(s1)})
        spliced.laser_poses[len(i1):] = odo2
        spliced.robot_poses[len(i1):] = odo2
        spliced.timestamps[len(i1):] = t2
        truth = np.concatenate([ref[i1], ref[i2]])
        kr = ps.localize(spliced, grid, initial_pose=truth[0], progress=False,
                        options=mcl_options(spliced, seed=3, **opts))
        pos, head = errors(kr.poses, truth)
        jump = float(np.hypot(*(truth[len(i1)] - truth[len(i1) - 1])[:2]))
        before_ok = bool(np.median(pos[:len(i1)]) < CONVERGED_ERROR)
        k = settled_index(pos[len(i1):], head[len(i1):])
        if k is None:
            rec = "not recovered"
        else:
            rec = (f"{kr.timestamps[len(i1) + k] - kr.timestamps[len(i1)]:.1f} s, "
                   f"{travel(odo2, k):.1f} m")
        summary.append(f"kidnap {rec}")
        kidnap_rows.append(f"| {title} | {jump:.1f} m | {'yes' if before_ok else 'no'} | {rec} | "
                           f"{int(kr.num_particles.max())} |")
    lines = heading("Monte Carlo localization on raw laser logs",
                    "probslam.localize with default options (likelihood field, KLD sampling 500-20000 "
                    "particles, augmented MCL), one thread; maps and reference trajectories from `probslam slam`.",
                    ["log", "scans", "ATE rmse / median / max (m)", "median heading error (deg)",
                     "particles median / max / last", "processing (s)", "log duration (s)", "real-time factor"])
    lines += track_rows
    if beam_rows:
        lines += ["", "Beam model (`sensor_model=\"beam\"`), the tracking runs above:", "",
                  "| log | ATE rmse / median / max (m) | median heading error (deg) | particles median / max | "
                  "processing (s) | real-time factor |", "|---|---|---|---|---|---|"]
        lines += beam_rows
    lines += ["", "| log | global runs | converged | time to converge median / max (s) | "
              "travel to converge median / max (m) | real-time factor |", "|---|---|---|---|---|---|"]
    lines += global_rows
    lines += ["", "| log | kidnapping jump | tracking before | recovery (log time, travel) | max particles |",
              "|---|---|---|---|---|"]
    lines += kidnap_rows
    lines += [""] + notes + [
        f"Load average at the start: {load0:.2f} (on 2 cores). Tracking starts at the SLAM trajectory's first pose; "
        f"ATE is against the SLAM trajectory without alignment (the map is in its frame). Converged: within "
        f"{CONVERGED_ERROR} m and {CONVERGED_HEADING} rad of the SLAM pose from then to the segment's end. Global "
        f"segments start at random scans (seed {args.seed}). Kidnapping: scans at 1/5 and 3/5 of the log, "
        f"{args.segment_seconds:.0f} s each, the second piece's odometry continued from the first's end.",
        f"Command: `python benchmarks/bench_localization.py --logs {' '.join(args.logs)} --segments {args.segments} "
        f"--segment-seconds {args.segment_seconds:g}"
        + "".join(f" --option {kv}" for kv in args.option) + "`."]
    report(lines, args.record)
    print("summary:", " ".join(args.option) or "defaults", "|", "; ".join(summary))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--logs", nargs="+", choices=sorted(LOGS), default=["aces", "intel", "fr079"])
    p.add_argument("--maps", default="/tmp/probslam_localization_maps",
                   help="folder of <log>.yaml and <log>_trajectory.tum from probslam slam (made when missing)")
    p.add_argument("--segments", type=int, default=20)
    p.add_argument("--segment-seconds", type=float, default=120.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="a MonteCarloLocalization keyword for every run (repeatable)")
    p.add_argument("--no-beam", action="store_true", help="skip the beam model's tracking run")
    p.add_argument("--record", action="store_true")
    run(p.parse_args())


if __name__ == "__main__":
    main()
