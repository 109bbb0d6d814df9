"""Motion and measurement models: values, Jacobians against finite differences, bad input."""

import numpy as np
import pytest

import probslam as ps

FD_STEP = 1e-6  # central differences: truncation ~1e-12, rounding ~1e-10
FD_TOL = 1e-7


def numeric_jacobian(f, x, angle_rows=()):
    x = np.asarray(x, float)
    cols = []
    for i in range(x.size):
        a, b = x.copy(), x.copy()
        a[i] += FD_STEP
        b[i] -= FD_STEP
        d = np.asarray(f(a)) - np.asarray(f(b))
        for r in angle_rows:
            d[r] = ps.wrap_angle(d[r])
        cols.append(d / (2 * FD_STEP))
    return np.column_stack(cols)


def test_wrap_angle_range_and_vectorised():
    a = np.linspace(-40, 40, 2001)
    w = ps.wrap_angle(a)
    assert w.shape == a.shape
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-9)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-9)
    assert ps.wrap_angle(-np.pi) == np.pi
    assert ps.wrap_angle(0.3) == 0.3


@pytest.mark.parametrize("w", [0.8, -2.1, 1e-7, 0.0])
def test_velocity_motion_and_jacobians(w):
    pose, v, dt = np.array([0.3, -1.2, 2.9]), 1.1, 0.6
    out = ps.velocity_motion(pose, v, w, dt)
    if abs(w) > 1e-3:  # eq. 10.11 as printed
        expected = pose + [-v / w * np.sin(pose[2]) + v / w * np.sin(pose[2] + w * dt),
                           v / w * np.cos(pose[2]) - v / w * np.cos(pose[2] + w * dt), w * dt]
    else:
        expected = pose + [v * dt * np.cos(pose[2]), v * dt * np.sin(pose[2]), w * dt]
    expected[2] = ps.wrap_angle(expected[2])
    np.testing.assert_allclose(out, expected, atol=1e-9)
    g = numeric_jacobian(lambda p: ps.velocity_motion(p, v, w, dt), pose, angle_rows=[2])
    np.testing.assert_allclose(ps.velocity_motion_jacobian(pose, v, w, dt), g, atol=FD_TOL)
    vj = numeric_jacobian(lambda u: ps.velocity_motion(pose, u[0], u[1], dt), [v, w], angle_rows=[2])
    np.testing.assert_allclose(ps.velocity_motion_control_jacobian(pose, v, w, dt), vj, atol=FD_TOL)


def test_straight_line_limit_is_continuous():
    pose = np.array([1.0, 2.0, 0.4])
    straight = ps.velocity_motion(pose, 2.0, 0.0, 1.0)
    for w in (1e-12, -1e-12, 1e-8):
        np.testing.assert_allclose(ps.velocity_motion(pose, 2.0, w, 1.0), straight, atol=1e-7)
        np.testing.assert_allclose(ps.velocity_motion_jacobian(pose, 2.0, w, 1.0),
                                   ps.velocity_motion_jacobian(pose, 2.0, 0.0, 1.0), atol=1e-7)


@pytest.mark.parametrize("landmark", [[2.0, -1.0], [-3.0, 0.5, 7.0]])
def test_range_bearing_jacobians(landmark):
    pose = np.array([0.5, 0.2, -2.8])
    z = ps.range_bearing(pose, landmark)
    d = np.asarray(landmark[:2]) - pose[:2]
    assert z[0] == pytest.approx(np.hypot(*d))
    assert z[1] == pytest.approx(ps.wrap_angle(np.arctan2(d[1], d[0]) - pose[2]))
    hp, hl = ps.range_bearing_jacobians(pose, landmark)
    np.testing.assert_allclose(hp, numeric_jacobian(lambda p: ps.range_bearing(p, landmark), pose, [1]), atol=FD_TOL)
    np.testing.assert_allclose(hl, numeric_jacobian(lambda m: ps.range_bearing(pose, m), landmark, [1]), atol=FD_TOL)
    back = ps.landmark_from_range_bearing(pose, z)
    np.testing.assert_allclose(back, landmark, atol=1e-12)


def test_inverse_measurement_jacobians():
    pose, z = np.array([1.0, -1.0, 0.7]), np.array([3.0, -0.4])
    jp, jz = ps.landmark_from_range_bearing_jacobians(pose, z)
    np.testing.assert_allclose(jp, numeric_jacobian(lambda p: ps.landmark_from_range_bearing(p, z), pose), atol=FD_TOL)
    np.testing.assert_allclose(jz, numeric_jacobian(lambda q: ps.landmark_from_range_bearing(pose, q), z), atol=FD_TOL)


def test_pose2():
    a, b = ps.Pose2(1, 2, 0.5), ps.Pose2(-0.3, 0.7, 3.0)
    c = a * b
    back = a.between(c)
    np.testing.assert_allclose(back.as_array(), b.as_array(), atol=1e-12)
    pts = np.array([[1.0, 0.0], [0.0, 2.0]])
    np.testing.assert_allclose(a.transform_to(a.transform_from(pts)), pts, atol=1e-12)
    assert ps.Pose2(0, 0, 4.0).theta == pytest.approx(4.0 - 2 * np.pi)


@pytest.mark.parametrize("call, name", [
    (lambda: ps.velocity_motion([0, 0, 0], 1, 0, 0.0), "dt"),
    (lambda: ps.velocity_motion([0, 0, 0], 1, 0, -1), "dt"),
    (lambda: ps.velocity_motion([0, np.nan, 0], 1, 0, 1), "pose"),
    (lambda: ps.velocity_motion([0, 0], 1, 0, 1), "pose"),
    (lambda: ps.velocity_motion([0, 0, 0], np.inf, 0, 1), "v"),
    (lambda: ps.range_bearing([0, 0, 0], [0, 0, 0, 0]), "landmark"),
    (lambda: ps.range_bearing_jacobians([1, 1, 0], [1, 1]), "landmark"),
    (lambda: ps.landmark_from_range_bearing([0, 0, 0], [-1, 0]), "z"),
    (lambda: ps.Pose2.from_array([np.inf, 0, 0]), "pose"),
])
def test_bad_input_raises_value_error_naming_argument(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_wrong_type_raises_type_error_naming_argument():
    with pytest.raises(TypeError, match="pose"):
        ps.velocity_motion("abc", 1, 0, 1)
    with pytest.raises(TypeError, match="landmark"):
        ps.range_bearing([0, 0, 0], None)
