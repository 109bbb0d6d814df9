"""EKF SLAM experiments on simulated data: (1) Monte-Carlo consistency and the run length at
which the filter becomes inconsistent; (2) unknown correspondences with clutter: association
precision/recall and spurious landmarks, with and without the ch. 10.3.3 map management, for
maximum-likelihood and joint-compatibility association.
Prints the tables (the last full run: studies/README.md).

    .venv/bin/python studies/ekf_experiments.py [--quick]
"""

import argparse
import collections
import datetime
import pathlib
import sys

import numpy as np
from scipy.stats import chi2

import probslam as ps
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))  # common.py and the benchmarks reused here
from common import machine, report

Q = np.diag([0.05 ** 2, np.radians(1.0) ** 2])
M = np.diag([0.01, 0.002])
WINDOW = 50  # steps of the moving average used to call the filter inconsistent


def consistency_run(k, steps):
    """Monte-Carlo run k of the consistency study (also used by fastslam_consistency.py): one
    world for every run, run k's noise from seed 1000 + k. A shorter run is a prefix of a longer
    one (the noise is drawn step by step)."""
    world = ps.sim.LandmarkWorld.random(15, 10.0, np.random.default_rng(1), min_separation=2.0)
    sensor = ps.sim.Sensor(Q, max_range=8.0, fov=np.radians(180))
    rng = np.random.default_rng(1000 + k)
    return ps.sim.simulate(world, ps.sim.circle_controls(steps, 1.0, 0.12), 0.2, sensor, M, rng,
                           initial_pose=(0, -8.3, 0))


def consistency(runs, steps):
    nees = np.zeros((runs, steps))
    nis = np.full((runs, steps), np.nan)
    for k in range(runs):
        run = consistency_run(k, steps)
        nees[k], step_nis = ps.sim.filter_known(run, M, Q)
        for t, values in enumerate(step_nis):
            if len(values):
                nis[k, t] = values.mean() / 2  # per degree of freedom
    return nees.mean(0), np.nanmean(nis, 0)


def association(runs, steps, management, clutter, method="ml"):
    precision_hits = precision_total = recall_hits = recall_total = 0
    spurious, duplicates, landmarks = [], [], []
    for k in range(runs):
        rng = np.random.default_rng(2000 + k)
        world = ps.sim.LandmarkWorld.random(20, 12.0, rng, min_separation=2.0)
        sensor = ps.sim.Sensor(Q, max_range=8.0, fov=np.radians(180), clutter_rate=clutter)
        m = np.diag([0.003, 0.0005])
        run = ps.sim.simulate(world, ps.sim.circle_controls(steps, 1.0, 0.1), 0.2, sensor, m, rng,
                              initial_pose=(0, -10.0, 0))
        ekf = ps.EkfSlam(m, Q, use_signatures=False, initial_pose=(0, -10.0, 0), map_management=management)
        votes = collections.defaultdict(collections.Counter)
        log = []
        for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
            ekf.predict(v, w, run.dt)
            if len(z):
                result = ekf.update_unknown(z, association=method)
                log.append((ids, result))
                for t, i, o in zip(ids, result.ids, result.outcome):
                    if o in (0, 1):
                        votes[int(i)][int(t)] += 1
        label = {i: c.most_common(1)[0][0] for i, c in votes.items()}
        first_seen = set()
        for ids, result in log:
            for t, i, o in zip(ids, result.ids, result.outcome):
                if o == 0:
                    precision_total += 1
                    precision_hits += t != ps.sim.CLUTTER_ID and label.get(int(i)) == t
                if t != ps.sim.CLUTTER_ID:
                    if t in first_seen:
                        recall_total += 1
                        recall_hits += o == 0 and label.get(int(i)) == t
                    first_seen.add(t)
        final = [label.get(int(i), ps.sim.CLUTTER_ID) for i in ekf.landmarks().ids]
        spurious.append(sum(1 for t in final if t == ps.sim.CLUTTER_ID))
        duplicates.append(len(final) - len(set(final) - {ps.sim.CLUTTER_ID}) - spurious[-1])
        landmarks.append(len(final))
    return (precision_hits / max(precision_total, 1), recall_hits / max(recall_total, 1), np.mean(spurious),
            np.mean(duplicates), np.mean(landmarks))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    runs, steps = (10, 400) if args.quick else (50, 3000)
    anees, anis = consistency(runs, steps)
    lo, hi = chi2.ppf([0.025, 0.975], 3 * runs) / runs
    smooth = np.convolve(anees, np.ones(WINDOW) / WINDOW, mode="valid")
    above = np.flatnonzero(smooth > hi)
    onset = next((int(i) for i in above if np.all(smooth[i:] > hi)), None)
    lines = [f"## EKF SLAM consistency and association (simulated), {datetime.date.today()}", "",
             f"Machine: {machine()}.", "",
             f"Known correspondences, {runs} Monte-Carlo runs of {steps} steps (0.2 s; circle of radius 8.3 m, "
             "a lap every 262 steps; 15 landmarks, 8 m range, 180 deg field of view). 95% band of the average "
             f"NEES (3 dof): [{lo:.2f}, {hi:.2f}].", "",
             "| steps | average NEES | average NIS per dof |", "|---|---|---|"]
    for a, b in [(5, 100), (100, 300), (300, 600), (600, 1000), (1000, 2000), (2000, 3000)]:
        if b <= steps:
            lines.append(f"| {a}-{b} | {anees[a:b].mean():.2f} | {np.nanmean(anis[a:b]):.2f} |")
    lines += ["", f"The {WINDOW}-step moving average of the NEES leaves the band for good at step "
              f"{onset if onset is not None else 'never (within the run)'}"
              f"{f' ({onset * 0.2:.0f} s, {onset / 262:.1f} laps)' if onset is not None else ''}.", ""]
    lines += ["Unknown correspondences (Table 10.2), 20 landmarks, 1500 steps, clutter 0.5 false detections "
              f"per scan, {max(4, runs // 5)} runs:", "",
              "| association | map management | precision | recall | spurious landmarks | duplicates | map size |",
              "|---|---|---|---|---|---|---|"]
    configs = [("none", ps.MapManagement())]
    prov = ps.MapManagement()
    prov.provisional = True
    ex = ps.MapManagement()
    ex.existence, ex.sensor_range, ex.sensor_fov = True, 8.0, np.radians(180)
    both = ps.MapManagement()
    both.provisional, both.existence, both.sensor_range, both.sensor_fov = True, True, 8.0, np.radians(180)
    configs += [("provisional list", prov), ("existence log-odds", ex), ("both", both)]
    for method in ("ml", "jcbb"):
        for name, mm in configs:
            p, r, s, d, n = association(max(4, runs // 5), 1500 if not args.quick else 400, mm, 0.5, method)
            lines.append(f"| {method} | {name} | {p:.3f} | {r:.3f} | {s:.1f} | {d:.1f} | {n:.1f} |")
    report(lines, record=False)


if __name__ == "__main__":
    main()
