"""Landmark FastSLAM (probslam.FastSlam, C++ fastslam/fast_slam.hpp): speed, map sharing and
threads, with a numpy FastSLAM 1.0 vectorised over the particles timed in the same run.

Table 1, particle-landmark updates per second: a simulated run (probslam.sim, known
correspondences, 100 particles), versions 1 and 2; the update calls are timed apart from the
predictions.
Table 2, time per step against the map size: 100 particles whose maps hold N = 100 ... 100 000
landmarks. Each step moves the robot (odometry), observes the 5 landmarks nearest to it and
resamples. Ratio per decade (a map copied or searched whole would give 10x), tree nodes copied
per particle-landmark update, and the memory the maps hold: distinct tree nodes against the
nodes unshared copies would hold.
Table 3, Victoria Park, whole log, 100 particles: C++ version 1 with the dataset's associations
against NumpyFastSlam1 below (the same equations), and C++ with the associations hidden
(update_unknown, default options); each best particle's path against the GraphSLAM optimum, EKF
SLAM and dead reckoning beside them.
Table 4, two threads against one, same seed: speed-up and whether the results are identical,
next to what two processes get on the machine at that moment (other jobs may hold the cores).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_fastslam.py [--quick] [--record]

--quick: short runs, maps of 100 and 1000 landmarks, the first 500 Victoria Park poses (a smoke
run; not recorded). Without ../shared/data (or $PROBSLAM_SHARED_DATA) Table 3 and the Victoria
Park rows of Table 4 are skipped with a message.
"""

import argparse
import datetime
import multiprocessing
import os
import pathlib
import sys
import time

import numpy as np

import probslam as ps
from common import machine, report
from probslam import _core
from probslam import graph as pg
from probslam import landmark_slam as ls
from probslam.datasets import victoria_park

HERE = pathlib.Path(__file__).resolve().parent
SHARED = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", HERE.parents[1] / "shared" / "data"))
VICTORIA_PARK = SHARED / "landmark_slam" / "victoria_park" / "victoriaPark.txt"
PARTICLES = 100
REPEATS = 3  # timings are the best of this many runs (same seed, same result)
# Table 4's runs (1 and 2 threads alternating): the second thread's core is the one a shared
# machine takes away, so two-thread times scatter more (0.20 to 0.37 s for one workload).
THREAD_REPEATS = 7

# Simulated world (Tables 1 and 4): landmarks in a 50 m square, a circle of radius 20 m.
SIM_Q = np.diag([0.05 ** 2, np.radians(1.0) ** 2])  # range (m), bearing (rad)
SIM_M = np.diag([0.003, 0.0005])                      # control noise of (v, w)
SIM_DT = 0.2

# Map-size sweep (Table 2).
MAP_SIZES = (100, 1000, 10000, 100000)
MAP_R = np.diag([0.01 ** 2, 0.01 ** 2, np.radians(0.1) ** 2])  # odometry noise per step
MAP_SPACING = 2.0  # m between landmarks (the filter's default cell size)
MAP_BLOCK = 32     # landmarks are added in blocks of 32 x 32, each seen from its centre
SEEN_PER_STEP = 5
# Memory of one tree node (sizeof on x86-64 with GCC: spatial node 176 B, id node 64 B, one of
# each per landmark) plus glibc's 16-byte chunk header.
NODE_BYTES = (176 + 64) / 2 + 16


def best_time(fn, repeats=REPEATS):
    """(smallest wall time of `repeats` calls of fn, fn's last result)."""
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def same_state(a, b):
    """Whether two filters hold bit-identical particles: poses, weights and every map."""
    if not (np.array_equal(a.poses, b.poses) and np.array_equal(a.log_weights, b.log_weights)):
        return False
    return all(np.array_equal(getattr(a.landmarks(k), name), getattr(b.landmarks(k), name))
               for k in range(a.num_particles) for name in ("ids", "means", "covariances"))


# ---- Table 1: particle-landmark updates per second ---------------------------------------------


