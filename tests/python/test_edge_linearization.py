"""The vectorised edge linearisations and motion increments (``linearize_pose_edges``,
``linearize_point_edges``, ``velocity_increments``) that GraphSLAM's refinement of landmark runs
uses instead of numpy copies: their errors against PoseGraph2D's own edge chi2 and a plain
transform computation, their Jacobians against central differences, the increments against the
closed-form arc of the velocity model; bad input refused by name."""

import numpy as np
import pytest

import probslam as ps

#: Central differences with this step: truncation (h^2 times a third derivative of order 1 on
#: these poses) and rounding (1e-16 / h) both stay near 1e-10, far below the checks' 1e-7.
STEP = 1e-6
#: What the central differences agree to (their own error is about 1e-10).
DIFFERENCE_TOLERANCE = 1e-7


def _poses(rng, n):
    return np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-5, 5, n), rng.uniform(-np.pi, np.pi, n)])


def _se2(p):
    c, s = np.cos(p[2]), np.sin(p[2])
    return np.array([[c, -s, p[0]], [s, c, p[1]], [0.0, 0.0, 1.0]])


def _t2v(m):
    return np.array([m[0, 2], m[1, 2], np.arctan2(m[1, 0], m[0, 0])])


def _difference(f, x, k):
    e = np.zeros_like(x)
    e[k] = STEP
    d = (f(x + e) - f(x - e)) / (2 * STEP)
    return d


def test_pose_edge_errors_are_the_graphs_and_the_jacobians_its_derivatives():
    rng = np.random.default_rng(0)
    a, b, z = _poses(rng, 40), _poses(rng, 40), _poses(rng, 40)
    error, d_from, d_to = ps.linearize_pose_edges(a, b, z)
    assert error.shape == (40, 3) and d_from.shape == d_to.shape == (40, 3, 3)
    g = ps.PoseGraph2D()
    for k in range(40):
        expected = _t2v(np.linalg.inv(_se2(z[k])) @ np.linalg.inv(_se2(a[k])) @ _se2(b[k]))
        np.testing.assert_allclose(error[k], expected, atol=1e-12)
        g.add_pose(2 * k, a[k])
        g.add_pose(2 * k + 1, b[k])
        g.add_pose_edge(2 * k, 2 * k + 1, z[k], np.eye(3))
        for j in range(3):
            def err_from(x, k=k):
                return ps.linearize_pose_edges(x[None], b[k][None], z[k][None])[0][0]

            def err_to(x, k=k):
                return ps.linearize_pose_edges(a[k][None], x[None], z[k][None])[0][0]
            np.testing.assert_allclose(d_from[k][:, j], _difference(err_from, a[k], j), atol=DIFFERENCE_TOLERANCE)
            np.testing.assert_allclose(d_to[k][:, j], _difference(err_to, b[k], j), atol=DIFFERENCE_TOLERANCE)
    # The graph's chi2 with identity information is the sum of the squared errors.
    np.testing.assert_allclose(g.chi2(), np.sum(error ** 2), rtol=1e-12)


def test_point_edge_errors_are_the_graphs_and_the_jacobians_its_derivatives():
    rng = np.random.default_rng(1)
    poses, points, z = _poses(rng, 30), rng.uniform(-8, 8, (30, 2)), rng.uniform(-3, 3, (30, 2))
    error, d_pose, d_point = ps.linearize_point_edges(poses, points, z)
    assert error.shape == (30, 2) and d_pose.shape == (30, 2, 3) and d_point.shape == (30, 2, 2)
    g = ps.PoseGraph2D()
    for k in range(30):
        local = np.linalg.inv(_se2(poses[k])) @ np.append(points[k], 1.0)
        np.testing.assert_allclose(error[k], local[:2] - z[k], atol=1e-12)
        g.add_pose(2 * k, poses[k])
        g.add_point(2 * k + 1, points[k])
        g.add_point_edge(2 * k, 2 * k + 1, z[k], np.eye(2))
        for j in range(3):
            def err_pose(x, k=k):
                return ps.linearize_point_edges(x[None], points[k][None], z[k][None])[0][0]
            np.testing.assert_allclose(d_pose[k][:, j], _difference(err_pose, poses[k], j), atol=DIFFERENCE_TOLERANCE)
        for j in range(2):
            def err_point(x, k=k):
                return ps.linearize_point_edges(poses[k][None], x[None], z[k][None])[0][0]
            np.testing.assert_allclose(d_point[k][:, j], _difference(err_point, points[k], j),
                                       atol=DIFFERENCE_TOLERANCE)
    np.testing.assert_allclose(g.chi2(), np.sum(error ** 2), rtol=1e-12)


