"""GraphSLAM's correspondence test (ch. 11.6) after the filters, on every shipped UTIAS MRCLAM
robot with barcodes hidden: EKF SLAM (joint compatibility, the CLI's default), the
multiple-hypothesis EKF and FastSLAM 1.0, each before and after ``probslam.refine_run``, one set
of defaults for all (the CLI's noise; the refinement's gates are its named constants).

Per run: the share of sightings whose landmark's majority barcode is their own, the landmarks
(the filter's map / the labels holding sightings before; after), the sightings on no landmark,
the path RMSE after a rigid alignment onto Vicon at the refinement's pose times (Dataset 7;
Dataset 1 ships no robot ground truth), the map RMSE after a rigid alignment onto the survey
(Dataset 1's exchanged survey labels corrected), and the refinement's time and rounds.

    .venv/bin/python benchmarks/bench_landmark_refine.py [--jobs 2] [--datasets 1 7] [--robots 1 2]
        [--methods jcbb mht fastslam] [--new-landmarks] [--record]

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
from probslam import landmark_refine as lr
from probslam.datasets import mrclam, refine_run
from common import heading, report

DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data" / "landmark_slam"
# The CLI's MRCLAM defaults (`probslam ekf-slam --help`): control noise per 10 ms command, sensor noise.
MOTION = np.diag([0.15 ** 2, 0.6 ** 2])
SENSOR = np.diag([0.15 ** 2, 0.04 ** 2])
METHODS = ("jcbb", "mht", "fastslam")


def path_rmse(data, times, poses) -> float:
    """Path RMSE (m) after the best rigid alignment onto the ground truth; NaN without it."""
    if data.groundtruth is None:
        return float("nan")
    truth = ev.truth_positions(data.groundtruth, times)
    r, t = ev.align_rigid(poses[:, :2], truth)
    return ev.rmse(poses[:, :2] @ r.T + t, truth)


def map_rmse(landmarks, data, labels) -> float:
    try:
        return ev.score_landmarks(landmarks, data, labels).rmse_aligned
    except ValueError:
        return float("nan")


def run_one(job):
    dataset, robot, method, new_landmarks = job
    data = ps.io.read_mrclam(DATA / f"mrclam_dataset{dataset}", robot=robot).with_euclidean_ranges()
    fixed = data.with_survey_swapped(mrclam.survey_label_swaps(data))
    if method == "fastslam":
        run = mrclam.run_fastslam(data, MOTION, SENSOR, known=False)
    else:
        run = mrclam.run_ekf(data, MOTION, SENSOR, known=False, association=method)
    t0 = time.perf_counter()
    refined = refine_run(run, data, MOTION, SENSOR, new_landmarks=new_landmarks)
    seconds = time.perf_counter() - t0
    start, result = refined.input, refined.result
    labelled = start.labels != lr.UNASSIGNED
    before_labels = lr.majority_truth(start.labels, start.truth)
    return dict(dataset=dataset, robot=robot, method=method,
                before=lr.sighting_accuracy(start.labels, start.truth),
                after=lr.sighting_accuracy(result.labels, start.truth),
                map_size=len(run.landmarks), labels_before=len(set(start.labels[labelled].tolist())),
                landmarks_after=len(result.landmarks),
                path_before=path_rmse(data, start.times, start.poses),
                path_after=path_rmse(data, start.times, result.poses),
                map_before=map_rmse({k: v for k, v in run.landmarks.items() if k in before_labels}, fixed,
                                    before_labels),
                map_after=map_rmse(result.landmarks, fixed, lr.majority_truth(result.labels, start.truth)),
                seconds=seconds, iterations=result.iterations, merges=len(result.merges), splits=len(result.splits),
                sightings=len(start.labels), unassigned_before=int(np.count_nonzero(~labelled)),
                unassigned_after=int(np.count_nonzero(result.labels == lr.UNASSIGNED)), converged=result.converged)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--datasets", type=int, nargs="+", default=[1, 7])
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--new-landmarks", action="store_true",
                        help="a sighting that fits no landmark founds one (refine_landmarks(new_landmarks=True))")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md")
    args = parser.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} not found")
        return 0
    jobs = [(d, r, m, args.new_landmarks) for d in args.datasets for r in args.robots for m in args.methods]
    with concurrent.futures.ProcessPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(run_one, jobs))
    lines = heading("MRCLAM, barcodes hidden, GraphSLAM refinement after each filter",
                    "The CLI's noise (sigma_v 0.15, sigma_w 0.6, sigma_r 0.15, sigma_phi 0.04), ranges from depth, "
                    "whole runs; FastSLAM 1.0, 100 particles, seed 0; refinement gates "
                    f"chi2_2({lr.MERGE_PROBABILITY}) for merges, Sidak {lr.SPLIT_RUN_PROBABILITY} over the run's "
                    "sightings for splits. Correct: sightings whose landmark's majority barcode is their own; "
                    "landmarks: the filter's map / labels holding sightings -> after (15 surveyed); path: RMSE "
                    "aligned onto Vicon at the scans (Dataset 7); map: RMSE aligned onto the survey; "
                    "unassigned: sightings on no landmark (the filter's discards; after: also those that left "
                    "their landmark and passed no other); rounds marked * reached max_iterations. "
                    f"`{' '.join(sys.argv)}`",
                    ["run", "method", "correct before -> after", "landmarks before -> after", "unassigned",
                     "path m before -> after", "map m before -> after", "refine s (rounds, merges, moves)"])
    for r in rows:
        lines.append(f"| D{r['dataset']} r{r['robot']} | {r['method']} | {r['before']:.2%} -> {r['after']:.2%} | "
                     f"{r['map_size']} / {r['labels_before']} -> {r['landmarks_after']} | "
                     f"{r['unassigned_before']} -> {r['unassigned_after']} of {r['sightings']} | "
                     f"{r['path_before']:.3f} -> {r['path_after']:.3f} | "
                     f"{r['map_before']:.3f} -> {r['map_after']:.3f} | "
                     f"{r['seconds']:.2f} ({r['iterations']}{'' if r['converged'] else '*'}, {r['merges']}, "
                     f"{r['splits']}) |")
    lines.append("")
    for m in args.methods:
        rs = [r for r in rows if r["method"] == m]
        better = sum(r["after"] > r["before"] for r in rs)
        worse = sum(r["after"] < r["before"] for r in rs)
        lines.append(f"- {m}: mean {np.mean([r['before'] for r in rs]):.1%} -> {np.mean([r['after'] for r in rs]):.1%} "
                     f"correct; improved on {better}, worse on {worse} of {len(rs)} runs; at >= 95% with 15 +- 1 "
                     f"landmarks: {sum(r['before'] >= 0.95 and abs(r['labels_before'] - 15) <= 1 for r in rs)} -> "
                     f"{sum(r['after'] >= 0.95 and abs(r['landmarks_after'] - 15) <= 1 for r in rs)}")
    report(lines, record=args.record, script="bench_landmark_refine.py")
    return 0


if __name__ == "__main__":
    sys.exit(main())
