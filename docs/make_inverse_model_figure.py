"""Renders docs/inverse_models.png, beside the book's Fig. 9.6: for a sonar ring and a laser
(the sensors of studies/eval_inverse_models.py) on a held-out world of the rooms prior,
(a) the true map with one scan, (b) Table 9.2's local map of that scan, (c) the learned model's
local map of the same scan (f of each field cell: Fig. 9.6's kind of picture), then the maps of
60 scans: (d) Table 9.2, (e) the learned model with its fitted evidence scale. Trains smaller
models than the study (6 maps x 30 poses) so that it runs in a few minutes.

    .venv/bin/python docs/make_inverse_model_figure.py
"""

import argparse
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import probslam as ps  # noqa: E402
from probslam import inverse_learning as il  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "studies"))
from eval_inverse_models import RES, SIZE, sensors  # noqa: E402

SCANS = 60


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=str(HERE / "inverse_models.png"))
    args = ap.parse_args()
    grid = ps.OccupancyGrid2D(RES, SIZE, SIZE)
    fig, axes = plt.subplots(2, 5, figsize=(17, 7.2))
    extent = (0, SIZE * RES, 0, SIZE * RES)
    for row, (name, model, angles, half) in zip(axes, sensors()):
        rng = np.random.default_rng(0)
        data = il.sample_training_set(grid, model, angles, 6, 30, rng, cells_per_scan=300, half_angle=half)
        learned = il.LearnedInverseModel(16).train(data, rng)
        learned.fit_evidence_scale(il.sample_scans(grid, model, angles, 3, SCANS, rng), grid, angles,
                                   model.max_range, half)
        occ, poses, scans = il.sample_scans(grid, model, angles, 1, SCANS, np.random.default_rng(1))[0]
        l0, ev = float(ps.logit(learned.prior)), float(ps.logit(0.7))
        new = lambda: ps.OccupancyGrid2D(RES, SIZE, SIZE, p_prior=learned.prior, clamp=None)  # noqa: E731
        one_hand, one_learned, hand, mine = new(), new(), new(), new()
        one_hand.insert_cone_scan(poses[0], scans[0], angles, model.max_range, RES, 2 * half, l0 + ev, l0 - ev)
        cells, x = il.field_features(grid, poses[0], scans[0], angles, model.max_range, half)
        local = np.full(SIZE * SIZE, np.nan)
        local[cells] = learned.probability(x)
        for pose, z in zip(poses, scans):
            hand.insert_cone_scan(pose, z, angles, model.max_range, RES, 2 * half, l0 + ev, l0 - ev)
            learned.insert_scan(mine, pose, z, angles, model.max_range, half)
        ends = poses[0][:2] + np.minimum(scans[0], model.max_range)[:, None] * np.column_stack(
            [np.cos(poses[0][2] + angles), np.sin(poses[0][2] + angles)])
        panels = [("(a) true map, one scan", occ.astype(float)),
                  ("(b) Table 9.2, that scan", one_hand.probability()),
                  ("(c) learned f, that scan (Fig. 9.6)", local.reshape(SIZE, SIZE)),
                  (f"(d) Table 9.2, {SCANS} scans", hand.probability()),
                  (f"(e) learned x {learned.evidence_scale:.2f}, {SCANS} scans", mine.probability())]
        for ax, (title, img) in zip(row, panels):
            ax.imshow(1 - img, origin="lower", extent=extent, cmap="gray", vmin=0, vmax=1)
            ax.set_title(f"{name}: {title}", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
        for ax in row[:3]:
            ax.plot(*poses[0][:2], "r^", ms=6)
        for e in ends:
            row[0].plot([poses[0][0], e[0]], [poses[0][1], e[1]], "r-", lw=0.5)
        row[0].set_xlim(extent[:2])
        row[0].set_ylim(extent[2:])
    fig.tight_layout()
    fig.savefig(args.out, dpi=80)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
