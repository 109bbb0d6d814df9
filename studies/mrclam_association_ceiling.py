"""How well can MRCLAM Dataset 7's sightings be told apart at all, with barcodes hidden?

Upper bounds that no filter can beat, for each robot with Vicon: each sighting is placed from the
Vicon pose and matched to the nearest surveyed landmark, (1) alone, (2) with one bearing offset
per scan fitted jointly with the scan's assignment (the bearing errors of one scan share an
offset: 0.025 rad common against 0.004 rad within the scan on robot 1, measured here), (3) lone
sightings borrowing the offset fitted in neighbouring scans (the offset drifts slowly: lag-1
correlation 0.84). Printed for the raw readings (the camera's depth), for distances
(``Mrclam.with_euclidean_ranges``, whose scale was fitted on robot 1) and, as an oracle, for
distances with each robot's constant range and bearing error against Vicon taken off (what a
camera calibrated per robot would add). Then, for every robot of the folder, what a filter has
instead of the truth: EKF SLAM with the barcodes as correspondences (the CLI's noise), and,
before each scan, the most likely landmark of its own map for each sighting (NIS + log det S
over all its landmarks). With --vicon-motion, also the multiple-hypothesis EKF (the CLI's
costs, with and without the scan's bearing offset) driven by controls taken from the Vicon
track instead of the odometry: what association gains from a nearly true motion. (What a batch
smoother reached, the former --smoothed, is recorded in studies/README.md.)

    .venv/bin/python studies/mrclam_association_ceiling.py [DATASET_FOLDER] [--vicon-motion]
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import pathlib

import numpy as np

import probslam as ps
from probslam import eval as ev
from probslam.datasets import mrclam

# The CLI's MRCLAM noise, and the multiple-hypothesis EKF with the bearing offset as
# benchmarks/sweeps/mrclam_association_offset.toml runs it: 0.03 rad of the bearing noise moved into
# an offset drawn afresh per scan, the sensor 0.15 m / 0.02 rad.
MOTION, SENSOR = mrclam.MOTION_NOISE, mrclam.MEASUREMENT_NOISE
MHT_OFFSET_SENSOR = np.diag([0.15 ** 2, 0.02 ** 2])
MHT_OFFSET_OPTIONS = dict(bearing_offset_sigma=0.03, bearing_offset_correlation=0.0)

DEFAULT = pathlib.Path(__file__).resolve().parents[2] / "shared/data/landmark_slam/mrclam_dataset7"
#: Offsets tried per scan (rad): the common bearing error stays within +-0.1 rad.
OFFSETS = np.linspace(-0.1, 0.1, 81)
#: Candidates per sighting when fitting a scan: its three nearest landmarks.
CANDIDATES = 3
#: Window (s) within which a lone sighting borrows the offsets fitted in other scans.
WINDOW = 1.0


def vicon_poses(data, times):
    return ps.eval.interpolate_poses(data.groundtruth[:, 0], data.groundtruth[:, 1:4], times)


def placed(readings, poses, offsets):
    """Sightings (n, 2): readings (n, 4) (time, id, range, bearing) placed from poses (n, 3), or
    one (3,), with their bearings turned by offsets (rad; (n,) or one)."""
    a = poses[..., 2] + readings[:, 3] + offsets
    return poses[..., :2] + readings[:, 2:3] * np.column_stack([np.cos(a), np.sin(a)])


def scan_points(m, idx):
    """points_at(pose, offset) -> (n, 2): the sightings m[idx] placed from `pose` with their
    bearings turned by `offset` (rad), as fit_scan takes them."""
    return lambda pose, off: placed(m[idx], pose, off)


def residual_spread(data):
    """Bearing and range errors from the Vicon pose, split into per-scan mean and the rest."""
    rng_error, bearing_error = sighting_errors(data)
    common, within = {"bearing": [], "range": []}, {"bearing": [], "range": []}
    for rows in mrclam.scans(data.measurements):
        if rows.stop - rows.start < 2:
            continue
        for name, e in (("bearing", bearing_error[rows]), ("range", rng_error[rows])):
            common[name].append(e.mean())
            within[name].extend(e - e.mean())
    return {k: (float(np.std(common[k])), float(np.std(within[k]))) for k in common}


def fit_scan(points_at, pose, n, landmarks, range_sd, offset_sd):
    """Best (cost, offset, assignment) of one scan: distinct landmarks, offset prior N(0, sd^2)."""
    best = (np.inf, 0.0, None)
    for off in OFFSETS:
        q = points_at(pose, off)
        dist = np.linalg.norm(q[:, None] - landmarks[None], axis=2)
        nearest = [np.argsort(dist[k])[:CANDIDATES] for k in range(n)]
        for combo in itertools.product(*nearest):
            if len(set(combo)) == n:
                cost = np.sum(dist[np.arange(n), combo] ** 2) / range_sd ** 2 + off ** 2 / offset_sd ** 2
                if cost < best[0]:
                    best = (cost, off, np.array(combo))
    return best




def main(folder, vicon_motion=False) -> None:
    print("robot | readings | each alone | scans of 2+, offset fitted | lone, offset borrowed | "
          "all (lone alone) | all (lone borrowing)")
    for robot in range(1, 6):
        try:
            raw = ps.io.read_mrclam(folder, robot=robot)
        except (ValueError, OSError):
            continue
        if raw.groundtruth is None:
            continue
        distances = raw.with_euclidean_ranges()
        bias = camera_bias(distances)
        spread = residual_spread(distances)
        print(f"robot {robot}: camera errors against Vicon, distances: bearing std per scan (common) "
              f"{spread['bearing'][0]:.4f} rad, within a scan {spread['bearing'][1]:.4f} rad; range "
              f"{spread['range'][0]:.3f} m / {spread['range'][1]:.3f} m; constant (median): "
              + ", ".join(f"{name} range {b[0]:+.3f} m, bearing {b[1]:+.4f} rad" for name, b in
                          (("depth", camera_bias(raw)), ("distances", bias))))
        for name, data in (("depth", raw), ("distances", distances),
                           ("distances, biases removed", without_camera_bias(distances, bias))):
            counts = ceiling(data)
            print(f"robot {robot} | {name} | " + " | ".join(f"{counts[k][0] / counts[k][1]:.3f}" for k in counts))
    print("--- the filter's own map and pose (barcodes known), distances: most likely landmark per sighting")
    for robot in range(1, 6):
        try:
            data = ps.io.read_mrclam(folder, robot=robot).with_euclidean_ranges()
        except (ValueError, OSError):
            continue
        good, total, lone = own_map(data)
        print(f"robot {robot}: {good} / {total} = {good / total:.3f} (sightings alone in their scan: {lone:.3f})")
        if vicon_motion and data.groundtruth is not None:
            for name, sensor, options in (("multiple hypotheses", SENSOR, {}),
                                          ("with the bearing offset", MHT_OFFSET_SENSOR, MHT_OFFSET_OPTIONS)):
                run = mrclam.run_ekf(with_vicon_motion(data), VICON_MOTION_NOISE, sensor, known=False,
                                        association="mht", hypotheses=options)
                print(f"  Vicon motion, {name}: {ev.association_accuracy(run):.3f} correct, "
                      f"{len(run.landmarks)} landmarks")


def sighting_errors(data):
    """Range (m) and bearing (rad) errors (M,) of every sighting against the Vicon pose and the survey."""
    m = data.measurements
    poses = vicon_poses(data, m[:, 0])
    delta = np.array([data.landmark_positions[int(s)] for s in m[:, 1]]) - poses[:, :2]
    bearing = ps.wrap_angle(m[:, 3] - (np.arctan2(delta[:, 1], delta[:, 0]) - poses[:, 2]))
    return m[:, 2] - np.hypot(delta[:, 0], delta[:, 1]), bearing


def camera_bias(data):
    """The camera's constant range (m) and bearing (rad) error: medians against Vicon."""
    rng, bearing = sighting_errors(data)
    return float(np.median(rng)), float(np.median(bearing))


