"""Ch. 9.3: the hand-made inverse model of Table 9.2 against inverse models learned from the
forward model (probslam.inverse_learning), for a ring of sonars and a 360 degree laser.

Training: maps of the rooms prior (random_map), scans sampled from the forward model, a 16-unit
network trained on J(W) (eq. 9.20); then the evidence scale of Table 9.1's update fitted on
other training worlds of the same prior (fit_evidence_scale). Test: held-out worlds of the rooms
prior, of the pillars prior (slanted walls and round pillars, never trained on) and, when
/work/shared/data is present, the Intel Research Lab floor plan (a map built from the corrected
log) as a world. Every model maps the same readings with Table 9.1 from the same prior (the
training maps' occupied fraction); the score is over the cells some reading's perceptual field
covers: the per-cell cross-entropy of the final map against the true map and the classification
accuracy (p > 0.5 means occupied).

Measurements of the cause (issue 37): the calibration of the single-scan probabilities on
held-out scans (reliability table, expected calibration error), the map cross-entropy with the
learned log-odds scaled by a factor, and the cross-entropy of maps from 1, 2, 5 and 20 scans.

    .venv/bin/python studies/eval_inverse_models.py [--quick]
"""

import argparse
import pathlib
import sys
import time

import numpy as np

import probslam as ps
from probslam import inverse_learning as il

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from eval_inverse_real import intel_floor_plan  # noqa: E402  (the Intel floor plan as a world)

RES, SIZE = 0.1, 100  # 10 m x 10 m maps
BINS = 10  # reliability table: 10 equal-width bins of the predicted probability
SCALES = (0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0)
COUNTS = (1, 2, 5, 20)


def sensors():
    sonar = ps.BeamSensorModel("sonar", 5.0, beta=np.radians(22.5), z_hit=0.8, z_short=0.1, z_max=0.05, z_rand=0.05,
                               sigma_hit=0.05, lambda_short=0.5)
    laser = ps.BeamSensorModel("laser", 5.0, z_hit=0.9, z_short=0.05, z_max=0.03, z_rand=0.02, sigma_hit=0.03,
                               lambda_short=0.5)
    ring = lambda n: np.array([ps.wrap_angle(a) for a in np.arange(n) * 2 * np.pi / n])  # noqa: E731
    return [("sonar", sonar, ring(16), sonar.beta / 2), ("laser", laser, ring(90), np.pi / 90)]


def per_scan_evidence(learned, grid, model, angles, half, poses, scans):
    """For each scan: (learned cells, learned evidence, features) and Table 9.2's log-odds change
    over the whole grid (l0 +- logit(0.7), a cone of 2 half)."""
    l0, ev = float(ps.logit(learned.prior)), float(ps.logit(0.7))
    out = []
    for pose, z in zip(poses, scans):
        cells, x = il.field_features(grid, pose, z, angles, model.max_range, half)
        e = ps.logit(learned.probability(x)) - l0 if cells.size else np.empty(0)
        hand = ps.OccupancyGrid2D(grid.resolution, grid.shape[1], grid.shape[0], origin=grid.origin,
                                  p_prior=learned.prior, clamp=None)
        hand.insert_cone_scan(pose, z, angles, model.max_range, grid.resolution, 2 * half, l0 + ev, l0 - ev)
        out.append((cells, e, x, hand.log_odds.ravel() - l0))
    return out


def map_scores(learned, occ, evidence, count=None, scales=(), mask=None):
    """Cross-entropy and accuracy of the maps from the first ``count`` scans: prior only,
    Table 9.2, learned with each scale in ``scales``."""
    n = occ.size
    l0 = float(ps.logit(learned.prior))
    seen, total, hand = np.zeros(n, bool), np.zeros(n), np.zeros(n)
    for cells, e, _, h in evidence[:count]:
        seen[cells] = True
        np.add.at(total, cells, e)
        hand += h
    if mask is not None:
        seen &= mask.ravel()
    y = occ.ravel()[seen]
    rows = {"prior only": np.full(y.size, l0), "Table 9.2": l0 + hand[seen]}
    for s in scales:
        rows[f"learned x {s:.3g}"] = l0 + s * total[seen]
    return {k: (il.map_cross_entropy(v, y), np.mean((v > 0) == y), y.size) for k, v in rows.items()}


