"""probslam.geometry, the one vectorised form of the SE(2) algebra: against the bound Pose2 (C++
core/pose2.hpp) pose by pose, broadcasting, and steps / accumulate as each other's inverse."""

import numpy as np
import pytest

import probslam as ps
from probslam import geometry

#: Agreement with Pose2 beyond rounding of a few operations on coordinates up to 100 m.
TOL = 1e-12


def poses(n, seed):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-100, 100, (n, 2)), rng.uniform(-np.pi, np.pi, n)])


def pose2(row):
    return ps.Pose2(*row)


def as_row(p):
    return np.array([p.x, p.y, p.theta])


def test_compose_between_inverse_equal_pose2_row_by_row():
    a, b = poses(200, 1), poses(200, 2)
    want_c = np.array([as_row(pose2(x).compose(pose2(y))) for x, y in zip(a, b)])
    want_b = np.array([as_row(pose2(x).between(pose2(y))) for x, y in zip(a, b)])
    want_i = np.array([as_row(pose2(x).inverse()) for x in a])
    for got, want in ((geometry.compose(a, b), want_c), (geometry.between(a, b), want_b), (geometry.inverse(a), want_i)):
        np.testing.assert_allclose(got[:, :2], want[:, :2], atol=TOL)
        assert np.all(np.abs(np.angle(np.exp(1j * (got[:, 2] - want[:, 2])))) < TOL)
        assert np.all((got[:, 2] > -np.pi) & (got[:, 2] <= np.pi))


def test_broadcasting_and_one_pose():
    a = poses(5, 3)
    one = np.array([1.0, -2.0, 0.3])
    np.testing.assert_allclose(geometry.compose(a, one), geometry.compose(a, np.tile(one, (5, 1))), atol=0)
    np.testing.assert_allclose(geometry.between(one, a), geometry.between(np.tile(one, (5, 1)), a), atol=0)
    assert geometry.compose(one, one).shape == (3,)
    np.testing.assert_allclose(geometry.compose(geometry.inverse(one), one), np.zeros(3), atol=TOL)


def test_steps_and_accumulate_invert_each_other():
    path = poses(300, 4)
    moves = geometry.steps(path)
    back = geometry.accumulate(path[0], moves)
    np.testing.assert_allclose(back[:, :2], path[:, :2], atol=1e-9)  # 300 steps of rounding
    assert np.all(np.abs(np.angle(np.exp(1j * (back[:, 2] - path[:, 2])))) < 1e-9)
    # One step at a time, as a dead-reckoning loop would.
    loop = [path[0]]
    for m in moves:
        loop.append(as_row(pose2(loop[-1]).compose(pose2(m))))
    np.testing.assert_allclose(back, np.array(loop), atol=1e-9)
    assert geometry.accumulate(path[0], np.empty((0, 3))).shape == (1, 3)


def test_a_heading_that_is_not_finite_is_refused():
    with pytest.raises(ValueError, match="angle"):
        geometry.compose([0.0, 0.0, np.nan], [1.0, 0.0, 0.0])