def simulated_run(steps):
    """A probslam.sim run: 150 landmarks, a 180 deg 10 m sensor, about 9 sightings per scan."""
    rng = np.random.default_rng(1)
    world = ps.sim.LandmarkWorld.random(150, 25.0, rng, min_separation=2.0)
    sensor = ps.sim.Sensor(SIM_Q, max_range=10.0, fov=np.pi)
    return ps.sim.simulate(world, ps.sim.circle_controls(steps, 1.0, 0.05), SIM_DT, sensor, SIM_M, rng,
                           initial_pose=(0.0, -20.0, 0.0))


def run_simulated(run, version, threads=1):
    """The filter over the run: (filter, seconds in update, seconds in predict)."""
    f = ps.FastSlam(SIM_M, SIM_Q, num_particles=PARTICLES, version=version, threads=threads, seed=7,
                    initial_pose=run.poses[0])
    t_update = t_predict = 0.0
    for (v, w), z, ids in zip(run.controls, run.measurements, run.ids):
        t0 = time.perf_counter()
        f.predict(v, w, run.dt)
        t1 = time.perf_counter()
        f.update(z, ids)
        t_predict, t_update = t_predict + t1 - t0, t_update + time.perf_counter() - t1
    return f, t_update, t_predict


def table_update_rates(run):
    """Table 1: per version, the run with the least time in predict + update of REPEATS."""
    sightings = sum(len(z) for z in run.measurements)
    lines = ["| version | steps | sightings | particle-landmark updates | s in update | updates per second | "
             "us per predict | resamplings | final position error (m) |", "|---|---|---|---|---|---|---|---|---|"]
    for version in (1, 2):
        print(f"bench_fastslam: simulated run, version {version} ...", file=sys.stderr, flush=True)
        runs = [run_simulated(run, version) for _ in range(REPEATS)]
        f, t_update, t_predict = min(runs, key=lambda r: r[1] + r[2])
        err = np.hypot(*(f.mean_pose[:2] - run.poses[-1, :2]))
        lines.append(f"| {version} | {len(run.controls)} | {sightings} | {PARTICLES * sightings / 1e6:.2f} M | "
                     f"{t_update:.3f} | **{PARTICLES * sightings / t_update / 1e6:.2f} M/s** | "
                     f"{t_predict / len(run.controls) * 1e6:.0f} | {f.num_resamples} | {err:.3f} |")
    return lines + ["", "Simulated (probslam.sim): 150 landmarks in a 50 m square, a circle of radius 20 m "
                    f"(v = 1 m/s, w = 0.05 rad/s, dt = {SIM_DT} s), 180 deg 10 m sensor, Q = diag(0.05 m, 1 deg)^2, "
                    "control noise diag(0.003, 0.0005), known correspondences, seed 7. Updates per second: "
                    "particles x sightings over the time spent in `update` (the Python call included); final "
                    "position error: the weighted mean pose against the true one.", ""]


# ---- Table 2: time per step against the number of landmarks ------------------------------------