def calibration(learned, occs, evidences, mask=None):
    """Reliability table of the single-scan probabilities over all field cells of held-out scans."""
    p, y = [], []
    for occ, ev in zip(occs, evidences):
        for cells, _, x, _ in ev:
            keep = np.ones(cells.size, bool) if mask is None else mask.ravel()[cells]
            p.append(learned.probability(x[keep]))
            y.append(occ.ravel()[cells[keep]])
    p, y = np.concatenate(p), np.concatenate(y)
    b = np.minimum((p * BINS).astype(int), BINS - 1)
    table, ece = [], 0.0
    for k in range(BINS):
        m = b == k
        if m.any():
            table.append((k / BINS, (k + 1) / BINS, int(m.sum()), p[m].mean(), y[m].mean()))
            ece += m.sum() / p.size * abs(p[m].mean() - y[m].mean())
    return table, ece, il.map_cross_entropy(ps.logit(np.clip(p, il.EPS, 1 - il.EPS)), y)


def average(dicts):
    keys = dicts[0].keys()
    return {k: tuple(np.mean([d[k][i] for d in dicts]) for i in range(3)) for k in keys}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small training and test sets (smoke run)")
    args = parser.parse_args()
    train_maps, train_poses, fit_maps, test_maps, test_poses = (3, 15, 2, 2, 20) if args.quick else (8, 40, 3, 3, 60)
    grid = ps.OccupancyGrid2D(RES, SIZE, SIZE)
    plan = intel_floor_plan(RES)  # None without /work/shared/data
    print(f"# Learned inverse sensor models (ch. 9.3): {SIZE} x {SIZE} maps of {RES} m; training {train_maps} maps x "
          f"{train_poses} poses (300 cells per scan), scale fitted on {fit_maps} other training maps x {test_poses} "
          f"scans; test {test_maps} held-out maps x {test_poses} scans per world kind\n")
    for name, model, angles, half in sensors():
        rng = np.random.default_rng(0)
        t0 = time.perf_counter()
        data = il.sample_training_set(grid, model, angles, train_maps, train_poses, rng, cells_per_scan=300,
                                      half_angle=half)
        learned = il.LearnedInverseModel(16).train(data, rng)
        t1 = time.perf_counter()
        fit_worlds = il.sample_scans(grid, model, angles, fit_maps, test_poses, rng)
        scale = learned.fit_evidence_scale(fit_worlds, grid, angles, model.max_range, half)
        t2 = time.perf_counter()
        print(f"## {name}: {data.occupied.size} training cells ({100 * learned.prior:.1f}% occupied), "
              f"J = {learned.final_objective:.4f}, sampling + training {t1 - t0:.0f} s; fitted evidence scale "
              f"{scale:.3f} ({t2 - t1:.0f} s)\n")
        kinds = [("rooms", grid, lambda g, r: il.random_map(g, r), None), ("pillars", grid, il.pillar_map, None)]
        if plan is not None:
            kinds.append(("Intel floor plan", plan[0], lambda g, r, occ=plan[1]: occ, plan[2]))
        for kind, g, world, mask in kinds:
            worlds = il.sample_scans(g, model, angles, test_maps, test_poses, np.random.default_rng(1), world=world)
            evs = [per_scan_evidence(learned, g, model, angles, half, poses, z) for _, poses, z in worlds]
            occs = [w[0] for w in worlds]
            table, ece, ce1 = calibration(learned, occs, evs, mask)
            print(f"### {name} on {kind}: single-scan calibration (held-out scans): ECE {ece:.4f}, "
                  f"cross-entropy per field cell {ce1:.4f}")
            print("| p bin | cells | mean predicted | observed occupied |\n|---|---|---|---|")
            for lo, hi, n, pm, ym in table:
                print(f"| [{lo:.1f}, {hi:.1f}) | {n} | {pm:.3f} | {ym:.3f} |")
            print("\nmap cross-entropy (accuracy) by number of scans per world:")
            counts = tuple(c for c in COUNTS if c < test_poses) + (test_poses,)
            print("| model | " + " | ".join(f"{c} scans" for c in counts) + " |")
            print("|---|" + "---|" * len(counts))
            res = [average([map_scores(learned, o, e, c, SCALES + (scale,), mask) for o, e in zip(occs, evs)])
                   for c in counts]
            for k in res[0]:
                label = k + (" (fitted)" if k == f"learned x {scale:.3g}" else "")
                print(f"| {label} | " + " | ".join(f"{r[k][0]:.3f} ({r[k][1]:.3f})" for r in res) + " |")
            print()


if __name__ == "__main__":
    main()
