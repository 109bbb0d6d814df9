"""A dense numpy EKF SLAM (Table 10.1 with the errata): full-width H and K, (I - K H) Sigma,
sequential measurements, state augmentation for new landmarks. The independent reference."""

import numpy as np

from reference import wrap  # noqa: F401 (used below and by the tests that import it from here)


def motion(x, v, w, dt):
    th = x[2]
    if abs(w) > 1e-9:  # eq. 10.11 and Table 10.1 line 4 (signs corrected)
        d = np.array([-v / w * np.sin(th) + v / w * np.sin(th + w * dt),
                      v / w * np.cos(th) - v / w * np.cos(th + w * dt), w * dt])
        g = np.array([[0, 0, -v / w * np.cos(th) + v / w * np.cos(th + w * dt)],
                      [0, 0, -v / w * np.sin(th) + v / w * np.sin(th + w * dt)], [0, 0, 0]])
        dv = np.array([[(-np.sin(th) + np.sin(th + w * dt)) / w, 0], [(np.cos(th) - np.cos(th + w * dt)) / w, 0],
                       [0, dt]])
        dv[0, 1] = v * (np.sin(th) - np.sin(th + w * dt)) / w ** 2 + v * np.cos(th + w * dt) * dt / w
        dv[1, 1] = -v * (np.cos(th) - np.cos(th + w * dt)) / w ** 2 + v * np.sin(th + w * dt) * dt / w
    else:
        d = np.array([v * dt * np.cos(th), v * dt * np.sin(th), 0.0])
        g = np.array([[0, 0, -v * dt * np.sin(th)], [0, 0, v * dt * np.cos(th)], [0, 0, 0]])
        # the straight-line limit of the arc's derivatives (w -> 0)
        dv = np.array([[dt * np.cos(th), -v * dt * dt * np.sin(th) / 2],
                       [dt * np.sin(th), v * dt * dt * np.cos(th) / 2], [0, dt]])
    return d, np.eye(3) + g, dv


def full_state(ekf):
    """The filter's mean and covariance in the full state's layout (x, y, theta, then each
    landmark's x, y[, signature]): with signatures, each landmark's signature mean and variance
    (kept apart by the filter) put back in its place, its cross covariances zero."""
    if not ekf.use_signatures:
        return np.array(ekf.mean), np.array(ekf.covariance)
    n = ekf.num_landmarks
    dense = np.r_[0, 1, 2, (3 + 3 * np.arange(n)[:, None] + np.arange(2)).ravel()]
    mean, cov = np.zeros(3 + 3 * n), np.zeros((3 + 3 * n, 3 + 3 * n))
    mean[dense] = ekf.mean
    cov[np.ix_(dense, dense)] = ekf.covariance
    sig = 5 + 3 * np.arange(n)
    mean[sig], cov[sig, sig] = ekf.signatures.T
    return mean, cov


class DenseEkfSlam:
    def __init__(self, motion_noise, q, signatures, pose=(0, 0, 0), pose_cov=None):
        self.m = np.asarray(motion_noise, float)
        self.q = np.asarray(q, float)
        self.ld = 3 if signatures else 2
        self.mu = np.array(pose, float)
        self.sigma = np.zeros((3, 3)) if pose_cov is None else np.array(pose_cov, float)
        self.ids = []

    def predict(self, v, w, dt):
        d, g3, dv = motion(self.mu, v, w, dt)
        n = len(self.mu)
        fx = np.zeros((3, n))
        fx[:, :3] = np.eye(3)
        r = dv @ self.m @ dv.T if self.m.shape == (2, 2) else self.m
        g = np.eye(n) + fx.T @ (g3 - np.eye(3)) @ fx
        self.mu = self.mu + fx.T @ d
        self.mu[2] = wrap(self.mu[2])
        self.sigma = g @ self.sigma @ g.T + fx.T @ r @ fx

    def predict_odometry(self, delta, noise):
        """x <- x (+) delta, delta (3,) with covariance noise (3, 3) in the robot's frame."""
        th = self.mu[2]
        rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        t = rot @ np.asarray(delta[:2], float)
        n = len(self.mu)
        g = np.eye(n)
        g[0, 2], g[1, 2] = -t[1], t[0]
        j = np.eye(3)
        j[:2, :2] = rot
        self.mu[:3] = [self.mu[0] + t[0], self.mu[1] + t[1], wrap(th + delta[2])]
        self.sigma = g @ self.sigma @ g.T
        self.sigma[:3, :3] += j @ np.asarray(noise, float) @ j.T

    def update(self, z, ids):
        for zi, j in zip(np.atleast_2d(z), np.atleast_1d(ids)):
            if j not in self.ids:
                self._augment(zi, j)
                continue
            k0 = 3 + self.ld * self.ids.index(j)
            x, m = self.mu[:3], self.mu[k0:k0 + self.ld]
            dx, dy = m[0] - x[0], m[1] - x[1]
            q = dx * dx + dy * dy
            sq = np.sqrt(q)
            h = np.zeros((self.ld, len(self.mu)))
            h[0, [0, 1, k0, k0 + 1]] = [-dx / sq, -dy / sq, dx / sq, dy / sq]
            h[1, [0, 1, 2, k0, k0 + 1]] = [dy / q, -dx / q, -1, -dy / q, dx / q]
            z_hat = [sq, wrap(np.arctan2(dy, dx) - x[2])]
            if self.ld == 3:
                h[2, k0 + 2] = 1
                z_hat.append(m[2])
            nu = zi - np.array(z_hat)
            nu[1] = wrap(nu[1])
            s = h @ self.sigma @ h.T + self.q
            k = self.sigma @ h.T @ np.linalg.inv(s)
            self.mu = self.mu + k @ nu
            self.mu[2] = wrap(self.mu[2])
            self.sigma = (np.eye(len(self.mu)) - k @ h) @ self.sigma

    def _augment(self, z, j):
        x = self.mu[:3]
        a = z[1] + x[2]
        m = [x[0] + z[0] * np.cos(a), x[1] + z[0] * np.sin(a)] + ([z[2]] if self.ld == 3 else [])
        gx = np.zeros((self.ld, len(self.mu)))
        gx[:2, :3] = [[1, 0, -z[0] * np.sin(a)], [0, 1, z[0] * np.cos(a)]]
        gz = np.zeros((self.ld, self.ld))
        gz[:2, :2] = [[np.cos(a), -z[0] * np.sin(a)], [np.sin(a), z[0] * np.cos(a)]]
        if self.ld == 3:
            gz[2, 2] = 1
        top = np.hstack([self.sigma, self.sigma @ gx.T])
        bottom = np.hstack([gx @ self.sigma, gx @ self.sigma @ gx.T + gz @ self.q @ gz.T])
        self.sigma = np.vstack([top, bottom])
        self.mu = np.concatenate([self.mu, m])
        self.ids.append(j)


