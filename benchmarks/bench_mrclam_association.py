"""Hidden barcodes on every shipped UTIAS MRCLAM robot: data association of EKF SLAM (joint
compatibility, multiple hypotheses) and landmark FastSLAM (versions 1 and 2), one set of
defaults for all robots (those of `probslam ekf-slam` / `probslam fastslam`).

Per run: the share of sightings whose filter landmark's majority barcode is their own, the
number of landmarks in the (best) map (15 surveyed), the map RMSE after a rigid alignment onto
the survey (Dataset 1's exchanged survey labels corrected, as the CLI does), and the filter time.

    .venv/bin/python benchmarks/bench_mrclam_association.py [--jobs 2] [--robots 1 2] [--datasets 1 7]
        [--methods jcbb mht fastslam1 fastslam2] [--seconds S] [--record]
        [--particles M] [--seed S] [--existence-miss C]   (FastSLAM only)
        (also: --methods ekf-known fastslam1-known fastslam2-known, fastslam1-offset fastslam2-offset, mht-offset)

Needs ../shared/data/landmark_slam (skips with a message without it).
"""

import argparse
import concurrent.futures
import pathlib
import sys
import time

import numpy as np

import probslam as ps
from probslam import eval as ev
from probslam.datasets import mrclam
from common import heading, report

DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data" / "landmark_slam"
# The library's (and the CLI's) MRCLAM defaults: control noise per 10 ms command, sensor noise.
MOTION = mrclam.MOTION_NOISE
SENSOR = mrclam.MEASUREMENT_NOISE
SURVEYED = 15
METHODS = ("jcbb", "mht", "fastslam1", "fastslam2")
# Barcodes as correspondences, for reference (`--methods ekf-known fastslam1-known ...`).
KNOWN_METHODS = ("ekf-known", "fastslam1-known", "fastslam2-known")
# FastSLAM with the scan's bearing offset as a particle state (`--methods fastslam1-offset
# fastslam2-offset`): the offset's size and scan-to-scan correlation as measured on Dataset 7
# against Vicon (docs/ekf_slam.md: 0.025 rad shared by a scan, lag-one correlation 0.84), the
# sensor noise then the part not shared (0.05 m, 0.01 rad), p_new 0.1.
OFFSET_METHODS = ("fastslam1-offset", "fastslam2-offset")
OFFSET_SENSOR = np.diag([0.05 ** 2, 0.01 ** 2])
OFFSET_OPTIONS = dict(bearing_offset_sigma=0.025, bearing_offset_correlation=0.84)
OFFSET_P_NEW = 0.1
# The multiple-hypothesis EKF with the scan's bearing offset in each filter (`--methods mht-offset`):
# the CLI's MHT costs, 0.03 rad of the bearing noise moved into an offset drawn afresh per scan
# (the best of the sweep in docs/landmark_fastslam.md; rho 0.84 made duplicates on Dataset 1).
MHT_OFFSET_SENSOR = np.diag([0.15 ** 2, 0.02 ** 2])
MHT_OFFSET_OPTIONS = dict(bearing_offset_sigma=0.03, bearing_offset_correlation=0.0)


def load(dataset: int, robot: int, seconds):
    return mrclam.load(DATA / f"mrclam_dataset{dataset}", robot, seconds)


