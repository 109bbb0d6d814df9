"""Ch. 9.3.4: an inverse model trained from real data, against one trained on the forward model's
samples and Table 9.2, on held-out real scans.

The Intel Research Lab corrected log (910 scans, GMapping-corrected poses, 180 beams of 1 deg)
is split in time: part A (the first half) gives the known map (probslam.inverse_learning.
known_map: the ray model, decided cells only) and the training set (real_training_set: each
scan's field cells that the known map decides, 300 per scan at random, labelled by it) and the
evidence scale (fit_evidence_scale on part A's scans against the same map); part B (the second
half) is mapped by each model with Table 9.1 and scored against part A's known map over the
cells that B's fields cover and A decides. The simulated model is trained on the rooms prior
(random_map, 20 m x 20 m) with a laser forward model of the same fan, its scale fitted on other
simulated rooms, and (a second row) on part A's real scans; a few fixed scales for comparison. All maps start from the same prior (part A's occupied fraction).

    .venv/bin/python studies/eval_inverse_real.py [--quick]
"""

import argparse
import os
import pathlib
import time

import numpy as np

import probslam as ps
from probslam import inverse_learning as il
from probslam import io

RES = 0.1
# ../shared/data beside the repository, or $PROBSLAM_SHARED_DATA (as the other benchmarks).
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"))
INTEL = SHARED / "laser_2d" / "intel" / "intel-corrected.log.gz"
MAX_RANGE = 10.0  # the readings used (m): beyond, the SICK's 1 deg beams spread over 17 cm
CELLS_PER_SCAN = 300


def intel_scans():
    return io.read_carmen_log(str(INTEL)).scans if INTEL.exists() else None


