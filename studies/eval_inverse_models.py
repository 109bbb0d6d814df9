"""Ch. 9.3: the hand-made inverse model of Table 9.2 against inverse models learned from the
forward model (probslam.inverse_learning), for a ring of sonars and a 360 degree laser, on
held-out maps of the same prior. Every model maps the same readings with Table 9.1 from the
same prior (the training maps' occupied fraction); the score is over the cells some reading's
perceptual field covers: the per-cell cross-entropy of the final map against the true map
(probabilities clipped to [1e-6, 1 - 1e-6], so one wrong cell costs at most 13.8 nats) and the
classification accuracy (p > 0.5 means occupied). Prints a table (the last full run:
studies/README.md).

    .venv/bin/python studies/eval_inverse_models.py [--quick]
"""

import argparse
import pathlib
import sys
import time

import numpy as np

import probslam as ps
from probslam import inverse_learning as il
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))  # common.py and the benchmarks reused here
from common import heading, report

RES, SIZE = 0.1, 100  # 10 m x 10 m maps
CLIP = 1e-6


def sensors():
    sonar = ps.BeamSensorModel("sonar", 5.0, beta=np.radians(22.5), z_hit=0.8, z_short=0.1, z_max=0.05, z_rand=0.05,
                               sigma_hit=0.05, lambda_short=0.5)
    laser = ps.BeamSensorModel("laser", 5.0, z_hit=0.9, z_short=0.05, z_max=0.03, z_rand=0.02, sigma_hit=0.03,
                               lambda_short=0.5)
    ring = lambda n: np.array([ps.wrap_angle(a) for a in np.arange(n) * 2 * np.pi / n])  # noqa: E731
    return [("sonar, 16 x 22.5 deg cones", sonar, ring(16), sonar.beta / 2),
            ("laser, 90 beams over 360 deg", laser, ring(90), np.pi / 90)]


def scores(p, truth):
    p = np.clip(p, CLIP, 1 - CLIP)
    ce = -np.mean(truth * np.log(p) + (1 - truth) * np.log(1 - p))
    return ce, np.mean((p > 0.5) == truth)


def evaluate(name, model, angles, half, learned, maps, poses_per_map, rng):
    grid0 = ps.OccupancyGrid2D(RES, SIZE, SIZE, p_prior=learned.prior, clamp=None)
    l0 = grid0.l0
    evidence = ps.logit(0.7)  # Table 9.2's l_occ and l_free: l0 +- logit(0.7)
    rows = {"prior only": [], "Table 9.2 (hand-made)": [], "learned (ch. 9.3)": []}
    for _ in range(maps):
        occ = il.random_map(grid0, rng)
        bmap = ps.BinaryMap2D(grid0, occ)
        hand = ps.OccupancyGrid2D(RES, SIZE, SIZE, p_prior=learned.prior, clamp=None)
        mine = ps.OccupancyGrid2D(RES, SIZE, SIZE, p_prior=learned.prior, clamp=None)
        seen = np.zeros(SIZE * SIZE, dtype=bool)
        for pose in il.free_poses(grid0, occ, poses_per_map, rng):
            z = model.sample(pose, angles, bmap, rng)
            hand.insert_cone_scan(pose, z, angles, model.max_range, RES, 2 * half, l0 + evidence, l0 - evidence)
            learned.insert_scan(mine, pose, z, angles, model.max_range, half)
            seen[il.field_features(grid0, pose, z, angles, model.max_range, half)[0]] = True
        truth = occ.ravel()[seen].astype(float)
        rows["prior only"].append(scores(np.full(truth.shape, learned.prior), truth))
        rows["Table 9.2 (hand-made)"].append(scores(hand.probability().ravel()[seen], truth))
        rows["learned (ch. 9.3)"].append(scores(mine.probability().ravel()[seen], truth))
    return [(name, k, *np.mean(v, axis=0)) for k, v in rows.items()]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small training and test sets (smoke run)")
    args = parser.parse_args()
    train_maps, train_poses, test_maps, test_poses = (3, 15, 2, 10) if args.quick else (12, 40, 6, 60)
    lines = heading("Learned inverse sensor models (ch. 9.3)",
                    f"{SIZE} x {SIZE} maps of {RES} m from probslam.inverse_learning.random_map; training: "
                    f"{train_maps} maps x {train_poses} poses, 300 field cells per scan, a 16-unit network "
                    f"trained by L-BFGS on J(W) (eq. 9.20); test: {test_maps} held-out maps x {test_poses} "
                    "scans, Table 9.1 from the training prior, scored over the cells some perceptual field covers.",
                    ["sensor", "inverse model", "cross-entropy (nats/cell)", "accuracy"])
    notes = []
    rng = np.random.default_rng(0)
    grid = ps.OccupancyGrid2D(RES, SIZE, SIZE)
    for name, model, angles, half in sensors():
        t0 = time.perf_counter()
        data = il.sample_training_set(grid, model, angles, train_maps, train_poses, rng, cells_per_scan=300,
                                      half_angle=half)
        learned = il.LearnedInverseModel(16).train(data, rng)
        notes.append(f"{name}: {len(data.occupied)} training cells ({100 * data.occupied.mean():.1f}% occupied), "
                     f"J = {learned.final_objective:.4f} nats/cell, sampling + training {time.perf_counter() - t0:.0f} s.")
        for row in evaluate(name, model, angles, half, learned, test_maps, test_poses, np.random.default_rng(1)):
            lines.append(f"| {row[0]} | {row[1]} | {row[2]:.3f} | {row[3]:.3f} |")
    lines += [""] + notes + [""]
    report(lines, record=False)


if __name__ == "__main__":
    main()
