"""Correlative scan matching: scan matches per second of probslam's CorrelativeScanMatcher in three
modes (branch and bound without refinement, branch and bound with refinement, C++ brute force)
next to a vectorised numpy brute force of the same window in the same run: the same lattice (the
same linear cells, the same angular steps as the C++ search reports, the same likelihood-field
table and the same discretisation of the rotated scan). The numpy search and every C++ mode must
find the same best lattice pose ('same best'). Prints a table; --record writes it
into benchmarks/RESULTS.md.

Workloads: (a) simulated scans in a 10 x 8 m room with a pillar (as in
tests/python/test_scan_matching.py); (b) when ../shared/data/laser_2d/aces exists, scans of the
ACES corrected log matched against a local map of the 10 scans before them, inserted at their
corrected poses. Each scan's prior is its true (corrected) pose perturbed by up to 0.2 m and
0.1 rad; window +-0.3 m, +-0.35 rad, automatic angular step; no odometry prior term.

    .venv/bin/python benchmarks/bench_scan_matching.py [--quick] [--record]
"""

import argparse
import os
import pathlib
import time

import numpy as np

import probslam as ps
from common import heading, report
from probslam import _core
from probslam.sim import cast_ranges

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
ACES = SHARED / "laser_2d" / "aces"

RES = 0.05
LINEAR, ANGULAR = 0.3, 0.35  # the matcher's default window
SIGMA = 0.05
#: Largest number of table lookups one numpy block gathers (bounds its memory to ~100 MB).
NUMPY_BLOCK = 1 << 22

# --- (a) the simulated room of tests/python/test_scan_matching.py ------------------------------

ROOM_ORIGIN = (-6.0123, -5.9871)  # walls off the cell borders
WALLS = [((-5, -4), (5, -4)), ((5, -4), (5, 4)), ((5, 4), (-5, 4)), ((-5, 4), (-5, -4)),
         ((1, 1), (2, 1)), ((2, 1), (2, 2)), ((2, 2), (1, 2)), ((1, 2), (1, 1)), ((-3, -2), (-1, -3))]
ROOM_ANGLES = np.linspace(-np.pi / 2, np.pi / 2, 181)


def cast(pose, angles):
    """Ranges from pose along angles to the nearest wall (inf when none), analytically."""
    return cast_ranges(pose, angles, WALLS)


def room_problems(n, rng):
    """(field, [(points, prior)]) for n scans at random poses in the room."""
    grid = ps.OccupancyGrid2D.covering((ROOM_ORIGIN[0], ROOM_ORIGIN[1], 6, 6), RES)
    for _ in range(20):
        pose = np.array([rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3)])
        grid.insert_rays(pose, cast(pose, ROOM_ANGLES), ROOM_ANGLES, 30.0)
    field = _core.LikelihoodField(grid, sigma=SIGMA)
    problems = []
    while len(problems) < n:
        true = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-np.pi, np.pi)])
        if 0.7 < true[0] < 2.3 and 0.7 < true[1] < 2.3:  # inside the pillar
            continue
        ranges = cast(true, ROOM_ANGLES) + rng.normal(0, 0.01, len(ROOM_ANGLES))
        points = _core.scan_hits(ranges, ROOM_ANGLES)
        problems.append((field, points, true + rng.uniform([-0.2, -0.2, -0.1], [0.2, 0.2, 0.1])))
    return problems


# --- (b) ACES: each scan against a local map of the scans before it ---------------------------

def aces_problems(n, rng, previous=10, max_usable=30.0):
    """[(field, points, prior)] for n scans of the ACES corrected log spread over the log, each
    with the field of a grid of the `previous` scans before it at their corrected poses."""
    log = ps.io.read_carmen_log(ACES / "aces-corrected.log.gz")
    s = log.scans
    no_return = s.no_return_range()
    angles = s.beam_angles()
    insert = np.where(s.ranges >= no_return, np.nan, s.ranges)
    problems = []
    for k in np.linspace(previous, len(s) - 1, n).astype(int):
        before = slice(k - previous, k)
        poses, r, a = s.laser_poses[before], insert[before], angles[before]
        reach = np.minimum(np.nan_to_num(r, nan=0.0), max_usable)
        ex = poses[:, :1] + reach * np.cos(poses[:, 2:3] + a)
        ey = poses[:, 1:2] + reach * np.sin(poses[:, 2:3] + a)
        lo = np.minimum([ex.min(), ey.min()], s.laser_poses[k, :2] - 1.0) - 1.0
        hi = np.maximum([ex.max(), ey.max()], s.laser_poses[k, :2] + 1.0) + 1.0
        grid = ps.OccupancyGrid2D.covering((lo[0], lo[1], hi[0], hi[1]), RES)
        grid.insert_scans(poses, r, a, max_usable)
        field = _core.LikelihoodField(grid, sigma=SIGMA)
        points = _core.scan_hits(s.ranges[k], angles[k], max_range=no_return, max_usable_range=max_usable)
        prior = s.laser_poses[k] + rng.uniform([-0.2, -0.2, -0.1], [0.2, 0.2, 0.1])
        problems.append((field, points, prior))
    return problems, len(s)