def without_camera_bias(data, bias):
    """`data` with its camera_bias (range m, bearing rad) taken off every reading: an oracle (it
    needs Vicon), showing how much of the ceiling a calibrated camera would add against the survey."""
    m = data.measurements.copy()
    m[:, 2:4] -= bias
    return dataclasses.replace(data, measurements=m)


#: --vicon-motion: control noise (per 10 ms command) of controls taken from the Vicon track.
VICON_MOTION_NOISE = np.diag([0.02 ** 2, 0.04 ** 2])


def with_vicon_motion(data):
    """The robot with its controls (v, w) replaced by the Vicon track's between the same stamps."""
    g, t = data.groundtruth, data.odometry[:, 0]
    x, y, h = (np.interp(t, g[:, 0], c) for c in (g[:, 1], g[:, 2], np.unwrap(g[:, 3])))
    dt = np.maximum(np.diff(t), 1e-3)
    mid = h[:-1] + np.diff(h) / 2
    odometry = data.odometry.copy()
    odometry[:-1, 1] = (np.diff(x) * np.cos(mid) + np.diff(y) * np.sin(mid)) / dt
    odometry[:-1, 2] = np.diff(h) / dt
    odometry[-1, 1:] = 0.0
    return dataclasses.replace(data, odometry=odometry)