def grid_landmarks(n):
    """(n, 2) landmarks on a square grid MAP_SPACING apart, numbered block by block."""
    side = int(np.ceil(np.sqrt(n)))
    ij = np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1).reshape(-1, 2)
    block = (ij[:, 0] // MAP_BLOCK) * side + ij[:, 1] // MAP_BLOCK
    return MAP_SPACING * ij[np.argsort(block, kind="stable")][:n].astype(float)


def range_bearing(pose, points):
    d = points - pose[:2]
    return np.column_stack([np.hypot(d[:, 0], d[:, 1]), wrap(np.arctan2(d[:, 1], d[:, 0]) - pose[2])])


class MapSweep:
    """A robot over a grid of landmarks, driving one FastSlam of PARTICLES particles whose
    resampling is explicit (resample_threshold 0): every step resamples."""

    def __init__(self, n, rng):
        self.points, self.rng, self.pose = grid_landmarks(n), rng, np.zeros(3)
        self.filter = ps.FastSlam(MAP_R, SIM_Q, num_particles=PARTICLES, resample_threshold=0.0, seed=3,
                                  record_path=False)

    def plan(self, known):
        """(pose, ids, z) of one step: a random pose near one of the first `known` landmarks,
        and noisy measurements of the SEEN_PER_STEP landmarks nearest to it."""
        pts = self.points[:known]
        to = np.r_[pts[self.rng.integers(known)] + self.rng.uniform(0.5, 1.5, 2), self.rng.uniform(-np.pi, np.pi)]
        near = np.flatnonzero(np.max(np.abs(pts - to[:2]), axis=1) <= 2 * MAP_SPACING)
        ids = near[np.argsort(np.hypot(*(pts[near] - to[:2]).T), kind="stable")[:SEEN_PER_STEP]]
        z = range_bearing(to, pts[ids]) + self.rng.standard_normal((len(ids), 2)) * np.sqrt(np.diag(SIM_Q))
        return to, ids, z

    def step(self, to, ids, z):
        self.filter.predict_odometry(ps.eval.relative_poses(self.pose, to), MAP_R)
        self.pose = to
        self.filter.update(z, ids)
        self.filter.resample()

    def build(self):
        """Adds the landmarks block by block, each block seen at once from its centre, with a few
        ordinary steps after each block (their resamplings let the particles share the maps)."""
        n, size = len(self.points), MAP_BLOCK * MAP_BLOCK
        for start in range(0, n, size):
            ids = np.arange(start, min(n, start + size))
            centre = np.r_[self.points[ids].mean(axis=0), 0.0]
            self.filter.predict_odometry(ps.eval.relative_poses(self.pose, centre), MAP_R)
            self.pose = centre
            self.filter.update(range_bearing(centre, self.points[ids]), ids)
            for _ in range(5):
                self.step(*self.plan(ids[-1] + 1))

    def timed_steps(self, steps):
        """Seconds per step (best of REPEATS batches of `steps`) and tree nodes created per
        particle-landmark update (live nodes after the update minus before it)."""
        best, created = np.inf, []
        for _ in range(REPEATS):
            plans = [self.plan(len(self.points)) for _ in range(steps)]
            tos = np.array([to for to, _, _ in plans])
            odometry = ps.eval.relative_poses(np.vstack([self.pose, tos[:-1]]), tos)  # computed before the clock
            self.pose = tos[-1]
            elapsed = 0.0
            for (to, ids, z), delta in zip(plans, odometry):
                t0 = time.perf_counter()
                self.filter.predict_odometry(delta, MAP_R)
                before = _core._persistent_tree_nodes()
                self.filter.update(z, ids)
                created.append((_core._persistent_tree_nodes() - before) / (PARTICLES * len(ids)))
                self.filter.resample()
                elapsed += time.perf_counter() - t0
            best = min(best, elapsed / steps)
        return best, float(np.median(created))


def rss_mib():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def table_map_sizes(sizes, steps):
    """Table 2: one row per map size, with the ratio of its step time to the previous size's."""
    lines = ["| landmarks N | build (s) | ms per step | ratio to N / 10 | new tree nodes per particle-landmark "
             "update | log2 N | tree nodes distinct / unshared | MiB distinct / unshared | process RSS (MiB) |",
             "|---|---|---|---|---|---|---|---|---|"]
    previous = None
    for n in sizes:
        print(f"bench_fastslam: map of {n} landmarks ...", file=sys.stderr, flush=True)
        sweep = MapSweep(n, np.random.default_rng(n))
        t0 = time.perf_counter()
        sweep.build()
        for _ in range(50):  # settle: the build's last unshared copies go
            sweep.step(*sweep.plan(n))
        built = time.perf_counter() - t0
        per_step, created = sweep.timed_steps(steps)
        s = sweep.filter.map_sharing
        ratio = f"{per_step / previous:.2f}x" if previous else "-"
        lines.append(f"| {n} | {built:.1f} | {per_step * 1e3:.3f} | {ratio} | {created:.1f} | {np.log2(n):.1f} | "
                     f"{s.distinct_nodes} / {s.total_nodes} | {s.distinct_nodes * NODE_BYTES / 2 ** 20:.1f} / "
                     f"{s.total_nodes * NODE_BYTES / 2 ** 20:.0f} | {rss_mib():.0f} |")
        previous = per_step
        del sweep
    return lines + ["", f"Step: odometry to a random pose in the map, an update with the {SEEN_PER_STEP} landmarks "
                    f"nearest to it (known ids) and a resampling, {PARTICLES} particles, {steps} steps (best of "
                    f"{REPEATS}). Landmarks on a {MAP_SPACING:g} m grid, added in blocks of {MAP_BLOCK} x {MAP_BLOCK} "
                    "seen from the block's centre, then 5 steps per block and 50 more before timing. A map copied "
                    "or searched whole would make the step 10x slower per decade. New tree nodes: live nodes "
                    "(`_persistent_tree_nodes`) after the update minus before it, per particle and landmark, median "
                    "over the steps (the path copies; those still shared by another particle are not counted "
                    "twice). MiB at "
                    f"{NODE_BYTES:g} B per node (sizeof of the two node types on x86-64, plus the allocator's "
                    "header); unshared: what deep copies of every particle's map would hold.", ""]


# ---- Table 3: Victoria Park, C++ against numpy ---------------------------------------------------


class VictoriaPark:
    """The iSAM file as a filter sees it: per chain pose, its odometry from the previous one and
    the range-bearing sightings made there (polar form of the file's Cartesian points)."""

    def __init__(self, path, poses=None):
        data = ps.io.read_victoria_park(path)
        self.chain = np.r_[data.pose_from[0], data.pose_to][:poses]
        self.delta, self.delta_cov = data.delta[:len(self.chain) - 1], data.delta_cov[:len(self.chain) - 1]
        z, z_cov = ls.polar_measurements(data.xy, data.xy_cov)
        q = np.median(z_cov, axis=0)  # as bench_victoria_park / datasets.victoria_park.run_ekf
        self.q = 0.5 * (q + q.T)
        position = {int(p): k for k, p in enumerate(self.chain)}
        at = np.array([position.get(int(p), -1) for p in data.pose])
        keep = at >= 0
        order = np.argsort(at[keep], kind="stable")
        self.z, self.ids = z[keep][order], data.landmark[keep][order]
        self.bounds = np.searchsorted(at[keep][order], np.arange(len(self.chain) + 1))
        _, self.dense = np.unique(self.ids, return_inverse=True)  # ids 0..L-1 for numpy's arrays
        self.num_landmarks = int(self.dense.max()) + 1 if len(self.dense) else 0

    def scans(self):
        """(k, odometry or None, rows of the sightings at pose k)."""
        for k in range(len(self.chain)):
            odometry = (self.delta[k - 1], self.delta_cov[k - 1]) if k else None
            yield k, odometry, slice(self.bounds[k], self.bounds[k + 1])


def run_victoria_cpp(vp, known, threads=1):
    """Hidden associations: the odometry noise inflated as `probslam fastslam` does
    (victoria_park.ODOMETRY_NOISE_SCALE), which lets the particles close the park's loops."""
    f = ps.FastSlam(np.eye(3) * 1e-6, vp.q, num_particles=PARTICLES, version=1, seed=11, threads=threads)
    inflate = 1.0 if known else victoria_park.ODOMETRY_NOISE_SCALE ** 2
    for _, odometry, rows in vp.scans():
        if odometry is not None:
            f.predict_odometry(odometry[0], odometry[1] * inflate)
        if rows.stop > rows.start:
            if known:
                f.update(vp.z[rows], vp.ids[rows])
            else:
                f.update_unknown(vp.z[rows])
    return f


class NumpyFastSlam1:
    """FastSLAM 1.0 with known correspondences, vectorised over the M particles: poses (M, 3),
    landmark means (M, L, 2) and covariances (M, L, 2, 2) indexed by dense landmark number,
    log weights (M,). The equations of C++ FastSlam version 1 (Table 13.1):
      motion:       x <- x (+) (delta + e), e ~ N(0, noise) in the robot frame;
      seen before:  H = dh/dm, Q_j = H S H^T + Q, K = S H^T Q_j^-1, mu += K nu,
                    S <- S - K Q_j K^T, log w += log N(nu; 0, Q_j) (bearing of nu wrapped);
      new:          mu = x + r (cos(th + phi), sin(th + phi)), S = H^-1 Q H^-T, log w += log p_new;
      resampling:   low-variance when N_eff = 1 / sum w^2 < M / 2.
    Python loops run over the measurements of a scan, never over particles. Each particle's path
    is kept as the poses of every step and the resampling ancestors (traced back at the end)."""

    def __init__(self, m, num_landmarks, q, steps, p_new=0.01, seed=0):
        self.m, self.q, self.log_p_new = m, np.asarray(q, float), np.log(p_new)
        self.rng = np.random.default_rng(seed)
        self.x = np.zeros((m, 3))
        self.mu = np.zeros((m, num_landmarks, 2))
        self.sigma = np.zeros((m, num_landmarks, 2, 2))
        self.seen = np.zeros(num_landmarks, bool)  # known correspondences: the same in every particle
        self.log_w = np.full(m, -np.log(m))
        self.history = np.zeros((steps, m, 3))
        self.ancestors = np.tile(np.arange(m), (steps, 1))
        self.step, self.num_resamples = 0, 0

    def predict_odometry(self, delta, noise):
        d = delta + self.rng.standard_normal((self.m, 3)) @ np.linalg.cholesky(noise).T
        c, s = np.cos(self.x[:, 2]), np.sin(self.x[:, 2])
        self.x[:, 0] += c * d[:, 0] - s * d[:, 1]
        self.x[:, 1] += s * d[:, 0] + c * d[:, 1]
        self.x[:, 2] = wrap(self.x[:, 2] + d[:, 2])
        self.step += 1
        self.history[self.step] = self.x

    def update(self, z, landmarks):
        for (r, phi), j in zip(z, landmarks):
            if self.seen[j]:
                self._update_landmark(r, phi, j)
            else:
                self._new_landmark(r, phi, j)
                self.seen[j] = True
        self.log_w -= np.logaddexp.reduce(self.log_w)
        if 1.0 / np.sum(np.exp(2 * self.log_w)) < 0.5 * self.m:
            self._resample()

    def _update_landmark(self, r, phi, j):
        x, mu, s = self.x, self.mu[:, j], self.sigma[:, j]
        d = mu - x[:, :2]
        q2 = np.sum(d * d, axis=1)
        rr = np.sqrt(q2)
        h = np.stack([np.stack([d[:, 0] / rr, d[:, 1] / rr], -1), np.stack([-d[:, 1] / q2, d[:, 0] / q2], -1)], 1)
        qj = h @ s @ h.transpose(0, 2, 1) + self.q
        nu = np.stack([r - rr, wrap(phi - np.arctan2(d[:, 1], d[:, 0]) + x[:, 2])], -1)
        det = qj[:, 0, 0] * qj[:, 1, 1] - qj[:, 0, 1] * qj[:, 1, 0]
        qj_inv = np.stack([np.stack([qj[:, 1, 1], -qj[:, 0, 1]], -1), np.stack([-qj[:, 1, 0], qj[:, 0, 0]], -1)],
                          1) / det[:, None, None]
        k = s @ h.transpose(0, 2, 1) @ qj_inv
        self.mu[:, j] = mu + np.einsum("mij,mj->mi", k, nu)
        s_new = s - k @ qj @ k.transpose(0, 2, 1)
        self.sigma[:, j] = 0.5 * (s_new + s_new.transpose(0, 2, 1))
        self.log_w += -0.5 * (np.einsum("mi,mij,mj->m", nu, qj_inv, nu) + np.log((2 * np.pi) ** 2 * det))

    def _new_landmark(self, r, phi, j):
        a = self.x[:, 2] + phi
        c, s = np.cos(a), np.sin(a)
        self.mu[:, j] = self.x[:, :2] + r * np.stack([c, s], -1)
        h_inv = np.stack([np.stack([c, -r * s], -1), np.stack([s, r * c], -1)], 1)
        self.sigma[:, j] = h_inv @ self.q @ h_inv.transpose(0, 2, 1)
        self.log_w += self.log_p_new

    def _resample(self):
        """Low-variance (systematic) resampling: one offset, M equally spaced pointers."""
        edges = np.cumsum(np.exp(self.log_w))
        pointers = (self.rng.uniform(0.0, 1.0) + np.arange(self.m)) / self.m * edges[-1]
        idx = np.minimum(np.searchsorted(edges, pointers, side="right"), self.m - 1)
        self.x, self.mu, self.sigma = self.x[idx], self.mu[idx], self.sigma[idx]
        self.log_w = np.full(self.m, -np.log(self.m))
        self.ancestors[self.step] = idx
        self.num_resamples += 1

    def best_path(self):
        """The path of the particle of highest weight, traced back through the ancestors."""
        k = int(np.argmax(self.log_w))
        path = np.empty((self.step + 1, 3))
        for t in range(self.step, -1, -1):
            k = self.ancestors[t, k]
            path[t] = self.history[t, k]
        return path


def run_victoria_numpy(vp):
    f = NumpyFastSlam1(PARTICLES, vp.num_landmarks, vp.q, len(vp.chain), seed=11)
    for _, odometry, rows in vp.scans():
        if odometry is not None:
            f.predict_odometry(*odometry)
        if rows.stop > rows.start:
            f.update(vp.z[rows], vp.dense[rows])
    return f


def run_victoria_ekf(vp):
    """EKF SLAM (known correspondences) over the same scans: its pose after each step, (P, 3)."""
    ekf = ps.EkfSlam(np.eye(3) * 1e-6, vp.q, use_signatures=False)
    poses = np.empty((len(vp.chain), 3))
    for k, odometry, rows in vp.scans():
        if odometry is not None:
            ekf.predict_odometry(*odometry)
        if rows.stop > rows.start:
            ekf.update(vp.z[rows], vp.ids[rows])
        poses[k] = ekf.pose
    return poses


def dead_reckoning(vp):
    poses = np.zeros((len(vp.chain), 3))
    for k, d in enumerate(vp.delta):
        x = poses[k]
        c, s = np.cos(x[2]), np.sin(x[2])
        poses[k + 1] = x + [c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]]
    return poses


