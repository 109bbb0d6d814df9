"""The car's (Ackermann) motion model of Guivant and Nebot against a numpy integration of the
Victoria Park README's equations, its Jacobians against finite differences, and its checks."""

import numpy as np
import pytest

import probslam as ps

#: Dead reckoning over 5,000 inputs (125 s, ~300 m) sums 5,000 steps of rounding in two
#: implementations of the same equations (sensor frame + rotation vs world frame): ~1e-12 m.
DEAD_RECKONING_TOLERANCE = 1e-9
#: Central differences with step 1e-6 on these smooth functions are good to ~1e-9.
FD_STEP, FD_TOLERANCE = 1e-6, 1e-7
VP_START = np.array([-67.6493, -41.7142, np.deg2rad(36.0)])  # the first GPS fix, heading of the README


def readme_dead_reckoning(inputs, start, L=2.83, H=0.76, a=3.78, b=0.50):
    """The README's equations, step by step in the world frame; control k held over
    [t_k, t_k+1]."""
    x, y, phi = start
    out = [start]
    for k in range(len(inputs) - 1):
        dt = inputs[k + 1, 0] - inputs[k, 0]
        ve, alpha = inputs[k, 1], inputs[k, 2]
        vc = ve / (1 - np.tan(alpha) * H / L)
        w = vc / L * np.tan(alpha)
        x, y, phi = (x + dt * (vc * np.cos(phi) - w * (a * np.sin(phi) + b * np.cos(phi))),
                     y + dt * (vc * np.sin(phi) + w * (a * np.cos(phi) - b * np.sin(phi))),
                     phi + dt * w)
        out.append((x, y, phi))
    return np.array(out)


def test_dead_reckoning_matches_the_readme_equations(shared_data):
    path = shared_data / "landmark_slam" / "victoria_park_acfr" / "inputs.dat"
    if not path.exists():
        pytest.skip(f"{path} not present")
    inputs = np.loadtxt(path, max_rows=5000)
    reference = readme_dead_reckoning(inputs, VP_START)
    pose = VP_START.copy()
    ours = [pose]
    for k in range(len(inputs) - 1):
        pose = ps.ackermann_motion(pose, inputs[k, 1], inputs[k, 2], inputs[k + 1, 0] - inputs[k, 0])
        ours.append(pose)
    ours = np.array(ours)
    assert np.ptp(reference[:, 0]) > 50  # the car has driven
    assert np.max(np.abs(ours[:, :2] - reference[:, :2])) < DEAD_RECKONING_TOLERANCE
    assert np.max(np.abs(ps.wrap_angle(ours[:, 2] - reference[:, 2]))) < DEAD_RECKONING_TOLERANCE
    # The increments composed give the same path (what the filters' predict_odometry applies).
    deltas, _ = ps.ackermann_increments(inputs[:-1, 1], inputs[:-1, 2], np.diff(inputs[:, 0]), np.zeros((2, 2)))
    pose = VP_START.copy()
    for d in deltas:
        pose = ps.Pose2.from_array(pose).compose(ps.Pose2.from_array(d)).as_array()
    assert np.max(np.abs(pose[:2] - reference[-1, :2])) < DEAD_RECKONING_TOLERANCE


def numeric_jacobian(f, x):
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = FD_STEP
        d = np.asarray(f(x + e)) - np.asarray(f(x - e))
        d[2] = ps.wrap_angle(d[2])
        cols.append(d / (2 * FD_STEP))
    return np.column_stack(cols)


@pytest.mark.parametrize("steering", [0.3, -0.4, 0.0])
def test_jacobians_match_finite_differences(steering):
    geometry = ps.AckermannGeometry(sensor_left=-0.2)
    pose, speed, dt = np.array([3.0, -1.0, 2.8]), 2.0, 0.1
    g = ps.ackermann_motion_jacobian(pose, speed, steering, dt, geometry)
    v = ps.ackermann_motion_control_jacobian(pose, speed, steering, dt, geometry)
    np.testing.assert_allclose(g, numeric_jacobian(lambda p: ps.ackermann_motion(p, speed, steering, dt, geometry),
                                                   pose), atol=FD_TOLERANCE)
    np.testing.assert_allclose(v, numeric_jacobian(
        lambda u: ps.ackermann_motion(pose, u[0], u[1], dt, geometry), np.array([speed, steering])), atol=FD_TOLERANCE)
    # The increments' covariance is the control noise carried by the increment's Jacobian.
    m = np.diag([0.04, 0.003])
    _, cov = ps.ackermann_increments([speed], [steering], [dt], m, geometry)
    v0 = ps.ackermann_motion_control_jacobian(np.zeros(3), speed, steering, dt, geometry)
    np.testing.assert_allclose(cov[0], v0 @ m @ v0.T, atol=1e-15)


def test_bad_input_is_refused_by_name():
    with pytest.raises(ValueError, match="^steering"):
        ps.ackermann_motion(np.zeros(3), 1.0, 1.6, 0.1)
    with pytest.raises(ValueError, match="^dt"):
        ps.ackermann_motion(np.zeros(3), 1.0, 0.1, 0.0)
    with pytest.raises(TypeError, match="^speed"):
        ps.ackermann_motion(np.zeros(3), "fast", 0.1, 0.1)
    with pytest.raises(ValueError, match="^wheelbase"):
        ps.AckermannGeometry(wheelbase=-1.0)
    with pytest.raises(TypeError, match="^geometry"):
        ps.ackermann_motion(np.zeros(3), 1.0, 0.1, 0.1, geometry=(2.83, 0.76))
    with pytest.raises(ValueError, match=r"^steering\[1\]"):
        ps.ackermann_increments([1.0, 1.0], [0.1, 1.4], [0.1, 0.1], np.eye(2))
    with pytest.raises(ValueError, match="^dt"):
        ps.ackermann_increments([1.0, 1.0], [0.1, 0.1], [0.1], np.eye(2))
    with pytest.raises(ValueError, match="^control_noise"):
        ps.ackermann_increments([1.0], [0.1], [0.1], -np.eye(2))