def test_velocity_increments_are_the_closed_form_arc_and_its_propagated_noise():
    v = np.array([0.3, -0.2, 0.0, 0.5, 1e-9, 2.0])
    w = np.array([0.5, 1e-5, -0.7, 0.0, 2.0, -1.3])
    dt = np.array([0.015, 0.2, 0.01, 1.0, 0.3, 0.5])
    noise = np.array([np.diag([0.15 ** 2, 0.6 ** 2])] * 5 + [[[0.04, 0.01], [0.01, 0.09]]])

    def arc(u):  # Table 5.3 from the origin, without noise (1 - cos as 2 sin^2: no cancellation)
        vv, ww, t = u
        if ww == 0.0:
            return np.array([vv * t, 0.0, 0.0])
        return np.array([vv / ww * np.sin(ww * t), vv / ww * 2.0 * np.sin(0.5 * ww * t) ** 2, ww * t])

    delta, cov = ps.velocity_increments(v, w, dt, noise)
    assert delta.shape == (6, 3) and cov.shape == (6, 3, 3)
    for k in range(len(v)):
        u = np.array([v[k], w[k], dt[k]])
        np.testing.assert_allclose(delta[k], arc(u), rtol=1e-9, atol=1e-12)
        if w[k] == 0.0:
            continue  # the closed form's derivative in w is 0 / 0 there
        jac = np.column_stack([_difference(arc, u, 0), _difference(arc, u, 1)])
        np.testing.assert_allclose(cov[k], jac @ noise[k] @ jac.T, rtol=1e-6, atol=1e-12)
        np.testing.assert_array_equal(cov[k], cov[k].T)


@pytest.mark.parametrize("call, error, name", [
    (lambda: ps.linearize_pose_edges(np.zeros((2, 3)), np.zeros((3, 3)), np.zeros((2, 3))), ValueError, "to_poses"),
    (lambda: ps.linearize_pose_edges(np.zeros((2, 2)), np.zeros((2, 3)), np.zeros((2, 3))), ValueError, "from_poses"),
    (lambda: ps.linearize_pose_edges(np.zeros((1, 3)), np.zeros((1, 3)), [[np.nan, 0, 0]]), ValueError,
     "measurements"),
    (lambda: ps.linearize_pose_edges("a", np.zeros((1, 3)), np.zeros((1, 3))), TypeError, "from_poses"),
    (lambda: ps.linearize_point_edges(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 2))), ValueError, "points"),
    (lambda: ps.linearize_point_edges(np.zeros((2, 3)), np.zeros((2, 2)), np.full((2, 2), np.inf)), ValueError,
     "measurements"),
    (lambda: ps.velocity_increments([1.0], [0.0, 1.0], [1.0], np.zeros((1, 2, 2))), ValueError, "w"),
    (lambda: ps.velocity_increments([1.0], [0.0], [np.nan], np.zeros((1, 2, 2))), ValueError, "dt"),
    (lambda: ps.velocity_increments([1.0], [0.0], [1.0], np.zeros((1, 3, 3))), ValueError, "control_noise"),
])
def test_bad_input_is_refused_by_name(call, error, name):
    with pytest.raises(error, match=name):
        call()


def test_no_edges_give_empty_arrays():
    error, d_from, d_to = ps.linearize_pose_edges(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)))
    assert error.shape == (0, 3) and d_from.shape == (0, 3, 3) and d_to.shape == (0, 3, 3)
