"""Dense numpy GraphSLAM (Tables 11.2-11.4 with the errata) and a dense Gauss-Newton on eq. 11.11
with finite-difference Jacobians: the independent references of the sparse C++ code."""

import numpy as np

from ekf_reference import motion, wrap


def simulate(steps=40, num_features=6, seed=0, signatures=False):
    """A robot on an arc among features, noisy range-bearing measurements of every feature
    within 8 m, headings kept inside (-pi/2, pi/2) so no residual wraps."""
    rng = np.random.default_rng(seed)
    controls = np.column_stack([np.full(steps, 1.0), np.full(steps, 0.03)])
    dt = np.full(steps, 0.5)
    x = np.zeros((steps + 1, 3))
    for t in range(steps):
        d, _, _ = motion(x[t], *controls[t], dt[t])
        x[t + 1] = x[t] + d + rng.normal(0, [0.02, 0.02, 0.005])
    feats = np.column_stack([rng.uniform(0, 20, num_features), rng.uniform(-3, 8, num_features)])
    time, z, corr = [], [], []
    for t in range(steps + 1):
        for j, m in enumerate(feats):
            delta = m - x[t, :2]
            r = np.hypot(*delta)
            if r < 8.0:
                phi = wrap(np.arctan2(delta[1], delta[0]) - x[t, 2])
                row = [r + rng.normal(0, 0.05), phi + rng.normal(0, 0.01)]
                if signatures:
                    row.append(float(j) + rng.normal(0, 0.1))
                time.append(t), z.append(row), corr.append(j)
    seen, corr = np.unique(corr, return_inverse=True)  # features never in range are dropped
    z = np.array(z)
    if signatures:
        z[:, 2] = corr + (z[:, 2] - np.array(seen)[corr])
    return controls, dt, (np.array(time), z, corr), x, feats[seen]


def measurement_jacobian(pose, m, d):
    delta = m[:2] - pose[:2]
    q = delta @ delta
    sq = np.sqrt(q)
    h = np.zeros((d, 3 + d))
    h[0, :5] = np.array([-sq * delta[0], -sq * delta[1], 0, sq * delta[0], sq * delta[1]]) / q
    h[1, :5] = np.array([delta[1], -delta[0], -q, -delta[1], delta[0]]) / q
    if d == 3:
        h[2, 5] = 1.0
    zhat = [sq, wrap(np.arctan2(delta[1], delta[0]) - pose[2])] + ([m[2]] if d == 3 else [])
    return np.array(zhat), h


def construct(controls, dt, meas, poses, features, R, Q):
    """Table 11.2 in dense form; x_0 anchored exactly (rows/columns cleared, Omega_00 = I)."""
    time, z, corr = meas
    T = len(controls)
    d = z.shape[1]
    n = features.shape[0]
    dim = 3 * (T + 1) + d * n
    omega = np.zeros((dim, dim))
    xi = np.zeros(dim)
    rinv, qinv = np.linalg.inv(R), np.linalg.inv(Q)
    for t in range(1, T + 1):
        dd, g, _ = motion(poses[t - 1], *controls[t - 1], dt[t - 1])
        xhat = poses[t - 1] + dd
        a = np.hstack([np.eye(3), -g])  # rows of (x_t, x_{t-1})
        idx = np.r_[3 * t:3 * t + 3, 3 * t - 3:3 * t]
        omega[np.ix_(idx, idx)] += a.T @ rinv @ a
        xi[idx] += a.T @ rinv @ (xhat - g @ poses[t - 1])
    for k in range(len(z)):
        t, j = time[k], corr[k]
        zhat, h = measurement_jacobian(poses[t], features[j], d)
        idx = np.r_[3 * t:3 * t + 3, 3 * (T + 1) + d * j:3 * (T + 1) + d * j + d]
        innovation = z[k] - zhat
        innovation[1] = wrap(innovation[1])
        omega[np.ix_(idx, idx)] += h.T @ qinv @ h
        xi[idx] += h.T @ qinv @ (innovation + h @ np.r_[poses[t], features[j]])
    x0 = poses[0]
    xi -= omega[:, :3] @ x0
    omega[:3, :] = 0
    omega[:, :3] = 0
    omega[:3, :3] = np.eye(3)
    xi[:3] = x0
    return omega, xi


def residuals(y, controls, dt, meas, T, d, R, Q):
    """Whitened residuals of eq. 11.11 (x_0 held at y[:3])."""
    time, z, corr = meas
    poses = y[:3 * (T + 1)].reshape(T + 1, 3)
    feats = y[3 * (T + 1):].reshape(-1, d)
    lr, lq = np.linalg.cholesky(np.linalg.inv(R)), np.linalg.cholesky(np.linalg.inv(Q))
    out = []
    for t in range(1, T + 1):
        dd, _, _ = motion(poses[t - 1], *controls[t - 1], dt[t - 1])
        r = poses[t - 1] + dd - poses[t]
        r[2] = wrap(r[2])
        out.append(lr.T @ r)
    for k in range(len(z)):
        zhat, _ = measurement_jacobian(poses[time[k]], feats[corr[k]], d)
        r = z[k] - zhat
        r[1] = wrap(r[1])
        out.append(lq.T @ r)
    return np.concatenate(out)


def dense_gauss_newton(y0, controls, dt, meas, R, Q, iterations=15, eps=1e-6):
    """Minimises eq. 11.11 over every coordinate but x_0, Jacobians by central differences."""
    T = len(controls)
    d = meas[1].shape[1]
    y = y0.copy()
    for _ in range(iterations):
        r = residuals(y, controls, dt, meas, T, d, R, Q)
        jac = np.zeros((r.size, y.size - 3))
        for i in range(3, y.size):
            e = np.zeros_like(y)
            e[i] = eps
            jac[:, i - 3] = (residuals(y + e, controls, dt, meas, T, d, R, Q)
                             - residuals(y - e, controls, dt, meas, T, d, R, Q)) / (2 * eps)
        step = np.linalg.lstsq(jac, -r, rcond=None)[0]
        y[3:] += step
        if np.abs(step).max() < 1e-11:
            break
    return y
