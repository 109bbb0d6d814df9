"""Table 9.3 (MAP occupancy grid mapping, ch. 9.4) on a 200 x 200 map with 10 000 sonar
readings: the incremental scorer (a flip re-scores only the readings whose cone holds the cell,
through an index built once) against the literal table, which re-evaluates eq. 9.24 from
scratch (every reading's cone cast again) for each candidate flip, in the same run. The literal
version would take hours, so it is timed on a prefix of the same run's candidate flips (its
per-candidate cost is the slope between two prefix lengths, which removes its set-up) and
extrapolated to the incremental run's number of candidates. Prints a table; --record writes it
into benchmarks/RESULTS.md.

    .venv/bin/python benchmarks/bench_map_mapping.py [--quick] [--record]
"""

import argparse
import time

import numpy as np

import probslam as ps
from common import heading, report

RES, SIZE, MAX_RANGE, BETA = 0.1, 200, 5.0, np.radians(20.0)


def office_map(grid: ps.OccupancyGrid2D) -> np.ndarray:
    """A 20 m x 20 m floor: outer walls, a 3 x 3 block of rooms with 1 m doors, a few pillars."""
    occ = np.zeros((SIZE, SIZE), dtype=bool)
    occ[[0, -1], :] = True
    occ[:, [0, -1]] = True
    for k in (66, 133):
        occ[k, :] = True
        occ[:, k] = True
    for k in (66, 133):  # doors: a 10-cell gap in every wall segment between rooms
        for mid in (33, 100, 166):
            occ[k, mid - 5:mid + 5] = False
            occ[mid - 5:mid + 5, k] = False
    for r, c in ((30, 30), (100, 40), (160, 170), (50, 110), (120, 150)):
        occ[r:r + 3, c:c + 3] = True
    return occ


def free_poses(occ: np.ndarray, n: int, rng) -> np.ndarray:
    """n poses uniform over cells at least 0.3 m from any occupied cell, random headings."""
    from scipy.ndimage import binary_dilation

    blocked = binary_dilation(occ, iterations=3)
    rows, cols = np.nonzero(~blocked)
    k = rng.integers(0, len(rows), n)
    return np.column_stack([(cols[k] + rng.random(n)) * RES, (rows[k] + rng.random(n)) * RES,
                            rng.uniform(-np.pi, np.pi, n)])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="1 000 readings (for a smoke run)")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    sonars = 16
    n_poses = 63 if args.quick else 625  # x 16 sonars = 1 008 / 10 000 readings
    grid = ps.OccupancyGrid2D(RES, SIZE, SIZE, p_prior=0.3)
    truth = office_map(grid)
    model = ps.BeamSensorModel("sonar", MAX_RANGE, beta=BETA, z_hit=0.8, z_short=0.1, z_max=0.05, z_rand=0.05,
                               sigma_hit=0.05, lambda_short=0.5)
    angles = ps.wrap_angle(np.arange(sonars) * 2 * np.pi / sonars)
    poses = free_poses(truth, n_poses, rng)
    truth_map = ps.BinaryMap2D(grid, truth)
    scans = np.stack([model.sample(p, angles, truth_map, rng) for p in poses])

    t0 = time.perf_counter()
    inc = ps.map_occupancy_grid_mapping(poses, scans, angles, model, grid, record_trace=True, sensitivity=False)
    t_inc = time.perf_counter() - t0
    # The index build alone: a run that stops before scoring its first candidate.
    t0 = time.perf_counter()
    ps.map_occupancy_grid_mapping(poses, scans, angles, model, grid, max_evaluations=1, sensitivity=False)
    t_index = time.perf_counter() - t0

    # The literal Table 9.3 on two prefixes of the same run.
    short, long_ = (5, 25) if not args.quick else (20, 200)
    times, runs = [], []
    for k in (short, long_):
        t0 = time.perf_counter()
        runs.append(ps.map_occupancy_grid_mapping(poses, scans, angles, model, grid, scoring="full",
                                                  max_evaluations=k, record_trace=True, sensitivity=False))
        times.append(time.perf_counter() - t0)
    per_candidate = (times[1] - times[0]) / (long_ - short)
    full_estimate = per_candidate * inc.evaluations
    # Same decisions on the prefix the literal version ran.
    n_flips = len(runs[1].trace_cells)
    same = np.array_equal(runs[1].trace_cells, inc.trace_cells[:n_flips])

    wrong = int(np.sum((inc.occupied != truth) & inc.field))
    lines = heading("MAP occupancy grid mapping (Table 9.3)",
                    f"One thread. {SIZE} x {SIZE} cells of {RES} m, {inc.readings} sonar readings "
                    f"({n_poses} poses x {sonars} sonars, {np.degrees(BETA):.0f} deg cones, {MAX_RANGE} m), "
                    "noisy readings sampled from the forward model.",
                    ["scorer", "candidates scored", "seconds", "ms per candidate", "speed-up"])
    lines += [
        f"| incremental (index + climb) | {inc.evaluations} | {t_inc:.2f} | "
        f"{1e3 * (t_inc - t_index) / inc.evaluations:.4f} | 1x |",
        f"| full re-evaluation per candidate (estimated) | {inc.evaluations} | {full_estimate:.0f} | "
        f"{1e3 * per_candidate:.1f} | {full_estimate / t_inc:.0f}x |",
        "",
        f"Incremental run: index {t_index:.2f} s ({inc.index_entries} (reading, cell) pairs over "
        f"{inc.field_cells} cells), climb {t_inc - t_index:.2f} s, {inc.sweeps} sweeps, {inc.flips} flips, "
        f"converged: {inc.converged}; {wrong} observed cells differ from the true map.",
        f"Full re-evaluation: timed on the first {short} and {long_} candidates of the same run "
        f"({times[0]:.2f} s and {times[1]:.2f} s; the slope is its cost per candidate) and extrapolated to "
        f"{inc.evaluations} candidates; its first {n_flips} flips are the incremental run's: {same}.",
        "",
    ]
    report(lines, record=args.record and not args.quick)


if __name__ == "__main__":
    main()
