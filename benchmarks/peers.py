"""Plain-Python and numpy implementations of the 2-D grid updates, the peers of the benchmarks."""

import math

import numpy as np


def python_rays(log_odds, x0, y0, res, pose, ranges, angles, max_range, l_hit, l_miss):
    """Laser-beam update in plain Python: an integer DDA per beam, each cell once per scan."""
    h, w = log_odds.shape
    hits, misses = set(), set()
    px, py, th = pose
    cx0, cy0 = int(math.floor((px - x0) / res)), int(math.floor((py - y0) / res))
    for r, a in zip(ranges, angles):
        if not (r >= 0 and math.isfinite(r)):
            continue
        length = min(r, max_range)
        ex, ey = px + length * math.cos(th + a), py + length * math.sin(th + a)
        kx, ky = cx0, cy0
        tx_end, ty_end = int(math.floor((ex - x0) / res)), int(math.floor((ey - y0) / res))
        dx, dy = ex - px, ey - py
        sx, sy = (1 if dx > 0 else -1), (1 if dy > 0 else -1)
        tmx = ((x0 + (kx + (sx > 0)) * res) - px) / dx if dx else math.inf
        tmy = ((y0 + (ky + (sy > 0)) * res) - py) / dy if dy else math.inf
        tdx, tdy = (res / abs(dx) if dx else math.inf), (res / abs(dy) if dy else math.inf)
        while (kx, ky) != (tx_end, ty_end) and min(tmx, tmy) <= 1.0:
            misses.add((kx, ky))
            if tmx < tmy:
                kx += sx
                tmx += tdx
            else:
                ky += sy
                tmy += tdy
        if r < max_range:
            hits.add((tx_end, ty_end))
    for cells, delta in ((hits, l_hit), (misses - hits, l_miss)):
        for kx, ky in cells:
            if 0 <= kx < w and 0 <= ky < h:
                log_odds[ky, kx] += delta
    return len(hits) + len(misses - hits)


def numpy_rays(log_odds, x0, y0, res, pose, ranges, angles, max_range, l_hit, l_miss):
    """Laser-beam update vectorised with numpy: rays sampled every res/2 (an approximation of
    the exact walk), cells de-duplicated per scan, hits winning over misses."""
    h, w = log_odds.shape
    ok = np.isfinite(ranges) & (ranges >= 0)
    r, a = ranges[ok], angles[ok] + pose[2]
    length = np.minimum(r, max_range)
    steps = np.arange(0.0, length.max(), res / 2)
    t = steps[None, :]
    inside = t < length[:, None]
    xs = (pose[0] + t * np.cos(a)[:, None])[inside]
    ys = (pose[1] + t * np.sin(a)[:, None])[inside]
    miss = np.unique(np.floor((ys - y0) / res).astype(np.int64) * w + np.floor((xs - x0) / res).astype(np.int64))
    is_hit = r < max_range
    hx = pose[0] + r[is_hit] * np.cos(a[is_hit])
    hy = pose[1] + r[is_hit] * np.sin(a[is_hit])
    hit = np.unique(np.floor((hy - y0) / res).astype(np.int64) * w + np.floor((hx - x0) / res).astype(np.int64))
    miss = np.setdiff1d(miss, hit, assume_unique=True)
    flat = log_odds.reshape(-1)
    for cells, delta in ((hit, l_hit), (miss, l_miss)):
        cells = cells[(cells >= 0) & (cells < h * w)]
        flat[cells] += delta
    return len(hit) + len(miss)


def numpy_cone(log_odds, x0, y0, res, pose, ranges, angles, z_max, alpha, beta, l_occ, l_free):
    """Table 9.1/9.2 vectorised with numpy over the cells of the disc's bounding box, the
    nearest beam found by searchsorted (beam angles sorted)."""
    h, w = log_odds.shape
    c0, c1 = max(0, int((pose[0] - z_max - x0) / res)), min(w, int((pose[0] + z_max - x0) / res) + 1)
    r0, r1 = max(0, int((pose[1] - z_max - y0) / res)), min(h, int((pose[1] + z_max - y0) / res) + 1)
    cx = x0 + (np.arange(c0, c1) + 0.5) * res - pose[0]
    cy = y0 + (np.arange(r0, r1) + 0.5) * res - pose[1]
    dx, dy = np.meshgrid(cx, cy)
    r = np.sqrt(dx * dx + dy * dy)
    phi = (np.arctan2(dy, dx) - pose[2] + np.pi) % (2 * np.pi) - np.pi
    hi = np.clip(np.searchsorted(angles, phi), 1, len(angles) - 1)
    k = np.where(np.abs(phi - angles[hi - 1]) <= np.abs(phi - angles[hi]), hi - 1, hi)
    zk = ranges[k]
    d = np.abs(phi - angles[k])
    out = ~((r > np.minimum(z_max, zk + alpha / 2)) | (d > beta / 2))
    occ = out & (zk < z_max) & (np.abs(r - zk) < alpha / 2)
    free = out & ~occ & (r <= zk)
    block = log_odds[r0:r1, c0:c1]
    block[occ] += l_occ
    block[free] += l_free
    return int(occ.sum() + free.sum())


def dense_ekf_predict(mu, sigma, v, w, dt, r):
    """Table 10.1 lines 2-5 with full matrices: G is (3N+3) x (3N+3)."""
    n = len(mu)
    th = mu[2]
    fx = np.zeros((3, n))
    fx[:, :3] = np.eye(3)
    d = np.array([-v / w * np.sin(th) + v / w * np.sin(th + w * dt), v / w * np.cos(th) - v / w * np.cos(th + w * dt),
                  w * dt])
    g3 = np.array([[0, 0, -v / w * np.cos(th) + v / w * np.cos(th + w * dt)],
                   [0, 0, -v / w * np.sin(th) + v / w * np.sin(th + w * dt)], [0, 0, 0]])
    g = np.eye(n) + fx.T @ g3 @ fx
    return mu + fx.T @ d, g @ sigma @ g.T + fx.T @ r @ fx


def dense_ekf_update(mu, sigma, z, j, q):
    """Table 10.1 lines 12-20 for one measurement of landmark j, with full-width H and K."""
    n = len(mu)
    k0 = 3 + 2 * j
    dx, dy = mu[k0] - mu[0], mu[k0 + 1] - mu[1]
    qq = dx * dx + dy * dy
    s = np.sqrt(qq)
    h = np.zeros((2, n))
    h[0, [0, 1, k0, k0 + 1]] = [-dx / s, -dy / s, dx / s, dy / s]
    h[1, [0, 1, 2, k0, k0 + 1]] = [dy / qq, -dx / qq, -1, -dy / qq, dx / qq]
    nu = z - np.array([s, np.arctan2(dy, dx) - mu[2]])
    nu[1] = (nu[1] + np.pi) % (2 * np.pi) - np.pi
    k = sigma @ h.T @ np.linalg.inv(h @ sigma @ h.T + q)
    return mu + k @ nu, (np.eye(n) - k @ h) @ sigma
