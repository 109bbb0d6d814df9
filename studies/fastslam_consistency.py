"""Monte-Carlo consistency of landmark FastSLAM 1.0 / 2.0 beside EKF SLAM (issue 14), on the runs of
ekf_experiments.py's consistency study (same world, same seeds): known correspondences, the
average pose NEES over time across the runs for the EKF and for FastSLAM versions 1 and 2 with 100
and 1000 particles, its 95% band, and the step after which a WINDOW-step moving average of it
leaves the band for good. Prints a table (the last full run:
studies/README.md); draws docs/fastslam_nees.png with --figure.

FastSLAM's pose estimate is the particles' weighted mean (heading by circular mean) with their
weighted covariance (``FastSlam.mean_pose`` / ``pose_covariance``); the NEES is
``probslam.eval.nees``; where that covariance is singular the NEES is counted as inf and reported
(never replaced by a pseudo-inverse). The EKF's is ``probslam.sim.filter_known``'s, as in the EKF study.

    .venv/bin/python studies/fastslam_consistency.py [--quick] [--jobs 2] [--figure]
    .venv/bin/python studies/fastslam_consistency.py --coalescence   (run 0's particle paths)
"""

import argparse
import concurrent.futures
import datetime
import pathlib
import sys
import time

import numpy as np
from scipy.stats import chi2

import probslam as ps
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))  # common.py and the benchmarks reused here
from common import machine, report
from ekf_experiments import M, Q, WINDOW, consistency_run

FIGURE = pathlib.Path(__file__).resolve().parents[1] / "docs" / "fastslam_nees.png"
DT = 0.2  # s per step (consistency_run)
LAP = 262  # steps per lap of the 8.3 m circle at 1 m/s, 0.12 rad/s, 0.2 s steps
# (name, version (0: EKF), particles); FastSLAM run k uses seed k.
FILTERS = [("EKF", 0, 0), ("FastSLAM 1.0, 100", 1, 100), ("FastSLAM 2.0, 100", 2, 100),
           ("FastSLAM 1.0, 1000", 1, 1000), ("FastSLAM 2.0, 1000", 2, 1000)]
WINDOWS = [(5, 100), (100, 300), (300, 600), (600, 1000), (1000, 2000), (2000, 3000)]


def one(name, version, particles, k, steps):
    """Run k of one filter: (name, k, NEES (steps,), N_eff (steps,) or NaN for the EKF, CPU seconds)."""
    run = consistency_run(k, steps)
    start = time.process_time()  # CPU time: the machine is shared
    if version == 0:
        nees, _ = ps.sim.filter_known(run, M, Q)
        n_eff = np.full(steps, np.nan)
    else:
        poses, covariances, n_eff = ps.sim.fastslam_known(run, M, Q, particles, version=version, seed=k)
        nees = nees_or_inf(ps.sim.pose_error(poses, run.poses[1:]), covariances)
    return name, k, nees, n_eff, time.process_time() - start


def nees_or_inf(errors, covariances):
    """Pose NEES per step (T,), inf where the particle covariance is singular (the particles have
    collapsed onto fewer than three distinct poses: the filter claims certainty it lacks). These
    steps are counted in the report; an inf makes the average over runs at that step inf."""
    try:
        return ps.eval.nees(errors, covariances)
    except ps.eval.SingularCovarianceError:
        out = np.empty(len(errors))
        for t, (e, p) in enumerate(zip(errors, covariances)):
            try:
                out[t] = ps.eval.nees(e, p)
            except ps.eval.SingularCovarianceError:
                out[t] = np.inf
        return out


def coalescence(steps, at=(10, 100, 300, 500, 800, 950, 990)):
    """Run 0 of each FastSLAM filter over `steps` steps, then the number of distinct poses at the
    steps `at` among the final particles' paths: how far back they share one ancestor."""
    run = consistency_run(0, steps)
    lines = ["| filter | " + " | ".join(f"step {s}" for s in at) + f" | step {steps} |",
             "|---|" + "---|" * (len(at) + 1)]
    for name, version, particles in FILTERS[1:]:
        f = ps.FastSlam(M, Q, num_particles=particles, version=version, initial_pose=run.poses[0], seed=0)
        for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
            f.predict(v, w, run.dt)
            if len(z):
                f.update(z, ids)
        paths = np.array([f.path(k) for k in range(particles)])  # (M, steps + 1, 3)
        counts = [len(np.unique(paths[:, s], axis=0)) for s in (*at, steps)]
        lines.append(f"| {name} | " + " | ".join(map(str, counts)) + " |")
    return lines


