"""3-D occupancy insertion: probslam.OccupancyGrid3D against octomap::OcTree::insertPointCloud.

Runs the C++ benchmark (benchmarks/bench_grid3d.cpp; build it with
`cmake -S . -B build/bench -G Ninja -DPROBSLAM_BUILD_BENCHMARKS=ON && cmake --build build/bench`)
once per implementation, resolution and thread count, so that each peak RSS is its own, on the
same simulated clouds (a 64-beam lidar circling a 60 x 60 m courtyard, ~100 k points per scan,
20 m max range), checks that both maps hold the same voxels with the same log-odds
(fingerprint), and prints a markdown table; --record writes it into RESULTS.md.

    python benchmarks/bench_grid3d.py [--scans 100] [--scans-fine 25] [--record]
"""

import argparse
import datetime
import pathlib
import subprocess
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from common import machine, report  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEFAULT_BINARY = ROOT / "build" / "bench" / "benchmarks" / "bench_grid3d"


def run(binary, impl, res, scans, threads):
    out = subprocess.run([str(binary), "--impl", impl, "--res", str(res), "--scans", str(scans),
                          "--threads", str(threads)], check=True, capture_output=True, text=True).stdout
    fields = dict(kv.split("=", 1) for kv in out.split())
    print(" ", out.strip(), file=sys.stderr)
    return fields


def mb(n_bytes):
    return f"{int(n_bytes) / 2**20:.1f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", default=str(DEFAULT_BINARY))
    ap.add_argument("--scans", type=int, default=100, help="scans at 0.1 m")
    ap.add_argument("--scans-fine", type=int, default=25, help="scans at 0.05 m (OctoMap needs ~8 s per scan)")
    ap.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    args = ap.parse_args()

    rows = []
    for res, scans in ((0.1, args.scans), (0.05, args.scans_fine)):
        octo = run(args.binary, "octomap", res, scans, 1)
        one = run(args.binary, "ours", res, scans, 1)
        two = run(args.binary, "ours", res, scans, 2)
        same = octo["fingerprint"] == one["fingerprint"] == two["fingerprint"] and octo["voxels"] == one["voxels"]
        r_o, r_1, r_2 = (float(x["points_per_s"]) for x in (octo, one, two))
        c_o, c_1 = (float(x["points_per_cpu_s"]) for x in (octo, one))
        rows.append(
            f"| {res} | {scans} x {int(one['points']) // scans / 1000:.0f} k | {r_o / 1e6:.3f} | {r_1 / 1e6:.3f} | "
            f"**{r_1 / r_o:.1f}x** | {c_1 / c_o:.1f}x | {r_2 / 1e6:.3f} | {r_2 / r_1:.2f}x | {mb(octo['map_bytes'])} | "
            f"{mb(one['map_bytes'])} | {int(octo['peak_rss_kb']) / 1024:.0f} | {int(one['peak_rss_kb']) / 1024:.0f} | "
            f"{int(one['voxels']) / 1e6:.2f} M | {'yes' if same else '**NO**'} |")

    lines = [
        # The scan counts are part of the title: runs of other sizes keep their own RESULTS.md sections.
        f"## 3-D occupancy insertion vs OctoMap 1.9.7 (C++, {args.scans} + {args.scans_fine} scans), "
        f"{datetime.date.today().isoformat()}",
        "",
        f"Machine: {machine()}.",
        "",
        "Simulated 64-beam lidar (+2 to -24.8 deg, 1563 azimuths) at 1.8 m on a robot circling a 60 x 60 m "
        "courtyard (12 m facades, pillars, cars, a fountain), 0.6 m between scans, max range 20 m. "
        "OctoMap: `OcTree::insertPointCloud(cloud, origin, 20, lazy_eval=false, discretize=false)`; ours: "
        "`OccupancyGrid3D::insert_point_cloud` on the same float clouds. Insertion time only (the simulation "
        "is not timed); points/s over wall time, and the speed-up also over each process's CPU time "
        "(CLOCK_PROCESS_CPUTIME_ID; on a shared machine wall time counts other processes' turns too). Memory: `OcTree::memoryUsage()` and our `memory_bytes()` after the last scan; peak "
        "RSS of each process (each run alone). Identical: same known voxels and bit-identical log-odds "
        "(order-independent fingerprint over all voxels, OctoMap's pruned nodes expanded).",
        "",
        "| res (m) | scans x points | OctoMap (M pts/s) | ours, 1 thread | speed-up | speed-up in CPU time "
        "| ours, 2 threads | 2 vs 1 thread | OctoMap map (MiB) | our map (MiB) | OctoMap peak RSS (MiB) "
        "| our peak RSS (MiB) | known voxels | identical |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Command: `python benchmarks/bench_grid3d.py --scans {args.scans} --scans-fine {args.scans_fine}"
        f"{' --record' if args.record else ''}`.",
        "",
    ]
    report(lines, args.record)


if __name__ == "__main__":
    main()
