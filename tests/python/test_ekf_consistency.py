"""Monte-Carlo consistency of EKF SLAM with known correspondences on simulated runs."""

import numpy as np
import pytest
from scipy.stats import chi2

import probslam as ps

pytestmark = pytest.mark.slow  # 50 Monte-Carlo runs

RUNS = 50
STEPS = 150
SKIP = 5  # the first control-space predictions leave a rank-2 pose covariance: no NEES yet


def monte_carlo(steps=STEPS, runs=RUNS):
    world = ps.sim.LandmarkWorld.random(15, 10.0, np.random.default_rng(1), min_separation=2.0)
    q = np.diag([0.05 ** 2, np.radians(1.0) ** 2])
    m = np.diag([0.01, 0.002])
    sensor = ps.sim.Sensor(q, max_range=8.0, fov=np.radians(180))
    nees = np.zeros((runs, steps))
    nis = []
    for k in range(runs):
        rng = np.random.default_rng(1000 + k)
        run = ps.sim.simulate(world, ps.sim.circle_controls(steps, 1.0, 0.12), 0.2, sensor, m, rng,
                              initial_pose=(0, -8.3, 0))
        nees[k], step_nis = ps.sim.filter_known(run, m, q)
        nis += step_nis
    return nees.mean(axis=0), np.concatenate(nis)


def test_average_nees_and_nis_inside_chi_square_bands():
    anees, nis = monte_carlo()
    lo, hi = chi2.ppf([0.025, 0.975], 3 * RUNS) / RUNS  # [2.36, 3.72]
    inside = (anees[SKIP:] > lo) & (anees[SKIP:] < hi)
    assert inside.mean() > 0.9  # about 95% of the steps if the filter is consistent
    assert lo < anees[SKIP:].mean() < hi
    n = len(nis)
    lo_nis, hi_nis = chi2.ppf([0.025, 0.975], 2 * n) / n
    assert lo_nis < nis.mean() < hi_nis
