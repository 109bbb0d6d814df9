"""Renders docs/map3d_scan.png: OctoMap's sample 3-D scan (scan.dat, 88 206 points) inserted
into an OccupancyGrid3D at 0.1 m, occupied voxels drawn as squares coloured by height.

    .venv/bin/python docs/make_map3d_figure.py [--data ../shared/data]
"""

import argparse
import bz2
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import probslam  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--data", default=str(HERE.parents[1] / "shared" / "data"))
    ap.add_argument("--out", default=str(HERE / "map3d_scan.png"))
    args = ap.parse_args()
    scan = pathlib.Path(args.data) / "scans_3d" / "octomap_samples" / "scan.dat.bz2"
    points = np.loadtxt(bz2.open(scan, "rt"), dtype=np.float32)
    grid = probslam.OccupancyGrid3D(0.1)
    stats = grid.insert_point_cloud(points, (0.0, 0.0, 0.0))
    centres, _ = grid.occupied_voxels()
    print(f"{stats.points} points -> {grid.num_known_voxels} known, {len(centres)} occupied voxels, "
          f"{grid.memory_bytes / 2**20:.1f} MiB")

    fig = plt.figure(figsize=(10, 6.5))
    ax = fig.add_subplot(projection="3d")
    z = centres[:, 2]
    ax.scatter(centres[:, 0], centres[:, 1], z, c=z, cmap="viridis", marker="s", s=1.2, linewidths=0,
               vmin=np.percentile(z, 1), vmax=np.percentile(z, 99))
    ax.scatter([0], [0], [0], c="red", s=30, marker="^")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    span = np.ptp(centres, axis=0)
    ax.set_box_aspect(span / span.max())
    ax.view_init(elev=28, azim=-150)
    ax.set_title(f"OctoMap's sample scan (scan.dat) in OccupancyGrid3D, 0.1 m voxels: "
                 f"{len(centres):,} occupied of {grid.num_known_voxels:,} known", fontsize=10)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print("wrote", args.out)


if __name__ == "__main__":
    main()
