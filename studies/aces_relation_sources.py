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

The three do not err independently everywhere: on about two relations in five the reference's
translation is odometry's to a tenth of a millimetre (its rotation is not), so there the
reference shares odometry's error. The script counts those relations, scores the final
trajectory (run_slam's defaults, with --slam) on each part, and repeats the triangle on the
relations whose reference is not odometry's.

    .venv/bin/python studies/aces_relation_sources.py [--slam]

Needs ../shared/data/laser_2d/aces (skips with a message without it).
"""

import argparse
import pathlib
import sys
import time

import numpy as np

import probslam as ps
from probslam import _core
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))  # common.py and the benchmarks reused here
from common import heading, report

ACES = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data" / "laser_2d" / "aces"
#: Relations shorter than this (s) are "short": consecutive-scan geometry, no loop in them.
SHORT_RELATION = 1.0
#: A reference translation within this of odometry's (m, each axis) is odometry's: the file
#: prints five decimals, so a translation of its own would differ by more than rounding (5e-6).
SAME_AS_ODOMETRY = 1e-4
#: The laser-only match: the frontend's defaults, a window wide enough for either start.
MATCH_OPTIONS = dict(use_odometry_prior=False, update={"distance": 0.0, "angle": 0.0}, submap_distance=0.0,
                     match={"window": {"linear": 0.3, "angular": 0.2}}, field_refresh_distance=0.0,
                     field_refresh_angle=0.0)


def laser_relation(scans, i, j, start):
    """Scan j matched against a map of scan i, from relative pose `start`."""
    angles = scans.start_angles[i] + scans.angular_resolutions[i] * np.arange(scans.ranges.shape[1])
    matcher = _core.IncrementalScanMatcher(**MATCH_OPTIONS)
    p0 = scans.robot_poses[i]
    guess = ps.Pose2.from_array(p0).compose(ps.Pose2.from_array(start)).as_array()
    matcher.add_scans(scans.ranges[[i, j]], angles, np.array([p0, guess]), scans.timestamps[[i, j]])
    poses = matcher.poses
    return ps.eval.relative_poses(poses[0], poses[1])


def triangle(ms):
    """Each source's mean squared error from the pairwise mean squared distances, if independent."""
    ro, rl, ol = ms[("reference", "odometry")], ms[("reference", "laser")], ms[("odometry", "laser")]
    return {"reference": (ro + rl - ol) / 2, "odometry": (ro + ol - rl) / 2, "laser": (rl + ol - ro) / 2}


def slam_relations(scans, pairs):
    """run_slam's defaults on the whole log: the relative pose (x, y, theta) of each pair of scan
    indices (a pose per scan, in the log's order), (R, 3)."""
    result = ps.slam.run_slam(scans, progress=False)
    assert np.array_equal(result.timestamps, scans.timestamps)
    return ps.eval.relative_poses(result.poses[pairs[:, 0]], result.poses[pairs[:, 1]])


def slam_table(scans, pairs, relations, odo, short, same):
    """run_slam's error on the short relations whose reference is odometry's (`same`), the other
    short ones and the long ones, beside odometry's relative poses `odo` (R, 3)."""
    expected = relations[:, [2, 3, 7]]
    slam = slam_relations(scans, pairs)
    parts = {"all": np.ones(len(relations), bool), "short, reference = odometry": short & same,
             "short, reference not odometry": short & ~same, "long": ~short}
    lines = ["| run_slam (defaults) on ACES: mean translational error (m) | " +
             " | ".join(f"{k} ({m.sum()})" for k, m in parts.items()) + " |",
             "|---|" + "---|" * len(parts)]
    for name, est in (("run_slam", slam), ("raw odometry", odo)):
        err = dist(expected, est)
        lines.append(f"| {name} | " + " | ".join(f"{err[m].mean():.4f}" for m in parts.values()) + " |")
    return "\n".join(lines)


def dist(a, b):
    """Translational distance between relative poses, row by row."""
    return np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--slam", action="store_true",
                        help="also run run_slam on the log (about 20 s) and score it on each part")
    args = parser.parse_args()
    if not (ACES / "aces.clf.bz2").exists():
        print(f"skipped: {ACES} not found")
        return 0
    scans = ps.io.read_carmen_log(ACES / "aces.clf.bz2").scans
    relations = np.loadtxt(ACES / "aces.relations")
    # The relations name scans by their ipc time (read_carmen_log's timestamps are the logger's).
    index = {round(t, 4): k for k, t in enumerate(scans.ipc_timestamps)}
    scan_pairs = np.array([(index[round(t1, 4)], index[round(t2, 4)]) for t1, t2, *_ in relations])
    odo_all = ps.eval.relative_poses(scans.robot_poses[scan_pairs[:, 0]], scans.robot_poses[scan_pairs[:, 1]])
    same_all = np.all(np.abs(relations[:, [2, 3]] - odo_all[:, :2]) < SAME_AS_ODOMETRY, axis=1)
    short = relations[:, 1] - relations[:, 0] < SHORT_RELATION
    ref, odo, same = relations[short][:, [2, 3, 7]], odo_all[short], same_all[short]
    t0 = time.perf_counter()
    from_odo, from_ref = [], []
    for (i, j), o, r in zip(scan_pairs[short], odo, ref):
        from_odo.append(laser_relation(scans, i, j, o))
        from_ref.append(laser_relation(scans, i, j, r))
    seconds = time.perf_counter() - t0
    from_odo, from_ref = np.array(from_odo), np.array(from_ref)

    parts = {"all": np.ones(len(ref), bool), "reference = odometry": same, "reference not odometry": ~same}
    pairs = {("reference", "odometry"): dist(ref, odo), ("reference", "laser"): dist(ref, from_odo),
             ("odometry", "laser"): dist(odo, from_odo)}
    lines = heading("ACES short relations: reference, odometry and the laser alone",
                    f"{len(ref)} relations under {SHORT_RELATION:g} s; laser: scan-to-scan correlative match with "
                    f"refinement, no odometry in the score ({seconds:.1f} s for {2 * len(ref)} matches). "
                    f"reference = odometry: the reference's translation is odometry's within "
                    f"{SAME_AS_ODOMETRY:g} m on each axis ({same.sum()} relations; their rotations differ by "
                    f"{np.median(np.abs(ps.wrap_angle(ref[same, 2] - odo[same, 2]))):.4f} rad in the median). "
                    f"`{' '.join(sys.argv)}`",
                    ["pair: mean / RMS distance (m)"] + [f"{k} ({m.sum()})" for k, m in parts.items()])
    rows = {f"{a} / {b}": v for (a, b), v in pairs.items()}
    rows["laser from odometry's start / laser from the reference's"] = dist(from_odo, from_ref)
    for name, v in rows.items():
        lines.append(f"| {name} | " + " | ".join(f"{v[m].mean():.4f} / {np.sqrt(np.mean(v[m] ** 2)):.4f}"
                                                 for m in parts.values()) + " |")
    lines.append("")
    for name, m in parts.items():
        if name == "reference = odometry":
            continue  # there the reference is odometry: the triangle's independence fails
        shares = triangle({k: float(np.mean(d[m] ** 2)) for k, d in pairs.items()})
        lines.append(f"Each source's RMS share if the three erred independently (the triangle of squared distances), "
                     f"{name}: " + ", ".join(f"{k} {np.sqrt(max(x, 0.0)):.4f} m" for k, x in shares.items()) + ".")
    if args.slam:
        lines += ["", slam_table(scans, scan_pairs, relations, odo_all, short, same_all)]
    report(lines, record=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
