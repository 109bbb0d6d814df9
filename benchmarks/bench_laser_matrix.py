"""probslam's laser SLAM over simulated robots x worlds x odometry kinds (issue 51).

Each cell: ``probslam.sim_laser.simulate(world, sensor, odometry, seed)`` (a loop through the world,
exact ground truth), then ``probslam.slam.run_slam`` with its default options, ``method`` graph
and rbpf (rbpf needs odometry: "-" for kind none). Printed per cell: ATE (``probslam.eval.ate``,
SE(2) alignment, evo's APE rmse, m) of each method against the truth, the odometry alone's ATE
beside them, the scale of the result (the similarity that best maps it onto the truth: 1.25 for
a map 20 % too small), GraphSLAM's closures (active / rejected / dissolved) and the CPU seconds per log
(``time.process_time`` around run_slam: all threads of the process).

    .venv/bin/python benchmarks/bench_laser_matrix.py [--full] [--robots ...] [--worlds ...]
        [--odometry ...] [--methods graph rbpf] [--seed N] [--record]

The default matrix (a few minutes on one core): the Stage-like, LDS and SICK robots in the office
and the repeated world, every odometry kind. --full: every sensor, world and kind.
"""

import argparse
import os
import pathlib
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from common import heading, report  # noqa: E402

import probslam as ps  # noqa: E402
from probslam import sim_laser  # noqa: E402
from probslam.eval import associate, ate  # noqa: E402

DEFAULT = dict(robots=["stage", "lds", "sick"], worlds=["office", "repeated"],
               odometry=["none", "perfect", "good", "poor"])


def similarity_scale(times, poses, truth_times, truth) -> float:
    """The scale of the similarity (Umeyama with scale, in 2-D) that best maps the estimated
    positions onto the true ones at the same times: > 1 where the estimate is too small."""
    ia, ib = associate(times, truth_times)
    e = poses[ia, 0] + 1j * poses[ia, 1]
    r = truth[ib, 0] + 1j * truth[ib, 1]
    e, r = e - e.mean(), r - r.mean()
    return float(abs(np.vdot(e, r)) / np.vdot(e, e).real)


def run_cell(robot: str, world: str, odometry: str, methods, seed: int):
    sim = sim_laser.simulate(world, robot, odometry, seed=seed)
    scans = sim.scans()
    truth_len = float(np.hypot(*np.diff(sim.truth[:, :2], axis=0).T).sum())
    cells = {}
    if odometry != "none":
        cells["odometry"] = ate(sim.timestamps, sim.odometry, sim.timestamps, sim.truth).rmse
    for method in methods:
        if method == "rbpf" and odometry == "none":
            continue
        cpu = time.process_time()
        result = ps.slam.run_slam(scans, method=method, progress=False)
        cpu = time.process_time() - cpu
        err = ate(result.timestamps, result.poses, sim.timestamps, sim.truth)
        closures = ""
        if method == "graph":
            s = result.summary
            closures = f"{s.closures_accepted} / {s.closures_rejected} / {s.closures_dissolved}"
        scale = similarity_scale(result.timestamps, result.poses, sim.timestamps, sim.truth)
        cells[method] = (err.rmse, err.max, scale, cpu, closures)
    return len(scans), truth_len, cells


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--full", action="store_true", help="every sensor, world and odometry kind")
    parser.add_argument("--robots", nargs="+", choices=list(sim_laser.SENSORS))
    parser.add_argument("--worlds", nargs="+", choices=list(sim_laser.WORLDS))
    parser.add_argument("--odometry", nargs="+", choices=list(sim_laser.ODOMETRY))
    parser.add_argument("--methods", nargs="+", choices=list(ps.slam.METHODS), default=list(ps.slam.METHODS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md")
    args = parser.parse_args()
    pick = {k: (list(getattr(sim_laser, {"robots": "SENSORS", "worlds": "WORLDS", "odometry": "ODOMETRY"}[k]))
                if args.full else v) for k, v in DEFAULT.items()}
    for k in pick:
        if getattr(args, k):
            pick[k] = getattr(args, k)
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=pathlib.Path(__file__).parent).stdout.strip() or "unknown"
    except OSError:
        commit = "unknown"
    load = os.getloadavg()[0]
    rows = []
    for robot in pick["robots"]:
        for world in pick["worlds"]:
            for kind in pick["odometry"]:
                n, length, cells = run_cell(robot, world, kind, args.methods, args.seed)
                row = [robot, world, kind, str(n), f"{length:.0f}",
                       f"{cells['odometry']:.3f}" if "odometry" in cells else "-"]
                for m in args.methods:
                    if m in cells:
                        rmse, mx, scale, cpu, closures = cells[m]
                        row += [f"{rmse:.3f} ({mx:.2f})", f"{scale:.3f}", f"{cpu:.1f}"]
                        if m == "graph":
                            row.append(closures)
                    else:
                        row += ["-", "-", "-"] + (["-"] if m == "graph" else [])
                rows.append("| " + " | ".join(row) + " |")
                print(rows[-1], flush=True)
    columns = ["robot", "world", "odometry", "scans", "path (m)", "odometry ATE (m)"]
    for m in args.methods:
        columns += [f"{m} ATE rmse (max) m", f"{m} scale", f"{m} CPU (s)"] + (["closures a / r / d"]
                                                                            if m == "graph" else [])
    # A run over another selection is its own RESULTS.md record (--record replaces by title).
    chosen = any(getattr(args, k) for k in ("robots", "worlds", "odometry"))
    title = "Laser SLAM on simulated robots" + (" (full matrix)" if args.full else "") + \
        (f" ({'; '.join(', '.join(pick[k]) for k in ('robots', 'worlds', 'odometry'))})" if chosen else "")
    lines = heading(title, f"Commit {commit}; probslam.sim_laser seed {args.seed}; probslam.slam.run_slam with "
                    "its default options.", columns)
    lines += rows
    lines += ["", "ATE: evo's APE rmse (and max) after SE(2) alignment against the exact truth; odometry ATE: the "
              "odometry alone. Scale: of the similarity that best maps the estimate onto the truth (> 1: the "
              "estimate is too small). CPU: process seconds of "
              "run_slam (every thread). Closures: active at the end / rejected / dissolved.",
              "Robots (probslam.sim_laser.SENSORS): stage 270 deg / 90 beams / 5 m; lds 360 deg / 360 / 3.5 m; "
              "rplidar 360 / 360 / 12 m; hokuyo 270 / 1081 / 30 m; sick 180 / 181 / 80 m. Odometry: none, perfect, "
              "good (0.5 % scale, 0.2 deg/m drift), poor (3 % scale, 1.5 deg/m drift), both with random error and "
              "slip.",
              f"Load average at the start: {load:.2f} on {os.cpu_count()} cores (shared).",
              f"Command: `python benchmarks/bench_laser_matrix.py{' --full' if args.full else ''}"
              + "".join(f" --{k} {' '.join(v)}" for k, v in (("robots", args.robots), ("worlds", args.worlds),
                                                             ("odometry", args.odometry)) if v)
              + (f" --seed {args.seed}" if args.seed else "") + "`.", ""]
    report(lines, record=args.record)


if __name__ == "__main__":
    main()