def intel_floor_plan(resolution):
    """The Intel Research Lab floor plan as a world (studies/eval_inverse_models.py): the
    corrected log mapped with the ray model (il.known_map); occupied where the map says so and
    where it decides nothing (outside the building, unseen corners), so that sampled poses stay
    in explored free space; and the cells the map decides, the only ones scored (the filled
    unknown is no floor plan). None when the shared data are absent."""
    scans = intel_scans()
    if scans is None:
        return None
    grid, occupied, known = il.known_map(scans, resolution, MAX_RANGE)
    return grid, occupied | ~known, known


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--save-model", metavar="PATH",
                        help="save the real-data model (its scale fitted on part A) to PATH and stop; the bundled "
                             "python/probslam/data/intel_laser_inverse.npz is made so")
    args = parser.parse_args()
    scans = intel_scans()
    if scans is None:
        print("no /work/shared/data: nothing to do")
        return
    n = len(scans)
    half = n // 2
    angles = scans.beam_angles()[0]
    no_return = ps.mapping.no_return_range(scans)
    ranges = np.where(scans.ranges >= no_return, np.inf, scans.ranges)
    poses = scans.laser_poses
    a, b = slice(0, half), slice(half, n)
    from dataclasses import replace
    part_a = replace(scans, **{k: getattr(scans, k)[a] for k in ("ranges", "laser_poses", "robot_poses", "start_angles",
                                                                    "angular_resolutions", "max_ranges", "num_beams",
                                                                    "timestamps")})
    grid, occ, known = il.known_map(part_a, RES, MAX_RANGE)
    hw = abs(float(scans.angular_resolutions[0])) / 2
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    data = il.real_training_set(grid, occ, known, poses[a], ranges[a], angles, MAX_RANGE, hw)
    pick = rng.choice(data.occupied.size, min(data.occupied.size, CELLS_PER_SCAN * half), replace=False)
    data = il.TrainingSet(data.inputs[pick], data.occupied[pick])
    real = il.LearnedInverseModel(16).train(data, rng, max_iterations=100 if args.quick else 300)
    real_scale = real.fit_evidence_scale([(occ, poses[a], ranges[a], known)], grid, angles, MAX_RANGE, hw)
    t1 = time.perf_counter()
    if args.save_model:
        real.resolution, real.max_range = RES, MAX_RANGE  # the lattice and range it learned on: map's defaults
        real.save(args.save_model)
        print(f"saved {args.save_model}: trained on the first {half} scans ({t1 - t0:.0f} s), evidence scale "
              f"{real_scale:.3f}")
        return
    print(f"known map (part A, {half} scans): {grid.shape}, {known.sum()} decided cells, "
          f"{100 * occ[known].mean():.1f}% occupied; real training set {data.occupied.size} cells, J = "
          f"{real.final_objective:.4f}, scale {real_scale:.3f} ({t1 - t0:.0f} s)")

    laser = ps.BeamSensorModel("laser", MAX_RANGE, z_hit=0.85, z_short=0.05, z_max=0.05, z_rand=0.05, sigma_hit=0.05,
                               lambda_short=0.5)
    sim_grid = ps.OccupancyGrid2D(RES, 200, 200)
    maps, per = (3, 10) if args.quick else (10, 30)
    sim_data = il.sample_training_set(sim_grid, laser, angles, maps, per, rng, cells_per_scan=CELLS_PER_SCAN,
                                      half_angle=hw)
    sim = il.LearnedInverseModel(16).train(sim_data, rng, max_iterations=100 if args.quick else 300)
    sim_scale = sim.fit_evidence_scale(il.sample_scans(sim_grid, laser, angles, 2, per, rng), sim_grid, angles,
                                       MAX_RANGE, hw)
    # the same forward-model-trained network with only its one scale fitted on part A's real scans
    sim_scale_a = sim.fit_evidence_scale([(occ, poses[a], ranges[a], known)], grid, angles, MAX_RANGE, hw)
    t2 = time.perf_counter()
    print(f"simulated: {sim_data.occupied.size} cells, J = {sim.final_objective:.4f}, scale {sim_scale:.3f} on "
          f"simulated rooms, {sim_scale_a:.3f} on part A ({t2 - t1:.0f} s)\n")

    l0 = float(ps.logit(real.prior))
    ev = float(ps.logit(0.7))
    size = grid.shape[0] * grid.shape[1]
    seen = np.zeros(size, bool)
    totals = {"real": np.zeros(size), "sim": np.zeros(size)}
    hand = ps.OccupancyGrid2D(RES, grid.shape[1], grid.shape[0], origin=grid.origin, p_prior=real.prior, clamp=None)
    seconds = {"Table 9.2 (insert_cone_scan)": 0.0, "learned (insert_scan's work: field + network)": 0.0}
    for pose, z in zip(poses[b], ranges[b]):
        s0 = time.perf_counter()
        hand.insert_cone_scan(pose, z, angles, MAX_RANGE, RES, 2 * hw, l0 + ev, l0 - ev)
        s1 = time.perf_counter()
        cells, e = real.scan_evidence(grid, pose, z, angles, MAX_RANGE, hw)
        s2 = time.perf_counter()
        seconds["Table 9.2 (insert_cone_scan)"] += s1 - s0
        seconds["learned (insert_scan's work: field + network)"] += s2 - s1
        totals["real"][cells] += e
        sim_cells, sim_e = sim.scan_evidence(grid, pose, z, angles, MAX_RANGE, hw)
        totals["sim"][sim_cells] += sim_e
        seen[cells] = True
    mask = seen & known.ravel()
    y = occ.ravel()[mask]
    rows = [("prior only", np.full(y.size, l0)), ("Table 9.2 (hand-made)", hand.log_odds.ravel()[mask])]
    for name, key, fitted in (("forward-model-trained", "sim", {sim_scale: "fitted on simulated rooms",
                                                                 sim_scale_a: "fitted on part A"}),
                              ("real-data-trained", "real", {real_scale: "fitted on part A"})):
        for k in (1.0, 0.03, 0.1, 0.3, *fitted):
            rows.append((f"{name} x {k:.3g}" + (f" ({fitted[k]})" if k in fitted else ""), l0 + k * totals[key][mask]))
    print(f"part B ({n - half} held-out scans), {y.size} scored cells ({100 * y.mean():.1f}% occupied in A's map):\n")
    print("| inverse model | cross-entropy (nats/cell) | accuracy |\n|---|---|---|")
    for name, l in rows:
        print(f"| {name} | {il.map_cross_entropy(l, y):.3f} | {np.mean((l > 0) == y):.3f} |")
    print("\nmapping time over part B:")
    for k, v in seconds.items():
        print(f"- {k}: {v:.2f} s, {1e3 * v / (n - half):.1f} ms per scan")
    np.savez("/tmp/intel_inverse_maps.npz", occ=occ, known=known, hand=hand.log_odds, real=totals["real"],
             sim=totals["sim"], l0=l0, real_scale=real_scale, sim_scale=sim_scale, shape=grid.shape)


if __name__ == "__main__":
    main()
