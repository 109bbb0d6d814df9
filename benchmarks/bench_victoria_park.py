"""Victoria Park, full run with known correspondences (6 969 poses, 3 640 sightings, 151
landmarks): probslam's EkfSlam next to a dense numpy EKF of the same equations (odometry as a
relative pose, sequential range-bearing updates, state augmentation) in the same run. The two
final states must agree; prints a table and, with --record, writes it into benchmarks/RESULTS.md.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_victoria_park.py [FILE] [--record]
"""

import argparse
import datetime
import os
import pathlib
import time

import numpy as np

import probslam as ps
from common import machine, report
from probslam import landmark_slam as ls
from probslam.ekf import EkfSlam

DEFAULT = pathlib.Path(__file__).resolve().parents[2] / "shared/data/landmark_slam/victoria_park/victoriaPark.txt"
#: The two filters run the same arithmetic in a different order; over 6 969 steps their states
#: may drift apart by rounding only, far below the 0.1 m scale of the map.
AGREEMENT = 1e-6


def rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


class DenseEkf:
    """Full-matrix EKF: every step multiplies (3+2N)-square matrices, as a textbook numpy port would."""

    def __init__(self, q):
        self.mu, self.sigma, self.q, self.index = np.zeros(3), np.zeros((3, 3)), q, {}

    def predict_odometry(self, delta, noise):
        n, th = len(self.mu), self.mu[2]
        turned = rot(th) @ delta[:2]
        g = np.eye(n)
        g[0, 2], g[1, 2] = -turned[1], turned[0]
        j = np.eye(3)
        j[:2, :2] = rot(th)
        fx = np.zeros((3, n))
        fx[:, :3] = np.eye(3)
        self.mu = self.mu.copy()
        self.mu[:2] += turned
        self.mu[2] = np.angle(np.exp(1j * (th + delta[2])))
        self.sigma = g @ self.sigma @ g.T + fx.T @ j @ noise @ j.T @ fx

    def update(self, z, ids):
        for zk, i in zip(z, ids):
            if int(i) not in self.index:
                self._augment(zk, int(i))
                continue
            k0 = self.index[int(i)]
            n = len(self.mu)
            dx, dy = self.mu[k0] - self.mu[0], self.mu[k0 + 1] - self.mu[1]
            qq = dx * dx + dy * dy
            s = np.sqrt(qq)
            h = np.zeros((2, n))
            h[0, [0, 1, k0, k0 + 1]] = [-dx / s, -dy / s, dx / s, dy / s]
            h[1, [0, 1, 2, k0, k0 + 1]] = [dy / qq, -dx / qq, -1, -dy / qq, dx / qq]
            nu = zk - np.array([s, np.arctan2(dy, dx) - self.mu[2]])
            nu[1] = np.angle(np.exp(1j * nu[1]))
            gain = self.sigma @ h.T @ np.linalg.inv(h @ self.sigma @ h.T + self.q)
            self.mu = self.mu + gain @ nu
            self.sigma = (np.eye(n) - gain @ h) @ self.sigma
            self.sigma = 0.5 * (self.sigma + self.sigma.T)

    def _augment(self, z, i):
        r, a = z[0], self.mu[2] + z[1]
        gx = np.array([[1.0, 0.0, -r * np.sin(a)], [0.0, 1.0, r * np.cos(a)]])
        gz = np.array([[np.cos(a), -r * np.sin(a)], [np.sin(a), r * np.cos(a)]])
        cross = gx @ self.sigma[:3, :]
        corner = gx @ self.sigma[:3, :3] @ gx.T + gz @ self.q @ gz.T
        self.index[i] = len(self.mu)
        self.mu = np.r_[self.mu, self.mu[:2] + r * np.array([np.cos(a), np.sin(a)])]
        self.sigma = np.block([[self.sigma, cross.T], [cross, corner]])


def run(filter_, data, z, by_pose):
    """The loop of datasets.victoria_park.run_ekf, for either filter."""
    rows = by_pose.get(int(data.pose_from[0]))
    if rows is not None:
        filter_.update(z[rows], data.landmark[rows])
    for e in range(len(data.delta)):
        filter_.predict_odometry(data.delta[e], data.delta_cov[e])
        rows = by_pose.get(int(data.pose_to[e]))
        if rows is not None:
            filter_.update(z[rows], data.landmark[rows])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("file", nargs="?", default=str(DEFAULT))
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    args = parser.parse_args()
    data = ps.io.read_victoria_park(args.file)
    z, z_cov = ls.polar_measurements(data.xy, data.xy_cov)
    q = np.median(z_cov, axis=0)
    q = 0.5 * (q + q.T)
    by_pose = {int(p): np.flatnonzero(data.pose == p) for p in np.unique(data.pose)}
    ours = EkfSlam(np.eye(3) * 1e-6, q, use_signatures=False)
    t0 = time.perf_counter()
    run(ours, data, z, by_pose)
    t_ours = time.perf_counter() - t0
    dense = DenseEkf(q)
    t0 = time.perf_counter()
    run(dense, data, z, by_pose)
    t_dense = time.perf_counter() - t0
    diff = max(np.max(np.abs(ours.pose - dense.mu[:3])),
               max(np.max(np.abs(ours.landmark(i)[:2] - dense.mu[k:k + 2])) for i, k in dense.index.items()))
    if diff > AGREEMENT:
        raise SystemExit(f"the filters disagree by {diff:g}")
    lines = [f"## EKF SLAM, Victoria Park full run vs dense numpy, {datetime.date.today()}", "",
             f"Machine: {machine()}; load average {os.getloadavg()[0]:.1f} at the end (shared machine), "
             f"BLAS threads: OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}.", "",
             f"{len(data.delta) + 1} poses, {len(z)} sightings, {len(dense.index)} landmarks (state "
             f"{len(dense.mu)}), known correspondences, odometry as relative poses; both filters in "
             f"the same run, final states equal to {diff:.1e}.", "",
             "| filter | full run | per pose |", "|---|---|---|",
             f"| probslam `EkfSlam` | {t_ours:.3f} s | {t_ours / (len(data.delta) + 1) * 1e6:.1f} us |",
             f"| dense numpy, same equations | {t_dense:.2f} s ({t_dense / t_ours:.0f}x slower) | "
             f"{t_dense / (len(data.delta) + 1) * 1e6:.0f} us |", "",
             "Command: `OPENBLAS_NUM_THREADS=1 python benchmarks/bench_victoria_park.py --record`."]
    report(lines, args.record)


if __name__ == "__main__":
    main()
