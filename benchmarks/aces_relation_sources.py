"""Three independent opinions on ACES's short relations: the reference, odometry and the laser alone.

aces.relations (Kummerle et al. 2009) holds 1049 relations shorter than a second (about 0.27 m of
travel). For each, the relative pose (x_t1^-1 x_t2) three ways:
  - the reference relation;
  - odometry: the robot poses of the two FLASER lines;
  - the laser alone: the later scan matched against a local map of the earlier one
    (IncrementalScanMatcher, correlative search and Gauss-Newton refinement, no odometry term
    in the score), started once from odometry's relative pose and once from the reference's.
Prints the mean translational distance between each pair. The laser's two starts end within
millimetres of each other, so its answer is the scans', not the start's. If the three erred
independently, with squared distances d2(a, b) = s_a^2 + s_b^2, each source's share follows from
the triangle: s_ref^2 = (d2(ref, odo) + d2(ref, laser) - d2(odo, laser)) / 2, and so on.

    .venv/bin/python benchmarks/aces_relation_sources.py [--record]

Needs ../shared/data/laser_2d/aces (skips with a message without it).
"""

import argparse
import pathlib
import sys
import time

import numpy as np

import probslam as ps
from probslam import _core
from common import heading, report

ACES = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data" / "laser_2d" / "aces"
#: Relations shorter than this (s) are "short", as in bench_slam_logs.py.
SHORT_RELATION = 1.0
#: The laser-only match: the frontend's defaults, a window wide enough for either start.
MATCH_OPTIONS = dict(use_odometry_prior=False, min_travel=0.0, min_rotation=0.0, submap_distance=0.0,
                     linear_window=0.3, angular_window=0.2, field_refresh_distance=0.0, field_refresh_angle=0.0)


def relative(a, b):
    """Pose b (3,) in pose a's frame: (x, y, theta)."""
    return ps.Pose2.from_array(a).between(ps.Pose2.from_array(b)).as_array()


def laser_relation(scans, i, j, start):
    """Scan j matched against a map of scan i, from relative pose `start`."""
    angles = scans.start_angles[i] + scans.angular_resolutions[i] * np.arange(scans.ranges.shape[1])
    matcher = _core.IncrementalScanMatcher(**MATCH_OPTIONS)
    p0 = scans.robot_poses[i]
    guess = ps.Pose2.from_array(p0).compose(ps.Pose2.from_array(start)).as_array()
    matcher.add_scans(scans.ranges[[i, j]], angles, np.array([p0, guess]), scans.timestamps[[i, j]])
    poses = matcher.poses
    return relative(poses[0], poses[1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md")
    args = parser.parse_args()
    if not (ACES / "aces.clf.bz2").exists():
        print(f"skipped: {ACES} not found")
        return 0
    scans = ps.io.read_carmen_log(ACES / "aces.clf.bz2").scans
    relations = np.loadtxt(ACES / "aces.relations")
    index = {round(t, 4): k for k, t in enumerate(scans.timestamps)}
    t0 = time.perf_counter()
    ref, odo, from_odo, from_ref = [], [], [], []
    for t1, t2, x, y, _, _, _, yaw in relations:
        if t2 - t1 >= SHORT_RELATION:
            continue
        i, j = index[round(t1, 4)], index[round(t2, 4)]
        ref.append(np.array([x, y, yaw]))
        odo.append(relative(scans.robot_poses[i], scans.robot_poses[j]))
        from_odo.append(laser_relation(scans, i, j, odo[-1]))
        from_ref.append(laser_relation(scans, i, j, ref[-1]))
    seconds = time.perf_counter() - t0
    ref, odo, from_odo, from_ref = map(np.array, (ref, odo, from_odo, from_ref))

    def dist(a, b):
        return np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])

    pairs = {("reference", "odometry"): dist(ref, odo), ("reference", "laser"): dist(ref, from_odo),
             ("odometry", "laser"): dist(odo, from_odo)}
    ms = {k: float(np.mean(v ** 2)) for k, v in pairs.items()}
    shares = {
        "reference": (ms[("reference", "odometry")] + ms[("reference", "laser")] - ms[("odometry", "laser")]) / 2,
        "odometry": (ms[("reference", "odometry")] + ms[("odometry", "laser")] - ms[("reference", "laser")]) / 2,
        "laser": (ms[("reference", "laser")] + ms[("odometry", "laser")] - ms[("reference", "odometry")]) / 2,
    }
    lines = heading("ACES short relations: reference, odometry and the laser alone",
                    f"{len(ref)} relations under {SHORT_RELATION:g} s; laser: scan-to-scan correlative match with "
                    f"refinement, no odometry in the score ({seconds:.1f} s for {2 * len(ref)} matches). "
                    f"`{' '.join(sys.argv)}`",
                    ["pair", "mean distance (m)", "RMS distance (m)"])
    for (a, b), v in pairs.items():
        lines.append(f"| {a} / {b} | {v.mean():.4f} | {np.sqrt(np.mean(v ** 2)):.4f} |")
    lines.append(f"| laser from odometry's start / laser from the reference's | {dist(from_odo, from_ref).mean():.4f} | "
                 f"{np.sqrt(np.mean(dist(from_odo, from_ref) ** 2)):.4f} |")
    lines.append("")
    lines.append("Each source's RMS share if the three erred independently (the triangle of squared distances): " +
                 ", ".join(f"{k} {np.sqrt(max(v, 0.0)):.4f} m" for k, v in shares.items()) + ".")
    report(lines, record=args.record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