def graphslam_optimum(vp):
    """(P, 3) poses of the GraphSLAM optimum (EKF start, Gauss-Newton: chi2 6184.12) along the chain."""
    g = pg.read_pose_graph(str(VICTORIA_PARK))
    pg.initialize(g, "ekf")
    pg.optimize(g)
    ids = np.asarray(g.pose_ids)
    order = np.argsort(ids)
    return np.asarray(g.poses)[order[np.searchsorted(ids[order], vp.chain)]]


def path_rmse(path, optimum):
    return float(np.sqrt(np.mean(np.sum((path[:, :2] - optimum[:len(path), :2]) ** 2, axis=1))))


def table_victoria_park(vp):
    """Table 3: C++ FastSlam (known, hidden) and the numpy filter on the same scans, EKF SLAM
    and dead reckoning for reference; paths against the GraphSLAM optimum."""
    optimum = graphslam_optimum(vp)
    print("bench_fastslam: Victoria Park, C++ known ...", file=sys.stderr, flush=True)
    t_cpp, cpp = best_time(lambda: run_victoria_cpp(vp, known=True))
    print("bench_fastslam: Victoria Park, numpy known ...", file=sys.stderr, flush=True)
    t_np, npf = best_time(lambda: run_victoria_numpy(vp))
    print("bench_fastslam: Victoria Park, C++ hidden ...", file=sys.stderr, flush=True)
    t_unk, unk = best_time(lambda: run_victoria_cpp(vp, known=False))
    counts = [len(unk.landmarks(k)) for k in range(unk.num_particles)]
    lines = [
        f"| Victoria Park, {len(vp.chain)} poses, {len(vp.z)} sightings | s | us per pose | landmarks (best "
        "particle) | resamplings | best path RMSE vs GraphSLAM optimum (m) | speed-up vs numpy |",
        "|---|---|---|---|---|---|---|",
        f"| C++ `FastSlam`, version 1, known | {t_cpp:.3f} | {t_cpp / len(vp.chain) * 1e6:.0f} | "
        f"{cpp.num_landmarks} | {cpp.num_resamples} | {path_rmse(cpp.path(), optimum):.2f} | "
        f"**{t_np / t_cpp:.1f}x** |",
        f"| numpy FastSLAM 1.0 (below), known | {t_np:.3f} | {t_np / len(vp.chain) * 1e6:.0f} | "
        f"{int(npf.seen.sum())} | {npf.num_resamples} | {path_rmse(npf.best_path(), optimum):.2f} | 1.0x |",
        f"| C++ `FastSlam`, version 1, hidden (`update_unknown`) | **{t_unk:.3f}** | {t_unk / len(vp.chain) * 1e6:.0f} | "
        f"**{unk.num_landmarks}** (particles: {min(counts)} - {max(counts)}) | {unk.num_resamples} | "
        f"{path_rmse(unk.path(), optimum):.2f} | - |",
    ]
    t_ekf, ekf_path = best_time(lambda: run_victoria_ekf(vp))
    lines += [f"| for reference: EKF SLAM (`EkfSlam`), known | {t_ekf:.3f} | {t_ekf / len(vp.chain) * 1e6:.0f} | "
             f"{len(np.unique(vp.ids))} | - | {path_rmse(ekf_path, optimum):.2f} (filtered poses) | - |",
             f"| for reference: dead reckoning | - | - | - | - | {path_rmse(dead_reckoning(vp), optimum):.2f} | - |"]
    return lines + ["", "Victoria Park (iSAM's victoriaPark.txt): odometry as relative poses with the file's "
                    "covariances (`predict_odometry`; the file holds no velocity controls), sightings converted to "
                    "range-bearing, Q their median polar covariance (as bench_victoria_park.py), p_new 0.01, "
                    "default options, seed 11. The numpy filter is NumpyFastSlam1 in this file: the same equations "
                    "vectorised over the particles (arrays (M, L, 2) and (M, L, 2, 2)); its own random numbers, so "
                    "its run differs from the C++ one by sampling only. Hidden: `update_unknown` with the default "
                    "options (maximum likelihood against p_new = 0.01, 2 m association radius, no negative "
                    f"information) and the odometry covariances times {victoria_park.ODOMETRY_NOISE_SCALE:g}^2 "
                    "(VICTORIA_PARK_ODOMETRY_NOISE_SCALE, as `probslam fastslam`); the dataset has 151 landmarks. GraphSLAM optimum: EKF start and Gauss-Newton "
                    "(chi2 6184.12), the same file; the filters' best-particle paths and the EKF's filtered poses "
                    "are compared with it, position only, no alignment (all start at the first pose).", ""]