# --- the numpy brute force --------------------------------------------------------------------

def numpy_brute_force(field, points, prior, linear_cells, angular_steps, step):
    """Best lattice pose (a, cx, cy) and its score over rotations prior_theta + (a - A) step,
    a = 0..2A, and translations prior_xy + (cx, cy) res, |cx|, |cy| <= W: the C++ search's
    lattice. As in C++, the scan is rotated and discretised once per rotation (cell = floor((q -
    origin) / res) at the prior translation) and a translation shifts the cells; a cell outside
    the table scores the field's floor value. Vectorised over rotations (in blocks), both
    translation axes and the points; the first maximum in (a, cx, cy) order, as in C++."""
    table = field.log_likelihood.astype(np.float64)
    h, w = table.shape
    flat = np.append(table.ravel(), float(field.floor_value))  # index h*w: outside the table
    inv_res = 1.0 / field.resolution
    x0, y0 = field.origin
    W, A = linear_cells, angular_steps
    theta = prior[2] + (np.arange(2 * A + 1) - A) * step
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    px, py = points[:, 0][None, :], points[:, 1][None, :]
    col = np.floor(((c * px - s * py + prior[0]) - x0) * inv_res).astype(np.int64)  # (R, N)
    row = np.floor(((s * px + c * py + prior[1]) - y0) * inv_res).astype(np.int64)
    offsets = np.arange(-W, W + 1)
    T, N = len(offsets), points.shape[0]
    scores = np.empty((len(theta), T, T))
    block = max(1, NUMPY_BLOCK // (T * T * N))
    for a0 in range(0, len(theta), block):
        cols = col[a0:a0 + block, None, :] + offsets[None, :, None]  # (r, cx, N)
        rows = row[a0:a0 + block, None, :] + offsets[None, :, None]  # (r, cy, N)
        ok = ((rows >= 0) & (rows < h))[:, None, :, :] & ((cols >= 0) & (cols < w))[:, :, None, :]
        index = np.where(ok, rows[:, None, :, :] * w + cols[:, :, None, :], h * w)  # (r, cx, cy, N)
        scores[a0:a0 + block] = flat[index].sum(axis=-1)
    best = np.unravel_index(int(np.argmax(scores)), scores.shape)
    return (int(best[0]), int(best[1]) - W, int(best[2]) - W), float(scores[best]), scores


def lattice_of(result, prior, res, A):
    """(a, cx, cy) of a MatchResult's search_pose on the lattice around prior."""
    sp = np.asarray(result.search_pose)
    dth = ps.wrap_angle(sp[2] - prior[2])
    return (int(round(dth / result.angular_step)) + A, int(round((sp[0] - prior[0]) / res)),
            int(round((sp[1] - prior[1]) / res)))


# --- the run ----------------------------------------------------------------------------------

MODES = [("branch and bound, no refinement", dict(refine=False)),
         ("branch and bound + refinement", dict(refine=True)),
         ("C++ brute force", dict(refine=False, brute_force=True))]


def run(name, problems, repeat):
    """Rows (workload, mode, matches/s, ms/match, scored/match, speed-up vs numpy, same best)."""
    matchers = {}
    for field, _, _ in problems:
        if id(field) not in matchers:
            matchers[id(field)] = _core.CorrelativeScanMatcher(field)
    # The lattice of each problem as the C++ search used it: rotations and step as reported, the
    # linear cells W from the poses its brute force scored, (2A + 1) (2W + 1)^2.
    window = dict(linear_window=LINEAR, angular_window=ANGULAR)
    lattice = []
    for field, points, prior in problems:
        r = matchers[id(field)].match(points, prior, refine=False, brute_force=True, **window)
        side = int(round(np.sqrt(r.candidates_scored / r.angular_steps)))
        assert r.angular_steps * side * side == r.candidates_scored and side % 2 == 1
        lattice.append(((side - 1) // 2, (r.angular_steps - 1) // 2, r.angular_step))

    results, times = {}, {}
    for mode, options in MODES:
        best = np.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            out = [matchers[id(f)].match(p, x0, **window, **options) for f, p, x0 in problems]
            best = min(best, time.perf_counter() - t0)
        results[mode], times[mode] = out, best
    best = np.inf
    for _ in range(max(1, repeat - 1)):
        t0 = time.perf_counter()
        numpy_out = [numpy_brute_force(f, p, x0, W, A, step) for (f, p, x0), (W, A, step) in zip(problems, lattice)]
        best = min(best, time.perf_counter() - t0)
    times["numpy"] = best

    n = len(problems)
    rows = []
    for mode, _ in MODES:
        same = ties = 0
        for (f, _, x0), (W, A, _), r, (np_best, np_score, scores) in zip(problems, lattice, results[mode], numpy_out):
            got = lattice_of(r, x0, f.resolution, A)
            inside = all(abs(v) <= W for v in got[1:]) and 0 <= got[0] <= 2 * A
            if got == np_best:
                same += 1
            elif inside and abs(scores[got[0], got[1] + W, got[2] + W] - np_score) <= 1e-9 * max(1.0, abs(np_score)):
                ties += 1  # another pose of equal score (to rounding): as good a best
            assert abs(r.search_score - np_score) <= 1e-6 * max(1.0, abs(np_score)) or got != np_best, \
                (name, mode, r.search_score, np_score)
        scored = np.mean([r.candidates_scored for r in results[mode]])
        rows.append((name, mode, n / times[mode], 1e3 * times[mode] / n, scored, times["numpy"] / times[mode],
                     f"{same}/{n}" + (f" (+{ties} tie{'s' if ties > 1 else ''})" if ties else "")))
    poses = np.mean([(2 * A + 1) * (2 * W + 1) ** 2 for W, A, _ in lattice])
    rows.append((name, "numpy brute force (vectorised)", n / times["numpy"], 1e3 * times["numpy"] / n, poses, 1.0, "-"))
    return rows, lattice


def describe(name, problems, lattice):
    W = lattice[0][0]
    A = np.array([a for _, a, _ in lattice])
    steps = np.degrees([s for _, _, s in lattice])
    pts = np.array([p.shape[0] for _, p, _ in problems])
    return (f"{name}: {len(problems)} scans of {pts.min()}-{pts.max()} points, {2 * W + 1} x {2 * W + 1} "
            f"translations, {2 * A.min() + 1}-{2 * A.max() + 1} rotations of {steps.min():.3f}-{steps.max():.3f} deg.")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="fewer scans (for a smoke run; not recorded)")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    repeat = 1 if args.quick else 3
    load = os.getloadavg()[0]  # the machine is shared: say how busy it was
    room = room_problems(4 if args.quick else 50, rng)
    rows, lattice = run("simulated room, 181 beams", room, repeat)
    notes = [describe("Simulated room", room, lattice)]
    if (ACES / "aces-corrected.log.gz").exists():
        aces, total = aces_problems(3 if args.quick else 40, rng)
        aces_rows, aces_lattice = run("ACES corrected log vs local map of 10 scans", aces, repeat)
        rows += aces_rows
        notes.append(describe(f"ACES ({total} corrected scans)", aces, aces_lattice))
    else:
        print(f"bench_scan_matching: {ACES / 'aces-corrected.log.gz'} not found; ACES workload skipped")
        notes.append("ACES workload skipped: data absent.")

    lines = heading("Correlative scan matching", "One thread; window +-0.3 m, +-0.35 rad, automatic angular "
                    "step, 0.05 m field (sigma 0.05 m), no prior term.",
                    ["workload", "implementation", "matches/s", "ms/match", "scored/match", "speed-up vs numpy",
                     "same best"])
    lines += [f"| {w} | {impl} | {rate:.1f} | {ms:.2f} | {scored:.0f} | {ratio:.1f}x | {same} |"
              for w, impl, rate, ms, scored, ratio, same in rows]
    lines += ["", *notes, f"Load average at the start: {load:.2f} (on {os.cpu_count()} cores); best of {repeat} "
              f"runs (numpy: of {max(1, repeat - 1)}).",
              "scored/match: lattice poses and pyramid nodes the search scored (numpy: the lattice poses).",
              "same best: scans whose best lattice pose (search_pose) equals the numpy brute force's; a tie is a",
              "different pose of equal score. Every mode also computes the response-surface covariance",
              "(343 interpolated scores); 'refinement' adds Gauss-Newton on the interpolated field.", ""]
    report(lines, record=args.record and not args.quick)


if __name__ == "__main__":
    main()