def band(runs):
    """Two-sided 95% band of the average of `runs` independent chi2(3) NEES values."""
    return tuple(chi2.ppf([0.025, 0.975], 3 * runs) / runs)


def leaves(anees, lo, hi):
    """(first step at which the WINDOW-step moving average is outside [lo, hi], the step after
    which it stays outside for good, 'above'/'below' for that final side); None where it never
    does. A step index is the moving window's first step."""
    smooth = np.convolve(anees, np.ones(WINDOW) / WINDOW, mode="valid")
    outside = (smooth > hi) | (smooth < lo)
    first = int(np.argmax(outside)) if outside.any() else None
    inside = np.flatnonzero(~outside)
    onset = None
    if outside[-1]:
        onset = int(inside[-1]) + 1 if len(inside) else 0
    side = None if onset is None else ("above" if smooth[-1] > hi else "below")
    return first, onset, side


def describe(step):
    return "never" if step is None else f"{step} ({step * DT:.0f} s, {step / LAP:.1f} laps)"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="10 runs of 400 steps")
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--steps", type=int, default=3000, help="steps of the EKF and 100-particle runs")
    parser.add_argument("--steps-1000", type=int, default=None,
                        help="steps of the 1000-particle runs (a prefix of the same runs; default --steps)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes over runs (2 at most here)")
    parser.add_argument("--figure", action="store_true", help=f"draw {FIGURE.relative_to(FIGURE.parents[1])}")
    parser.add_argument("--coalescence", action="store_true",
                        help="only: distinct poses along the final particles' paths, run 0, 1000 steps")
    args = parser.parse_args()
    if args.coalescence:
        report([f"## FastSLAM path coalescence, {datetime.date.today()}", "",
                "FastSLAM path coalescence (`studies/fastslam_consistency.py --coalescence`): distinct poses "
                "at each step among the final particles' paths, run 0 of the consistency study, 1000 steps, seed 0.",
                ""] + coalescence(1000), record=False)
        return
    runs, steps = (10, 400) if args.quick else (args.runs, args.steps)
    steps_1000 = min(args.steps_1000 or steps, steps)
    lengths = {name: (steps_1000 if particles == 1000 else steps) for name, _, particles in FILTERS}

    nees = {name: np.zeros((runs, lengths[name])) for name, _, _ in FILTERS}
    n_eff = {name: np.zeros((runs, lengths[name])) for name, _, _ in FILTERS}
    seconds = {name: 0.0 for name, _, _ in FILTERS}
    wall = time.perf_counter()
    tasks = [(name, version, particles, k, lengths[name]) for name, version, particles in FILTERS
             for k in range(runs)]
    tasks.sort(key=lambda t: -t[2] * t[4])  # longest first: the pool ends together
    with concurrent.futures.ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for name, k, e, n, s in pool.map(one, *zip(*tasks)):
            nees[name][k], n_eff[name][k] = e, n
            seconds[name] += s
    wall = time.perf_counter() - wall

    lo, hi = band(runs)
    summary = {}
    for name, _, particles in FILTERS:
        anees = nees[name].mean(axis=0)
        summary[name] = (anees, *leaves(anees, lo, hi))

    lines = [f"## FastSLAM consistency beside EKF SLAM (simulated), {datetime.date.today()}", "",
             f"Machine: {machine()}. `studies/fastslam_consistency.py --jobs {args.jobs}"
             f"{' --quick' if args.quick else ''}{f' --steps-1000 {steps_1000}' if steps_1000 != steps else ''}`, "
             f"{wall:.0f} s wall.", "",
             f"Known correspondences, {runs} Monte-Carlo runs of ekf_experiments.py's consistency study (same "
             f"world and seeds; {steps} steps of {DT} s, a lap every {LAP} steps"
             f"{f'; the 1000-particle filters on the first {steps_1000} steps of the same runs' if steps_1000 != steps else ''}). "
             f"Pose NEES after each step's update; FastSLAM's from the particles' weighted mean and weighted "
             f"covariance. 95% band of the average NEES (3 dof, {runs} runs): [{lo:.2f}, {hi:.2f}]. Each cell: the "
             f"average NEES over the steps (its mean over runs and steps), and in brackets the median of the "
             f"single NEES values (runs x steps; 2.37 for chi2(3)): a few huge values from collapsed particle clouds "
             f"dominate an average.", "",
             "| steps | " + " | ".join(name for name, _, _ in FILTERS) + " |",
             "|---|" + "---|" * len(FILTERS)]
    for a, b in WINDOWS:
        if b > steps:
            continue
        cells = []
        for name, _, _ in FILTERS:
            anees = summary[name][0]
            cells.append(f"{anees[a:b].mean():.2f} ({np.median(nees[name][:, a:b]):.2f})"
                         if b <= len(anees) else "-")
        lines.append(f"| {a}-{b} | " + " | ".join(cells) + " |")
    lines += ["", f"Where the {WINDOW}-step moving average of the average NEES leaves the band (first time; for good):",
              "", "| filter | first leaves | leaves for good | side | singular covariances | mean N_eff | "
              "CPU s per run |", "|---|---|---|---|---|---|---|"]
    for name, version, particles in FILTERS:
        _, first, onset, side = summary[name]
        bad = np.argwhere(~np.isfinite(nees[name]))
        singular = f"{len(bad)}" + (" (run, step: " + ", ".join(f"{k}, {t}" for k, t in bad[:3])
                                    + (", ..." if len(bad) > 3 else "") + ")" if len(bad) else "")
        mean_eff = "-" if version == 0 else f"{np.mean(n_eff[name]):.0f} of {particles}"
        lines.append(f"| {name} | {describe(first)} | {describe(onset)} | {side or '-'} | "
                     f"{singular} of {nees[name].size} | {mean_eff} | {seconds[name] / runs:.1f} |")
    lines.append("")
    report(lines, record=False)

    if args.figure:
        draw(summary, nees, lo, hi, runs)


