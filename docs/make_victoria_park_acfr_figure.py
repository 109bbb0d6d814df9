"""Renders docs/victoria_park_acfr.png: the original Victoria Park run as the SLAM lecture showed
it (GPS in blue, FastSLAM in yellow): FastSLAM 1.0, 100 particles, the defaults, seeds 0-9, the
best particle's paths over the GPS fixes with seed 0's map; beside it the RMS against GPS per
seed (SE(2)-aligned) of FastSLAM 1.0 and 2.0, with the EKF's. Draws the runs the benchmark saved:

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_victoria_park_acfr.py DIR --save runs.npz
    .venv/bin/python docs/make_victoria_park_acfr_figure.py runs.npz
"""

import argparse
import pathlib

import numpy as np

import probslam as ps
from probslam.plot import require_matplotlib

HERE = pathlib.Path(__file__).resolve().parent


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", help="the .npz of bench_victoria_park_acfr.py --save")
    args = parser.parse_args()
    runs = np.load(args.runs)
    gps = runs["gps"]

    def rms(key):
        r = runs[key]
        return ps.eval.position_error(r[:, 0], r[:, 1:], gps[:, 0], gps[:, 1:]).rmse_aligned

    seeds = sorted(int(k.split("seed")[1]) for k in runs.files if k.startswith("fastslam1_seed"))
    plt = require_matplotlib()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(15, 6.5), gridspec_kw=dict(width_ratios=(2.2, 1)))
    ax.plot(gps[:, 1], gps[:, 2], ".", ms=2.5, color="tab:blue", label="GPS")
    for k in seeds:
        path = runs[f"fastslam1_seed{k}"]
        ax.plot(path[:, 1], path[:, 2], "-", lw=0.6, color="gold", alpha=0.85,
                label=f"FastSLAM 1.0, seeds {seeds[0]}-{seeds[-1]}" if k == seeds[0] else None)
    lm = runs["fastslam1_map"]
    ax.plot(lm[:, 0], lm[:, 1], "+", ms=3, color="k", label=f"seed 0's map ({len(lm)} landmarks)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize="small", loc="lower right")
    ax.set_title("Victoria Park (ACFR run, 1,549 s): FastSLAM 1.0, 100 particles, unknown correspondences",
                 fontsize="medium")
    for v, marker in ((1, "o"), (2, "s")):
        keys = [f"fastslam{v}_seed{k}" for k in seeds if f"fastslam{v}_seed{k}" in runs.files]
        bx.plot(range(len(keys)), [rms(k) for k in keys], marker, label=f"FastSLAM {v}.0")
    bx.axhline(rms("EKF SLAM (JCBB)"), color="tab:green", lw=1, label="EKF SLAM (JCBB)")
    bx.axhline(5.0, color="tab:red", lw=0.8, ls="--", label="the lecture's 5 m")
    bx.set_xlabel("seed")
    bx.set_ylabel("RMS against GPS, SE(2)-aligned [m]")
    bx.set_ylim(0, 6)
    bx.legend(fontsize="small")
    fig.tight_layout()
    out = HERE / "victoria_park_acfr.png"
    fig.savefig(out, dpi=90)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