# ---- Table 4: two threads against one ------------------------------------------------------------


def _busy(_=None):
    total = 0
    for i in range(4_000_000):
        total += i
    return total


def parallel_ceiling():
    """Speed-up of two processes of pure-Python work over one (2.00 on two idle cores): what
    the machine can give a second thread while this benchmark runs."""
    ctx = multiprocessing.get_context("fork")

    def processes(n):
        workers = [ctx.Process(target=_busy) for _ in range(n)]
        for p in workers:
            p.start()
        for p in workers:
            p.join()

    t1, _ = best_time(lambda: processes(1))
    t2, _ = best_time(lambda: processes(2))
    return 2 * t1 / t2


def interleaved_best_times(fn, repeats=THREAD_REPEATS):
    """((best time, last result, every time) with 1 thread, the same with 2): the runs alternate,
    so that a slow spell of a shared machine falls on both counts alike."""
    times = {1: [], 2: []}
    last = {}
    for _ in range(repeats):
        for threads in (1, 2):
            t0 = time.perf_counter()
            last[threads] = fn(threads)
            times[threads].append(time.perf_counter() - t0)
    return tuple((min(times[t]), last[t], times[t]) for t in (1, 2))


def table_threads(run, vp):
    """Table 4: per workload, wall time with 1 and 2 threads (best of THREAD_REPEATS, alternating),
    the speed-up and whether the results are identical."""
    workloads = [(f"simulated, version {v}, known", lambda t, v=v: run_simulated(run, v, t)[0]) for v in (1, 2)]
    if vp is not None:
        workloads += [("Victoria Park, version 1, known", lambda t: run_victoria_cpp(vp, True, t)),
                      ("Victoria Park, version 1, hidden", lambda t: run_victoria_cpp(vp, False, t))]
    lines = ["| threads, workload | 1 thread (s) | 2 threads (s) | speed-up | 2-thread runs, fastest - slowest (s) "
             "| results |", "|---|---|---|---|---|---|"]
    for name, fn in workloads:
        print(f"bench_fastslam: threads, {name} ...", file=sys.stderr, flush=True)
        (t1, f1, _), (t2, f2, all2) = interleaved_best_times(fn)
        lines.append(f"| {name} | {t1:.3f} | {t2:.3f} | **{t1 / t2:.2f}x** | {min(all2):.3f} - {max(all2):.3f} | "
                    f"{'identical' if same_state(f1, f2) else 'DIFFERENT'} |")
    lines.append(f"| for reference: two processes of pure-Python work against one (the machine's ceiling now) | - | - "
                f"| {parallel_ceiling():.2f}x | - | - |")
    return lines + ["", f"Best of {THREAD_REPEATS} runs each, 1 and 2 threads alternating. Same seed; identical: every "
                    "particle's pose, log weight and map equal bit for bit. The simulated workloads are Table 1's; "
                    "Victoria Park: Table 3's C++ runs. On this virtual machine two-thread runs fall into spells "
                    "about twice as slow, lasting seconds to minutes, which one-thread runs do not show; a spell "
                    "over all of a workload's runs shows in its speed-up (see docs/landmark_fastslam.md).", ""]