def draw(summary, nees, lo, hi, runs):
    """Top: the WINDOW-step moving average of the average NEES with its 95% band (gaps: windows
    holding a singular particle covariance, infinite NEES). Bottom: the same moving average of
    the median over runs at each step, which a few collapsed runs cannot dominate."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    top.axhspan(lo, hi, color="0.8", label=f"95% band ({runs} runs)")
    bottom.axhline(chi2.median(3), color="0.5", ls="--", lw=1, label="median of chi2(3)")
    kernel = np.ones(WINDOW) / WINDOW
    for name, _, _ in FILTERS:
        x = np.arange(len(summary[name][0]) - WINDOW + 1) + WINDOW // 2
        top.plot(x, np.convolve(summary[name][0], kernel, mode="valid"), label=name, lw=1.2)
        bottom.plot(x, np.convolve(np.median(nees[name], axis=0), kernel, mode="valid"), label=name, lw=1.2)
    for ax in (top, bottom):
        ax.set_yscale("log")
        ax.grid(True, which="major", alpha=0.3)
    top.set_ylabel("average pose NEES")
    bottom.set_ylabel("median pose NEES")
    bottom.set_xlabel(f"step ({DT} s; a lap every {LAP} steps); {WINDOW}-step moving averages")
    top.set_title(f"Pose NEES over {runs} simulated runs, known correspondences (gaps: a singular "
                  "particle covariance)", fontsize=10)
    top.legend(fontsize=8, loc="upper left", ncol=2)
    bottom.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    FIGURE.parent.mkdir(exist_ok=True)
    fig.savefig(FIGURE, dpi=100)
    print(f"wrote {FIGURE}")

if __name__ == "__main__":
    main()
