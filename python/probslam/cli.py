"""The ``probslam`` command line."""

from __future__ import annotations

import argparse
import sys
import time
from importlib import resources
from typing import List, Optional

from . import io
from .mapping import map_laser_log

BUNDLED_LOG = "intel_excerpt.log.gz"


def _bundled_log() -> str:
    return str(resources.files("probslam") / "data" / BUNDLED_LOG)


def _cmd_map(args: argparse.Namespace) -> int:
    path = args.log or _bundled_log()
    t0 = time.perf_counter()
    log = io.read_carmen_log(path)
    grid, summary = map_laser_log(log.scans, resolution=args.resolution, max_range=args.max_range,
                                  robot_radius=args.robot_radius,
                                  skip_no_return=not args.keep_no_return, progress=None if args.progress else False)
    io.save_ros_map(grid, args.output + ".yaml")
    io.write_png(grid, args.output + ".png", trajectory=log.scans.laser_poses)
    total = time.perf_counter() - t0
    rate = summary.beams / summary.seconds / 1e6 if summary.seconds > 0 else float("inf")
    print(f"log:           {path}{' (bundled Intel Research Lab excerpt)' if not args.log else ''}")
    print(f"scans:         {summary.scans}")
    print(f"beams:         {summary.beams}")
    print(f"cells updated: {summary.cells_updated}")
    print(f"map:           {grid.width} x {grid.height} cells at {grid.resolution} m, origin {grid.origin}")
    print(f"time:          {total:.2f} s total, {summary.seconds:.3f} s mapping ({rate:.2f} M beams/s)")
    print(f"wrote:         {args.output}.yaml, {args.output}.pgm, {args.output}.png")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="probslam", description="Probabilistic robot mapping and SLAM.")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("map", help="occupancy grid map of a CARMEN laser log with known (corrected) poses")
    p.add_argument("log", nargs="?", help="CARMEN log (.log/.clf, optionally .gz/.bz2); "
                                          "default: a bundled excerpt of the Intel Research Lab log")
    p.add_argument("--resolution", type=float, default=0.05, help="cell size in metres (default 0.05)")
    p.add_argument("--max-range", type=float, default=30.0,
                   help="readings at or beyond this (metres) only clear space (default 30)")
    p.add_argument("--robot-radius", type=float, default=0.0, help="clear the robot's footprint (metres)")
    p.add_argument("--keep-no-return", action="store_true",
                   help="let readings at the sensor maximum clear space (default: skip them)")
    p.add_argument("-o", "--output", default="map", help="output prefix: PREFIX.yaml/.pgm/.png (default 'map')")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="never show a progress bar")
    p.set_defaults(func=_cmd_map)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, OSError) as exc:
        print(f"probslam: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