# ---- main ------------------------------------------------------------------------------------------


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="short runs, small maps (not recorded)")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    run = simulated_run(200 if args.quick else 1000)
    vp = None
    if VICTORIA_PARK.exists():
        vp = VictoriaPark(VICTORIA_PARK, 500 if args.quick else None)
    else:
        print(f"bench_fastslam: {VICTORIA_PARK} not found; the Victoria Park runs are skipped", file=sys.stderr)
    lines = [f"## Landmark FastSLAM (FastSlam), {datetime.date.today()}", "",
             f"Machine: {machine()}. {PARTICLES} particles, one thread unless stated; wall times, best of "
             f"{REPEATS} runs (same seed, same result).", ""]
    lines += table_update_rates(run)
    # The large maps of Table 2 run last: after a process has built and freed a 100 000-landmark
    # map, its main thread's heap is scattered, and a small filter on that thread alone ran ~35%
    # slower (0.74 s against 0.54 s on Victoria Park), which would also flatter Table 4's threads.
    later = table_victoria_park(vp) if vp is not None else [
        f"Victoria Park: {VICTORIA_PARK} not found; its runs were skipped.", ""]
    threads = table_threads(run, vp)
    lines += table_map_sizes(MAP_SIZES[:2] if args.quick else MAP_SIZES, 100 if args.quick else 300)
    lines += later + threads
    lines += ["Issue 14's targets: C++ at least 50x the numpy FastSLAM 1.0 on Victoria Park, the hidden-association "
              "run (100 particles) under 2 s on one core, 2 threads at least 1.7x one.",
              f"Load average at the start: {load:.2f}, at the end: {os.getloadavg()[0]:.2f} (on {os.cpu_count()} "
              f"cores; OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}).",
              f"Command: `OPENBLAS_NUM_THREADS=1 python benchmarks/bench_fastslam.py{' --quick' if args.quick else ''}`.",
              ""]
    report(lines, record=args.record and not args.quick)


if __name__ == "__main__":
    main()
