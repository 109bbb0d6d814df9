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
track instead of the odometry: what association gains from a nearly true motion. With
--smoothed, what a batch method (smoothing the whole run, then placing each scan again) can
reach: the run smoothed with the barcodes as labels, then every scan's sightings placed on the
smoothed map from the smoothed pose with the offset fitted as above; the same with the lone
sightings withheld from the smoothing (placed, never smoothed: whether the right labels of lone
sightings are found from the rest of the run or only held by their own pull on the path); and
the alternation started from the multiple-hypothesis EKF's labels (with the bearing offset),
smoothing and re-placing until the labels settle.

    .venv/bin/python studies/mrclam_association_ceiling.py [DATASET_FOLDER] [--vicon-motion] [--smoothed]
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import pathlib
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import probslam as ps
from probslam import landmark_slam as ls
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))  # common.py and the benchmarks reused here
# The CLI's MRCLAM noise, and the bench's multiple-hypothesis settings with the bearing offset.
from bench_mrclam_association import MHT_OFFSET_OPTIONS, MHT_OFFSET_SENSOR, MOTION, SENSOR

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
    for rows in ls.scans(data.measurements):
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




def main(folder, vicon_motion=False, smoothed=False) -> None:
    if smoothed:
        smoothed_ceiling(folder)
        return
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
                run = ls.run_ekf_mrclam(with_vicon_motion(data), VICON_MOTION_NOISE, sensor, known=False,
                                        association="mht", hypotheses=options)
                print(f"  Vicon motion, {name}: {ls.association_accuracy(run):.3f} correct, "
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

    ls.run_ekf_mrclam(data, MOTION, SENSOR, known=True, before_scan=judge)
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
    for rows in ls.scans(m):
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
    for rows in ls.scans(m):
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


# ---- --smoothed: batch smoothing and re-association -------------------------------------------

#: Per-second variances of the velocity noise (m^2/s, rad^2/s): the CLI's MOTION per 10 ms
#: command, as run_ekf_mrclam applies it.
VELOCITY_NOISE_RATE = np.diag(MOTION) * 0.01
#: Cauchy scale (whitened units) of a sighting's residual in the smoother: a sighting given the
#: wrong label must not bend the path.
SIGHTING_ROBUST_SCALE = 2.0
#: Spreads of the re-association (fit_scan): position of a sighting within its scan (m; the
#: within-scan range spread measured above is 0.019 m) and the scan's bearing offset (rad; the
#: bench's offset sigma). Fixed, not measured from Vicon, as a method would have to.
PLACE_SD, OFFSET_SD = 0.02, 0.03
#: The smoother's sighting noise (m, rad): the camera's within-scan spread (range 0.02-0.035 m,
#: bearing 0.004-0.005 rad on robots 1-4 against Vicon, printed above), the scan's common bearing
#: error being the offset b.
SMOOTHER_SENSOR_SD = (0.03, 0.005)
#: Rounds of smoothing and re-association (on Dataset 7 under 0.5% of the labels still change in
#: the 6th; Dataset 1's robots 1-4 settle within 4).
ROUNDS = 6
#: Levenberg-Marquardt iterations of one smoothing, and the relative change of the cost that ends it.
SMOOTH_ITERATIONS, SMOOTH_TOLERANCE = 60, 1e-9
#: Weight (1/m, 1/rad) holding the first pose at the start: the gauge, far stiffer than any factor.
ANCHOR_WEIGHT = 1e3
#: Shortest gap between scans (s) and variance floors (m^2, rad^2) of the odometry factor: scans
#: stamped together, and a standstill, must still give an invertible covariance.
MIN_GAP, MIN_POSITION_VAR, MIN_HEADING_VAR = 1e-3, 1e-8, 1e-10


class Smoother:
    """The run as a least-squares problem over the scan states (x, y, theta, b: the pose and the
    scan's bearing offset) and the labelled landmarks: odometry between consecutive scans (dead
    reckoning's relative pose, covariance of a white velocity noise over the gap: along track
    qv T, heading qw T, across d^2 qw T / 3 and its covariance with the heading d qw T / 2),
    every labelled sighting (noise sd `sensor_sd` (m, rad), Cauchy-weighted, its bearing turned
    by b) and b's prior N(0, offset_sd^2); the first pose held at the start."""

    def __init__(self, data, times, scan_of, start, sensor_sd, offset_sd):
        odo = data.odometry
        dead = ps.eval.interpolate_poses(odo[:, 0], ls.dead_reckoning(odo, start), times)
        self.start, self.scan_of, self.z = dead[0], scan_of, data.measurements[:, 2:4]
        self.odometry = ps.eval.relative_poses(dead[:-1], dead[1:])
        gap, d = np.maximum(np.diff(times), MIN_GAP), np.abs(self.odometry[:, 0])
        qv, qw = VELOCITY_NOISE_RATE
        cov = np.zeros((len(gap), 3, 3))
        cov[:, 0, 0] = qv * gap + MIN_POSITION_VAR
        cov[:, 1, 1] = qw * gap * d ** 2 / 3 + MIN_POSITION_VAR
        cov[:, 1, 2] = cov[:, 2, 1] = qw * gap * d / 2
        cov[:, 2, 2] = qw * gap + MIN_HEADING_VAR
        self.whiten = np.transpose(np.linalg.cholesky(np.linalg.inv(cov)), (0, 2, 1))
        self.sd, self.offset_sd = np.asarray(sensor_sd, float), float(offset_sd)

    def _system(self, states, landmarks, labelled, labels):
        S, L = len(states), len(landmarks)
        a, b = states[:-1, :3], states[1:, :3]
        d = b[:, :2] - a[:, :2]
        c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
        r_odo = ps.eval.relative_poses(a, b) - self.odometry
        r_odo[:, 2] = ps.wrap_angle(r_odo[:, 2])
        j_odo = np.zeros((S - 1, 3, 8))  # d r / d (state a, state b)
        j_odo[:, 0, :3] = np.column_stack([-c, -s, -s * d[:, 0] + c * d[:, 1]])
        j_odo[:, 1, :3] = np.column_stack([s, -c, -c * d[:, 0] - s * d[:, 1]])
        j_odo[:, 2, 2] = -1.0
        j_odo[:, 0, 4:6] = np.column_stack([c, s])
        j_odo[:, 1, 4:6] = np.column_stack([-s, c])
        j_odo[:, 2, 6] = 1.0
        j_odo = self.whiten @ j_odo
        cols_odo = 4 * np.arange(S - 1)[:, None] + np.arange(8)
        p, m = states[self.scan_of[labelled]], landmarks[labels]
        q = m - p[:, :2]
        r2 = np.sum(q * q, axis=1)
        r = np.sqrt(r2)
        bearing = np.arctan2(q[:, 1], q[:, 0]) - p[:, 2] - p[:, 3]
        res = np.column_stack([r - self.z[labelled, 0], ps.wrap_angle(bearing - self.z[labelled, 1])]) / self.sd
        weight = 1.0 / np.sqrt(1.0 + np.sum(res * res, axis=1) / SIGHTING_ROBUST_SCALE ** 2)
        dr, db = q / r[:, None], np.column_stack([-q[:, 1], q[:, 0]]) / r2[:, None]
        j_see = np.zeros((len(labels), 2, 6))  # d r / d (state, landmark)
        j_see[:, 0, :2], j_see[:, 0, 4:] = -dr, dr
        j_see[:, 1, :2], j_see[:, 1, 2:4], j_see[:, 1, 4:] = -db, -1.0, db
        j_see *= (weight[:, None] / self.sd)[:, :, None]
        k = self.scan_of[labelled]
        cols_see = np.column_stack([4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3, 4 * S + 2 * labels, 4 * S + 2 * labels + 1])
        residual = np.concatenate([ANCHOR_WEIGHT * (states[0, :3] - self.start), states[:, 3] / self.offset_sd,
                                   np.einsum("kij,kj->ki", self.whiten, r_odo).ravel(), (res * weight[:, None]).ravel()])
        rows = np.concatenate([np.arange(3 + S), 3 + S + np.repeat(np.arange(3 * (S - 1)), 8),
                               3 + S + 3 * (S - 1) + np.repeat(np.arange(2 * len(labels)), 6)])
        cols = np.concatenate([np.arange(3), 4 * np.arange(S) + 3, np.repeat(cols_odo, 3, axis=0).ravel(),
                               np.repeat(cols_see, 2, axis=0).ravel()])
        values = np.concatenate([np.full(3, ANCHOR_WEIGHT), np.full(S, 1.0 / self.offset_sd), j_odo.ravel(), j_see.ravel()])
        jacobian = sp.csc_matrix((values, (rows, cols)), shape=(len(residual), 4 * S + 2 * L))
        return residual, jacobian

    def solve(self, states, landmarks, labels):
        """Levenberg-Marquardt from (states (S, 4), landmarks (L, 2)); labels (M,), -1 unused.
        Returns the states and landmarks."""
        labelled = np.flatnonzero(labels >= 0)
        of_labelled = labels[labelled]
        S = len(states)
        x = np.concatenate([states.ravel(), landmarks.ravel()])
        unpack = lambda v: (v[:4 * S].reshape(S, 4), v[4 * S:].reshape(-1, 2))  # noqa: E731
        r, j = self._system(*unpack(x), labelled, of_labelled)
        cost, damping = r @ r, 1e-6
        for _ in range(SMOOTH_ITERATIONS):
            h = (j.T @ j).tocsc()
            step = spla.spsolve(h + damping * sp.diags(h.diagonal()), -(j.T @ r))
            r_new, j_new = self._system(*unpack(x + step), labelled, of_labelled)
            if r_new @ r_new < cost:
                done = cost - r_new @ r_new < SMOOTH_TOLERANCE * cost
                x, r, j, cost, damping = x + step, r_new, j_new, r_new @ r_new, max(damping / 10, 1e-12)
                if done:
                    break
            else:
                damping *= 10
        return unpack(x)


def place_scans(m, scan_rows, poses, landmarks):
    """Labels (M,): each scan's sightings on `landmarks` from its pose, the offset fitted with
    the assignment (fit_scan; a lone sighting: the nearest landmark)."""
    labels = np.empty(len(m), np.int64)
    for s, rows in enumerate(scan_rows):
        idx = np.arange(rows.start, rows.stop)
        points_at = scan_points(m, idx)
        off, combo = 0.0, None
        if len(idx) > 1:
            _, off, combo = fit_scan(points_at, poses[s], len(idx), landmarks, PLACE_SD, OFFSET_SD)
        if combo is None:  # lone, or more sightings than distinct candidates
            combo = np.argmin(np.linalg.norm(points_at(poses[s], off)[:, None] - landmarks[None], axis=2), axis=1)
        labels[idx] = combo
    return labels


def majority_right(labels, truth):
    """(M,) bool: the sightings whose label's most frequent true landmark is their own."""
    right = np.zeros(len(labels), bool)
    for label in np.unique(labels):
        mine = labels == label
        right[mine] = truth[mine] == np.bincount(truth[mine]).argmax()
    return right


def majority_correct(labels, truth):
    """Share of the sightings whose label's most frequent true landmark is their own."""
    return float(np.mean(majority_right(labels, truth)))


def alternate(smoother, m, scan_rows, scan_of, poses, labels, withheld=None):
    """From poses (S, 3) and labels (M,; -1 unused): smooth, re-place every scan, until the
    labels settle or ROUNDS. Sightings `withheld` (M, bool) are placed but never smoothed: their
    labels cannot hold the path to themselves. Returns the labels and the rounds taken."""
    kept = np.ones(len(labels), bool) if withheld is None else ~np.asarray(withheld, bool)
    states = np.column_stack([poses, np.zeros(len(poses))])
    for rounds in range(1, ROUNDS + 1):
        used = np.unique(labels[(labels >= 0) & kept])
        labels = np.where(np.isin(labels, used), np.searchsorted(used, labels), -1)
        given = np.where(kept, labels, -1)
        points = sighted_points(m, scan_of, states)
        landmarks = np.array([points[given == k].mean(0) for k in range(len(used))])
        states, landmarks = smoother.solve(states, landmarks, given)
        new = place_scans(m, scan_rows, states[:, :3], landmarks)
        settled = np.array_equal(new, labels)
        labels = new
        if settled:
            break
    return labels, rounds


def sighted_points(m, scan_of, states):
    """The sightings (M, 2) placed from their scan's state (x, y, theta, b)."""
    return placed(m, states[scan_of, :3], states[scan_of, 3])


def described(labels, truth, lone):
    """'correct / landmarks (lone: correct among the lone sightings)'."""
    right = majority_right(labels, truth)
    return f"{right.mean():.3f} / {len(np.unique(labels))} (lone {right[lone].mean():.3f})"


def smoothed_ceiling(folder) -> None:
    print("robot | barcodes as labels: smoothed, re-placed | the same, lone sightings withheld from the smoothing | "
          "from the multiple-hypothesis EKF (offset): its own, alternated (correct / landmarks)")
    for robot in range(1, 6):
        try:
            data = ps.io.read_mrclam(folder, robot=robot).with_euclidean_ranges()
        except (ValueError, OSError):
            continue
        scan_rows = ls.scans(data.measurements)
        # run_ekf_mrclam skips the scans outside the odometry's time span
        inside = [r for r in scan_rows if data.odometry[0, 0] <= data.measurements[r.start, 0] < data.odometry[-1, 0]]
        data = dataclasses.replace(data, measurements=data.measurements[inside[0].start:inside[-1].stop])
        m = data.measurements
        scan_rows = ls.scans(m)
        times = np.array([m[r.start, 0] for r in scan_rows])
        scan_of = np.repeat(np.arange(len(scan_rows)), [r.stop - r.start for r in scan_rows])
        subjects = np.array(sorted(data.landmark_positions))
        truth = np.searchsorted(subjects, m[:, 1].astype(int))
        known = ls.run_ekf_mrclam(data, MOTION, SENSOR, known=True)
        smoother = Smoother(data, times, scan_of, known.poses[0], SMOOTHER_SENSOR_SD, OFFSET_SD)
        cells = []
        lone = np.bincount(scan_of)[scan_of] == 1
        known_poses = ps.eval.interpolate_poses(known.times, known.poses, times)
        for withheld in (None, lone):
            labels, _ = alternate(smoother, m, scan_rows, scan_of, known_poses, truth, withheld)
            cells.append(described(labels, truth, lone))
        mht = ls.run_ekf_mrclam(data, MOTION, MHT_OFFSET_SENSOR, known=False, association="mht",
                                hypotheses=MHT_OFFSET_OPTIONS)
        own = np.concatenate([np.where(np.isin(r.outcome, (ls.AssociationResult.ASSOCIATED, ls.AssociationResult.NEW_LANDMARK)),
                                       r.ids, -1) for _, r in mht.associations])
        own = np.where(np.isin(own, list(mht.landmarks)), own, -1)
        cells.append(f"{ls.association_accuracy(mht):.3f} / {len(mht.landmarks)}")
        mht_poses = ps.eval.interpolate_poses(mht.times, mht.poses, times)
        labels, rounds = alternate(smoother, m, scan_rows, scan_of, mht_poses, own)
        cells.append(described(labels, truth, lone) + f" ({rounds} rounds)")
        print(f"robot {robot} | " + " | ".join(cells), flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", nargs="?", default=DEFAULT)
    parser.add_argument("--vicon-motion", action="store_true")
    parser.add_argument("--smoothed", action="store_true")
    args = parser.parse_args()
    main(args.folder, args.vicon_motion, args.smoothed)