def run_one(job):
    dataset, robot, method, seconds, particles, seed, existence_miss = job
    options = {} if existence_miss is None else {"existence_miss": existence_miss}
    fastslam = dict(num_particles=particles, seed=seed, **options)
    data = load(dataset, robot, seconds)
    t0 = time.perf_counter()
    known = method.endswith("-known")
    if method == "ekf-known":
        run = ps.run_landmark_slam(data, "ekf", motion_noise=MOTION, measurement_noise=SENSOR)
    elif method == "jcbb":
        run = ps.run_landmark_slam(data, "ekf", known=False, motion_noise=MOTION, measurement_noise=SENSOR)
    elif method in ("mht", "mht-offset"):
        offset = method == "mht-offset"
        run = ps.run_landmark_slam(data, "mht", known=False, motion_noise=MOTION,
                                   measurement_noise=MHT_OFFSET_SENSOR if offset else SENSOR,
                                   hypotheses=ps.MultiHypothesisOptions(**MHT_OFFSET_OPTIONS) if offset else None)
    elif method in OFFSET_METHODS:
        fastslam.update(OFFSET_OPTIONS)
        run = ps.run_landmark_slam(data, "fastslam", known=False, motion_noise=MOTION, measurement_noise=OFFSET_SENSOR,
                                   version=int(method.split("-")[0][-1]), p_new=OFFSET_P_NEW, **fastslam)
    else:
        run = ps.run_landmark_slam(data, "fastslam", known=known, motion_noise=MOTION, measurement_noise=SENSOR,
                                   version=int(method.split("-")[0][-1]), **fastslam)
    correct, labels = (1.0, None) if known else (ev.association_accuracy(run), ev.majority_labels(run))
    seconds_taken = time.perf_counter() - t0
    fixed = data.with_survey_swapped(mrclam.survey_label_swaps(data))
    try:
        rmse = ev.score_landmarks(run.landmarks, fixed, labels).rmse_aligned
    except ValueError:
        rmse = float("nan")
    return dict(dataset=dataset, robot=robot, method=method, correct=correct, landmarks=len(run.landmarks),
                rmse=rmse, seconds=seconds_taken, sightings=len(data.measurements),
                seen=len(set(data.measurements[:, 1].astype(int)) & set(data.landmark_positions)))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--datasets", type=int, nargs="+", default=[1, 7])
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--methods", nargs="+", default=list(METHODS),
                        choices=METHODS + KNOWN_METHODS + OFFSET_METHODS + ("mht-offset",))
    parser.add_argument("--particles", type=int, default=100, help="FastSLAM particles (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="FastSLAM random seed (default 0)")
    parser.add_argument("--existence-miss", type=float, default=None,
                        help="FastSLAM: existence lost by a landmark in the camera's field that a scan misses "
                             "(default: the library's, 1)")
    parser.add_argument("--seconds", type=float, default=None, help="only the first SECONDS of each robot")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    args = parser.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} not found")
        return 0
    if args.particles < 1:
        parser.error("--particles must be >= 1")
    if args.existence_miss is not None and not (np.isfinite(args.existence_miss) and args.existence_miss >= 0):
        parser.error("--existence-miss must be finite and >= 0")
    jobs = [(d, r, m, args.seconds, args.particles, args.seed, args.existence_miss) for d in args.datasets for r in args.robots for m in args.methods]
    with concurrent.futures.ProcessPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(run_one, jobs))
    offset_only = all(m in OFFSET_METHODS for m in args.methods)
    mht_offset_only = args.methods == ["mht-offset"]
    title = "MRCLAM, barcodes hidden, every robot" + (", FastSLAM with the bearing offset model" if offset_only else
                                                      ", multiple-hypothesis EKF with the bearing offset" if mht_offset_only
                                                      else "")
    sensor = ("sensor: bearing offset 0.025 rad, correlation 0.84, sigma_r 0.05, sigma_phi 0.01, p_new 0.1" if offset_only
              else "sensor: bearing offset 0.03 rad afresh per scan, sigma_r 0.15, sigma_phi 0.02" if mht_offset_only
              else "sigma_r 0.15, sigma_phi 0.04")
    lines = heading(title,
                    f"One set of defaults (CLI: sigma_v 0.15, sigma_w 0.6, {sensor}; "
                    f"FastSLAM {args.particles} particles, seed {args.seed}"
                    f"{'' if args.existence_miss is None else ', existence miss %g' % args.existence_miss}); ranges from depth; "
                    f"{'first %g s' % args.seconds if args.seconds else 'whole runs'}. "
                    f"Correct: sightings whose landmark's majority barcode is their own; landmarks: "
                    f"{SURVEYED} surveyed; RMSE: map aligned onto the survey. `{' '.join(sys.argv)}`",
                    ["dataset / robot", "sightings / barcodes seen"] + [f"{m}: correct / landmarks / RMSE / s" for m in args.methods])
    by_key = {(r["dataset"], r["robot"], r["method"]): r for r in rows}
    for d in args.datasets:
        for rb in args.robots:
            cells = []
            for m in args.methods:
                r = by_key[(d, rb, m)]
                cells.append(f"{r['correct']:.1%} / {r['landmarks']} / {r['rmse']:.3f} / {r['seconds']:.1f}")
            first = by_key[(d, rb, args.methods[0])]
            lines.append(f"| D{d} r{rb} | {first['sightings']} / {first['seen']} | " + " | ".join(cells) + " |")
    lines.append("")
    for m in args.methods:
        rs = [r for r in rows if r["method"] == m]
        ok = sum(r["correct"] >= 0.95 and abs(r["landmarks"] - r["seen"]) <= 1 for r in rs)
        lines.append(f"- {m}: mean {np.mean([r['correct'] for r in rs]):.1%} correct, worst "
                     f"{min(r['correct'] for r in rs):.1%}; {ok} of {len(rs)} runs at >= 95% with one landmark per barcode seen +- 1")
    report(lines, record=args.record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