def measurement_rows(mu, ld, index, q_dim):
    """Predicted measurement (q_dim,) and dense Jacobian (q_dim, D) of landmark `index` (state order)."""
    k0 = 3 + ld * index
    dx, dy = mu[k0] - mu[0], mu[k0 + 1] - mu[1]
    q = dx * dx + dy * dy
    sq = np.sqrt(q)
    z_hat = np.array([sq, wrap(np.arctan2(dy, dx) - mu[2])] + ([mu[k0 + 2]] if q_dim == 3 else []))
    h = np.zeros((q_dim, len(mu)))
    h[0, [0, 1, k0, k0 + 1]] = np.array([-dx, -dy, dx, dy]) / sq
    h[1, [0, 1, 2, k0, k0 + 1]] = np.array([dy, -dx, -q, -dy, dx]) / q
    if q_dim == 3:
        h[2, k0 + 2] = 1.0
    return z_hat, h


def joint_compatibility_brute_force(z, mu, sigma, q, ld, alpha):
    """Every assignment of the scan's measurements to landmarks (state order) or to nothing,
    each landmark at most once, every pairing individually compatible (pi <= alpha) and every
    leading part, in measurement order, jointly compatible (joint NIS of its n pairings within the
    chi-square quantile with n * dof at alpha's probability). Returns the one with the most
    pairings, then the smallest joint NIS: (targets per measurement or -1, joint NIS, pi (k, N))."""
    from scipy.stats import chi2

    z = np.atleast_2d(z)
    k, m = z.shape
    n_lm = (len(mu) - 3) // ld
    rows = [measurement_rows(mu, ld, j, m) for j in range(n_lm)]
    nu = np.empty((k, n_lm, m))
    pi = np.empty((k, n_lm))
    for i in range(k):
        for j, (z_hat, h) in enumerate(rows):
            nu[i, j] = z[i] - z_hat
            nu[i, j, 1] = wrap(nu[i, j, 1])
            pi[i, j] = nu[i, j] @ np.linalg.solve(h @ sigma @ h.T + q, nu[i, j])
    p = chi2.cdf(alpha, m)

    def joint_nis(pairs):
        h = np.vstack([rows[j][1] for _, j in pairs])
        v = np.concatenate([nu[i, j] for i, j in pairs])
        s = h @ sigma @ h.T + np.kron(np.eye(len(pairs)), q)
        return float(v @ np.linalg.solve(s, v))

    best = [(), 0.0]

    def visit(i, pairs):
        if pairs and joint_nis(pairs) > chi2.ppf(p, m * len(pairs)):
            return  # not jointly compatible: nothing extending it is admissible
        if i == k:
            nis = joint_nis(pairs) if pairs else 0.0
            if len(pairs) > len(best[0]) or (len(pairs) == len(best[0]) and nis < best[1]):
                best[0], best[1] = tuple(pairs), nis
            return
        used = {j for _, j in pairs}
        for j in range(n_lm):
            if pi[i, j] <= alpha and j not in used:
                visit(i + 1, pairs + [(i, j)])
        visit(i + 1, pairs)

    visit(0, [])
    target = -np.ones(k, dtype=np.int64)
    for i, j in best[0]:
        target[i] = j
    return target, best[1], pi
