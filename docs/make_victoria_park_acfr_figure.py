"""Renders docs/victoria_park_acfr.png: the original Victoria Park run as the SLAM lecture showed
it (GPS in blue, FastSLAM in yellow): FastSLAM 1.0, 100 particles, the defaults, seeds 0-9, the
best particle's paths over the GPS fixes with seed 0's map; beside it the RMS against GPS per
seed (SE(2)-aligned) of FastSLAM 1.0 and 2.0, with the EKF's. Draws the runs the benchmark's
sweep kept (its table and trajectories), and runs seed 0 of FastSLAM 1.0 again for its map:

    PROBSLAM_SHARED_DATA=../shared/data OPENBLAS_NUM_THREADS=1 .venv/bin/probslam batch \\
        benchmarks/sweeps/victoria_park_acfr.toml -o OUT --trajectories
    .venv/bin/python docs/make_victoria_park_acfr_figure.py OUT [DATA]
"""

import argparse
import pathlib

import numpy as np

from probslam import batch, io
from probslam.batch import table
from probslam.datasets import victoria_park_acfr, victoria_park_acfr_run
from probslam.plot import require_matplotlib

HERE = pathlib.Path(__file__).resolve().parent
DEFAULT = HERE.parents[1] / "shared/data/landmark_slam/victoria_park_acfr"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", help="the folder of the sweep's table (probslam batch ... -o OUT --trajectories)")
    parser.add_argument("data", nargs="?", default=str(DEFAULT), help="the dataset's folder")
    args = parser.parse_args()
    data = victoria_park_acfr.load(args.data)
    gps = data.gps
    rows = [r for r in table.read(args.runs) if r["status"] == "ok" and r.get("options.refine", "none") == "none"]
    fastslam = {(r["options.fastslam.version"], r["seed"]): r for r in rows if r["kind"] == "fastslam"}
    ekf = next(r for r in rows if r["kind"] == "ekf-slam")
    seeds = sorted(s for v, s in fastslam if v == 1)

    def path(row):
        t = io.read_trajectory(str(pathlib.Path(args.runs) / batch.TRAJECTORIES / row["trajectory"]))
        return np.column_stack([t.timestamps, t.poses[:, :2]])

    plt = require_matplotlib()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(15, 6.5), gridspec_kw=dict(width_ratios=(2.2, 1)))
    ax.plot(gps[:, 1], gps[:, 2], ".", ms=2.5, color="tab:blue", label="GPS")
    for k in seeds:
        p = path(fastslam[1, k])
        ax.plot(p[:, 1], p[:, 2], "-", lw=0.6, color="gold", alpha=0.85,
                label=f"FastSLAM 1.0, seeds {seeds[0]}-{seeds[-1]}" if k == seeds[0] else None)
    lm = np.array(list(victoria_park_acfr_run.run_fastslam(data, version=1, seed=0).landmarks.values())).reshape(-1, 2)
    ax.plot(lm[:, 0], lm[:, 1], "+", ms=3, color="k", label=f"seed 0's map ({len(lm)} landmarks)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize="small", loc="lower right")
    ax.set_title("Victoria Park (ACFR run, 1,549 s): FastSLAM 1.0, 100 particles, unknown correspondences",
                 fontsize="medium")
    for v, marker in ((1, "o"), (2, "s")):
        mine = [fastslam[v, k] for k in seeds if (v, k) in fastslam]
        bx.plot([r["seed"] for r in mine], [r["position_rmse_aligned_m"] for r in mine], marker,
                label=f"FastSLAM {v}.0")
    bx.axhline(ekf["position_rmse_aligned_m"], color="tab:green", lw=1, label="EKF SLAM (JCBB)")
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
