"""Pose-graph optimisation: probslam against GTSAM (pip `gtsam`) on the same files, same run.

For each dataset: file-to-result time (read + optimise to convergence), time per Gauss-Newton
(or Levenberg-Marquardt) iteration, iterations and final chi2 in g2o's convention (GTSAM's error
is half of it; its first pose gets a tight prior, ours is held fixed: the same gauge). The median
of `--repeat` runs is reported. g2o's command line tool is used when installed (`g2o` on PATH).

    python benchmarks/bench_pose_graph.py [--repeat 5] [--quick]
"""

import argparse
import datetime
import pathlib
import shutil
import statistics
import sys
import time

import numpy as np

import probslam
from common import machine, report

DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data" / "pose_graphs"
DATASETS = {
    "Intel (intel.g2o)": DATA / "intel" / "intel.g2o",
    "M3500 (input_M3500_g2o.g2o)": DATA / "manhattan_m3500" / "input_M3500_g2o.g2o",
    "M3500 Olson (manhattanOlson3500.g2o)": DATA / "manhattan_m3500" / "manhattanOlson3500.g2o",
}
# Both optimisers stop when an iteration changes the error by less than this fraction.
RELATIVE_TOLERANCE = 1e-10


def run_probslam(path, algorithm):
    t0 = time.perf_counter()
    g = probslam.read_pose_graph(str(path))
    r = probslam.optimize(g, algorithm=algorithm, relative_tolerance=RELATIVE_TOLERANCE)
    total = time.perf_counter() - t0
    return total, r.iterations, float(np.mean(r.iteration_seconds)), r.chi2


def run_gtsam(path, algorithm):
    import gtsam

    t0 = time.perf_counter()
    graph, initial = gtsam.readG2o(str(path), False)
    first = min(initial.keys())
    graph.add(gtsam.PriorFactorPose2(first, initial.atPose2(first), gtsam.noiseModel.Isotropic.Sigma(3, 1e-6)))
    if algorithm == "gauss-newton":
        params = gtsam.GaussNewtonParams()
        params.setRelativeErrorTol(RELATIVE_TOLERANCE)
        params.setAbsoluteErrorTol(0.0)
        params.setMaxIterations(100)
        optimizer = gtsam.GaussNewtonOptimizer(graph, initial, params)
    else:
        params = gtsam.LevenbergMarquardtParams()
        params.setRelativeErrorTol(RELATIVE_TOLERANCE)
        params.setAbsoluteErrorTol(0.0)
        params.setMaxIterations(100)
        optimizer = gtsam.LevenbergMarquardtOptimizer(graph, initial, params)
    t1 = time.perf_counter()
    result = optimizer.optimize()
    t2 = time.perf_counter()
    iterations = max(optimizer.iterations(), 1)
    return t2 - t0, optimizer.iterations(), (t2 - t1) / iterations, 2.0 * graph.error(result)


def median_run(fn, path, algorithm, repeat):
    runs = [fn(path, algorithm) for _ in range(repeat)]
    return tuple(statistics.median(r[i] for r in runs) for i in range(4))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="one run, Intel only, nothing recorded")
    args = parser.parse_args()
    try:
        import gtsam  # noqa: F401
    except ImportError:
        sys.exit("bench_pose_graph: needs `pip install gtsam`")
    datasets = {k: v for k, v in DATASETS.items() if v.exists()}
    if not datasets:
        print(f"bench_pose_graph: no datasets under {DATA}; nothing to do")
        return
    if args.quick:
        datasets = dict(list(datasets.items())[:1])
    repeat = 1 if args.quick else args.repeat
    lines = [f"## Pose-graph optimisation against GTSAM, {datetime.date.today()}", "",
             f"Machine: {machine()}; gtsam {getattr(__import__('gtsam'), '__version__', '4.x')} (pip), "
             f"one thread each. Median of {repeat} runs; chi2 in g2o's convention.", "",
             "| dataset | algorithm | probslam file-to-result | GTSAM file-to-result | ratio | probslam ms/iteration "
             "| GTSAM ms/iteration | ratio | iterations (ours / GTSAM) | chi2 probslam | chi2 GTSAM |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, path in datasets.items():
        for algorithm in ("gauss-newton", "levenberg-marquardt"):
            ours = median_run(run_probslam, path, algorithm, repeat)
            theirs = median_run(run_gtsam, path, algorithm, repeat)
            lines.append(
                f"| {name} | {algorithm} | {ours[0] * 1e3:.1f} ms | {theirs[0] * 1e3:.1f} ms | "
                f"{theirs[0] / ours[0]:.1f}x | {ours[2] * 1e3:.2f} | {theirs[2] * 1e3:.2f} | "
                f"{theirs[2] / ours[2]:.1f}x | {ours[1]:.0f} / {theirs[1]:.0f} | {ours[3]:.6f} | {theirs[3]:.6f} |")
    if shutil.which("g2o") is None:
        lines += ["", "g2o: no `g2o` command-line tool on this machine, so no g2o column."]
    report(lines, record=not args.quick)


if __name__ == "__main__":
    main()
