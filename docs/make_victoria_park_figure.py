"""Renders docs/victoria_park_graph.png: Victoria Park as a pose/landmark graph, batch
Levenberg-Marquardt from dead reckoning (a wrong minimum) beside Gauss-Newton from the EKF SLAM
estimate (the optimum), drawn with probslam.plot.pose_graph.

    .venv/bin/python docs/make_victoria_park_figure.py [--data ../shared/data]
"""

import argparse
import pathlib

from probslam import graph as pg
from probslam.plot import pose_graph, require_matplotlib

HERE = pathlib.Path(__file__).resolve().parent


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(HERE.parents[1] / "shared" / "data"))
    args = parser.parse_args()
    path = pathlib.Path(args.data) / "landmark_slam" / "victoria_park" / "victoriaPark.txt"
    trapped = pg.read_pose_graph(str(path))
    dead_reckoning = trapped.poses
    lm = pg.optimize(trapped, algorithm="levenberg-marquardt")
    seeded = pg.read_pose_graph(str(path))
    pg.initialize(seeded, "ekf")
    ekf = seeded.poses
    gn = pg.optimize(seeded)
    plt = require_matplotlib()
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.5))
    pose_graph(axes[0], trapped, initial=dead_reckoning, edges=False)
    axes[0].set_title(f"LM from dead reckoning: chi2 {lm.chi2:.4g} ({lm.iterations} it.)")
    pose_graph(axes[1], seeded, initial=ekf, edges=False)
    axes[1].set_title(f"GN from the EKF SLAM estimate: chi2 {gn.chi2:.2f} ({gn.iterations} it.)")
    fig.tight_layout()
    fig.savefig(HERE / "victoria_park_graph.png", dpi=90)


if __name__ == "__main__":
    main()
