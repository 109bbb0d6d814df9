"""Independent references for the grid updates: a dense numpy Table 9.1/9.2 over all cells, and
a pure-Python laser-beam update with its own cell walk. Deliberately simple, not fast."""

import math

import numpy as np


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def ism_numpy(cells, pose, ranges, angles, z_max, alpha, beta, l0, l_occ, l_free):
    """Table 9.2 (line 8 corrected) for every row of cells (n, 2), by brute force over beams."""
    cells = np.atleast_2d(cells)
    x, y, th = pose
    dx, dy = cells[:, 0] - x, cells[:, 1] - y
    r = np.sqrt(dx * dx + dy * dy)
    phi = np.arctan2(dy, dx) - th
    ranges = np.asarray(ranges, float)
    valid = np.isfinite(ranges) & (ranges >= 0)
    d = np.abs(wrap(phi[:, None] - np.asarray(angles)[None, :]))
    d[:, ~valid] = np.inf
    k = np.argmin(d, axis=1)  # lowest index on ties
    zk = ranges[k]
    dk = d[np.arange(len(k)), k]
    out = np.full(len(cells), l0, float)
    outside = ~valid.any() | (r > np.minimum(z_max, zk + alpha / 2)) | (dk > beta / 2)
    occ = ~outside & (zk < z_max) & (np.abs(r - zk) < alpha / 2)
    free = ~outside & ~occ & (r <= zk)
    out[occ] = l_occ
    out[free] = l_free
    return out


def cell_centres(origin, res, height, width):
    cols = origin[0] + (np.arange(width) + 0.5) * res
    rows = origin[1] + (np.arange(height) + 0.5) * res
    xx, yy = np.meshgrid(cols, rows)
    return np.column_stack([xx.ravel(), yy.ravel()])


def cone_update(log_odds, origin, res, pose, ranges, angles, z_max, alpha, beta, l0, l_occ, l_free):
    """Table 9.1 over all cells: l += ism - l0."""
    h, w = log_odds.shape
    ism = ism_numpy(cell_centres(origin, res, h, w), pose, ranges, angles, z_max, alpha, beta, l0, l_occ, l_free)
    return log_odds + (ism - l0).reshape(h, w)


def walk(origin, end, x0, y0, res):
    """Cells (col, row) from origin's cell (included) to end's cell (excluded), Amanatides-Woo."""
    inv = 1.0 / res  # the grid's key is floor((c - c0) * (1 / res))
    key = [math.floor((origin[0] - x0) * inv), math.floor((origin[1] - y0) * inv)]
    key_end = [math.floor((end[0] - x0) * inv), math.floor((end[1] - y0) * inv)]
    if key == key_end:
        return []
    cells = [tuple(key)]
    direction = [end[0] - origin[0], end[1] - origin[1]]
    length = math.hypot(*direction)
    direction = [d / length for d in direction]
    step, t_max, t_delta = [0, 0], [math.inf, math.inf], [math.inf, math.inf]
    base = (x0, y0)
    for i in range(2):
        if direction[i] != 0:
            step[i] = 1 if direction[i] > 0 else -1
            border = base[i] + (key[i] + 0.5) * res + step[i] * res * 0.5
            t_max[i] = (border - origin[i]) / direction[i]
            t_delta[i] = res / abs(direction[i])
    while True:
        dim = 0 if t_max[0] < t_max[1] else 1
        key[dim] += step[dim]
        t_max[dim] += t_delta[dim]
        if key == key_end or min(t_max) > length:
            return cells
        cells.append(tuple(key))


def rays_update(log_odds, origin, res, pose, ranges, angles, max_range, p_hit=0.7, p_miss=0.4, l0=0.0,
                clamp=None):
    """OctoMap's per-scan rules on a bounded 2-D grid: misses along each ray, hits at the ends
    of readings < max_range, each cell once per scan, hit beats miss."""
    log_odds = log_odds.copy()
    h, w = log_odds.shape
    hits, misses = set(), set()
    for r, a in zip(ranges, angles):
        if not (math.isfinite(r) and r >= 0):
            continue
        length = r if r < max_range else max_range
        b = pose[2] + a
        end = (pose[0] + length * math.cos(b), pose[1] + length * math.sin(b))
        misses.update(walk(pose, end, origin[0], origin[1], res))
        if r < max_range:
            hits.add((math.floor((end[0] - origin[0]) * (1.0 / res)), math.floor((end[1] - origin[1]) * (1.0 / res))))
    lh = math.log(p_hit / (1 - p_hit)) - l0
    lm = math.log(p_miss / (1 - p_miss)) - l0
    for cells, delta in ((hits, lh), (misses - hits, lm)):
        for c, r in cells:
            if 0 <= r < h and 0 <= c < w:
                v = log_odds[r, c] + delta
                if clamp is not None:
                    v = min(max(v, clamp[0]), clamp[1])
                log_odds[r, c] = v
    return log_odds
