"""Renders docs/map_open_door.png, the book's open-door example (Figs. 9.7/9.8): (a) the true map
with the noise-free sonar readings, (b) the standard algorithm (Table 9.1 with the cone model
of Table 9.2), (c) the MAP map of Table 9.3, (d) its residual uncertainty (Fig. 9.8d: how much
eq. 9.24 drops when each cell alone is flipped). Prints the cell counts quoted in docs/occupancy_mapping.md.

    .venv/bin/python docs/make_open_door_figure.py
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import probslam  # noqa: E402
from probslam.sim import open_door_scenario  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=str(HERE / "map_open_door.png"))
    args = ap.parse_args()
    sc = open_door_scenario()
    standard = sc.standard_map()
    cls = np.sign(standard.log_odds - standard.l0)  # +1 occupied, 0 unknown, -1 free
    r = probslam.map_occupancy_grid_mapping(sc.poses, sc.scans, sc.beam_angles, sc.model, sc.grid)
    field = r.field
    map_wrong = int(np.sum((r.occupied != sc.truth) & field))
    known = (cls != 0) & field
    std_wrong = int(np.sum(((cls > 0) != sc.truth) & known))
    std_unknown = int(np.sum((cls == 0) & field))
    map_wrong_known = int(np.sum((r.occupied != sc.truth) & known))
    print(f"readings {r.readings}, observed cells {field.sum()}, sweeps {r.sweeps}, flips {r.flips}")
    print(f"door cells {sc.door.sum()}: standard occupied {int(np.sum(cls[sc.door] > 0))}, "
          f"unknown {int(np.sum(cls[sc.door] == 0))}, free {int(np.sum(cls[sc.door] < 0))}; "
          f"MAP occupied {int(r.occupied[sc.door].sum())}")
    print(f"cells differing from the truth over the observed cells: MAP {map_wrong}; standard {std_wrong} "
          f"(+{std_unknown} left unknown); over the {known.sum()} cells the standard map decided: "
          f"MAP {map_wrong_known}, standard {std_wrong}")

    extent = (0, sc.grid.width * sc.grid.resolution, 0, sc.grid.height * sc.grid.resolution)
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5))
    kw = dict(origin="lower", extent=extent, interpolation="nearest")
    ax = axes[0, 0]
    ax.imshow(np.where(sc.truth, 0.0, 1.0), cmap="gray", vmin=0, vmax=1, **kw)
    for k in range(0, len(sc.poses), 8):  # every 8th pose's readings, to keep the cones legible
        p = sc.poses[k]
        for a, z in zip(sc.beam_angles, sc.scans[k]):
            if z < sc.model.max_range:
                e = p[:2] + z * np.array([np.cos(p[2] + a), np.sin(p[2] + a)])
                ax.plot([p[0], e[0]], [p[1], e[1]], color="tab:orange", lw=0.4, alpha=0.6)
    ax.plot(sc.poses[:, 0], sc.poses[:, 1], color="tab:blue", lw=1.5)
    ax.set_title(f"(a) true map, noise-free sonar ({len(sc.beam_angles)} sonars, "
                 f"{np.degrees(sc.model.beta):.0f}° cones)")
    ax = axes[0, 1]
    ax.imshow(1.0 - standard.probability(), cmap="gray", vmin=0, vmax=1, **kw)
    ax.set_title(f"(b) standard algorithm (Tables 9.1, 9.2): {std_wrong} wrong, {std_unknown} unknown")
    ax = axes[1, 0]
    ax.imshow(np.where(r.occupied, 0.0, np.where(field, 1.0, 0.5)), cmap="gray", vmin=0, vmax=1, **kw)
    ax.set_title(f"(c) MAP map (Table 9.3): {map_wrong} wrong")
    ax = axes[1, 1]
    im = ax.imshow(np.log10(1.0 + np.abs(r.sensitivity)), cmap="gray_r", **kw)
    ax.set_title("(d) residual uncertainty (Fig. 9.8d): log10(1 + |eq. 9.24 drop|),\n"
                 "dark: a flip costs much (certain), light: it costs little")
    fig.colorbar(im, ax=ax, shrink=0.8)
    for ax in axes.flat:
        ax.set_xlim(1.0, 9.0)
        ax.set_ylim(0.5, 5.8)
        ax.set_aspect("equal")
        d = np.argwhere(sc.door)
        ax.add_patch(plt.Rectangle((d[:, 1].min() * sc.grid.resolution, d[0, 0] * sc.grid.resolution),
                                   len(d) * sc.grid.resolution, sc.grid.resolution, fill=False, ec="tab:red", lw=1.2))
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print("wrote", args.out)


if __name__ == "__main__":
    main()