def own_map(data):
    """(right, judged, share right among lone sightings): sightings of a mapped landmark whose most
    likely landmark in the known-correspondence filter's map, just before the scan, is their own."""
    counts = {"all": [0, 0], "lone": [0, 0]}

    def judge(ekf, rows):
        mapped = list(ekf.landmarks().ids)
        if len(mapped) < 2:
            return
        for z, truth in zip(rows[:, 2:4], rows[:, 1].astype(int)):
            if truth not in mapped:
                continue
            best = min(mapped, key=lambda j: sum(ekf.pairing_likelihood(z, j)))
            for key in ("all",) + (("lone",) if len(rows) == 1 else ()):
                counts[key][0] += int(best == truth)
                counts[key][1] += 1

    mrclam.run_ekf(data, MOTION, SENSOR, known=True, before_scan=judge)
    return counts["all"][0], counts["all"][1], counts["lone"][0] / max(1, counts["lone"][1])


def ceiling(data):
    """Sightings placed from the Vicon pose on the survey: {case: [correct, total]} for every
    sighting alone, scans of two or more with their offset fitted, the lone sightings borrowing
    nearby scans' offsets, and all sightings (lone ones alone / borrowing)."""
    m = data.measurements
    subjects = np.array(sorted(data.landmark_positions))
    landmarks = np.array([data.landmark_positions[s] for s in subjects])
    poses = vicon_poses(data, m[:, 0])
    spread = residual_spread(data)
    counts = {k: [0, 0] for k in ("alone", "lone", "multi, offset fitted", "lone, offset borrowed")}
    fitted = []  # (time, offset) of multi-sighting scans
    for rows in mrclam.scans(m):
        idx = np.arange(rows.start, rows.stop)

        points_at = scan_points(m, idx)
        pose, truth = poses[rows.start], m[idx, 1]
        nearest = subjects[np.argmin(np.linalg.norm(points_at(pose, 0.0)[:, None] - landmarks[None], axis=2), 1)]
        counts["alone"][0] += int(np.sum(nearest == truth))
        counts["alone"][1] += len(idx)
        if len(idx) == 1:
            counts["lone"][0] += int(nearest[0] == truth[0])
            counts["lone"][1] += 1
            continue
        _, off, combo = fit_scan(points_at, pose, len(idx), landmarks, spread["range"][1], spread["bearing"][0])
        fitted.append((m[rows.start, 0], off))
        counts["multi, offset fitted"][0] += int(np.sum(subjects[combo] == truth))
        counts["multi, offset fitted"][1] += len(idx)
    fitted = np.array(fitted)
    for rows in mrclam.scans(m):
        if rows.stop - rows.start != 1:
            continue
        t, (_, _, r, phi) = m[rows.start, 0], m[rows.start]
        near = np.abs(fitted[:, 0] - t) <= WINDOW
        pose = poses[rows.start]
        a = pose[2] + phi + (np.median(fitted[near, 1]) if near.any() else 0.0)
        point = pose[:2] + r * np.array([np.cos(a), np.sin(a)])
        counts["lone, offset borrowed"][0] += int(subjects[np.argmin(np.linalg.norm(landmarks - point, axis=1))] ==
                                                  m[rows.start, 1])
        counts["lone, offset borrowed"][1] += 1
    multi = counts["multi, offset fitted"]
    return {"alone": counts["alone"], "multi": multi, "lone, offset borrowed": counts["lone, offset borrowed"],
            "all, lone alone": [multi[0] + counts["lone"][0], multi[1] + counts["lone"][1]],
            "all, lone borrowing": [multi[0] + counts["lone, offset borrowed"][0], multi[1] + counts["lone"][1]]}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", nargs="?", default=DEFAULT)
    parser.add_argument("--vicon-motion", action="store_true")
    args = parser.parse_args()
    main(args.folder, args.vicon_motion)
