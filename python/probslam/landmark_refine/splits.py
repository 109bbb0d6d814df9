"""Step 2 of a round, the undo of ch. 11.6: sightings beyond the split gate leave their landmark
by backward elimination and go to the most likely other landmark, a new one, or none."""

from __future__ import annotations

from typing import List, Tuple

import numpy as np

from .._core import joint_marginal_covariances, linearize_point_edges
from .problem import UNASSIGNED, _Graph, _Problem
from .results import Split
from .sightings import LEAVE_ONE_OUT_RANK_TOLERANCE, _SightingTests

#: At most this many sightings beyond the split gate (the worst) are taken up per round; the
#: rest wait for the next. It bounds the round's dense posterior of the suspects' poses and the
#: landmarks (3 per pose plus 2 per landmark, squared) and its sequential updates.
MAX_SUSPECTS_PER_ROUND = 256


def _split_moves(g: _Graph, problem: _Problem, tests: _SightingTests, gate: float, next_label: int,
                 iteration: int, new_landmarks: bool) -> List[Split]:
    """The undo of ch. 11.6, as a backward elimination on the linearised posterior: among the
    sightings beyond the split gate (the suspects), the worst leaves; the posterior without it is
    updated exactly (Woodbury: the mean moves by Sigma J^T W e, the covariance by + Sigma J^T W J
    Sigma, W = (Q - J Sigma J^T)^-1), the other suspects' leave-one-out statistics are computed
    again, and the next worst leaves, until no suspect exceeds the gate. A gross error bends the
    path and pushes innocent sightings over the gate; they are acquitted once it has left. Each
    sighting that left then goes, worst first, to the most likely landmark (smallest d + ln det S,
    innovation covariance S = Q + H Sigma' H^T under the posterior without the round's leavers)
    within the gate that no other sighting of its scan holds and that it has not left before (a
    sighting that left a landmark never returns: the moves cannot cycle, and a move decided on
    one linearisation is not undone on the next by a statistic a little over the gate), else to a
    new landmark of its own (``new_landmarks``) or to none (UNASSIGNED)."""
    stats = tests.stats
    suspects = [int(i) for i in np.argsort(-np.nan_to_num(stats, nan=-np.inf), kind="stable") if stats[i] > gate]
    suspects = np.array(suspects[:MAX_SUSPECTS_PER_ROUND], dtype=np.int64)
    if not len(suspects):
        return []
    posterior = _Posterior(g, problem, suspects)
    left = _eliminate(posterior, g, problem, tests, suspects, gate)
    return _destinations(posterior, g, problem, left, gate, next_label, iteration, new_landmarks)


class _Posterior:
    """One dense joint posterior of the suspects' poses and every landmark, and its updates as
    sightings leave: the posterior without the leavers is sigma + B A^T, one rank-2 term (a W, a)
    per leaver, kept as factors, so each leaver costs O(n * leavers) for the blocks read, not
    O(n^2); its mean moves by ``delta``."""

    def __init__(self, g: _Graph, problem: _Problem, suspects: np.ndarray):
        poses = sorted({int(problem.pose_index[i]) for i in suspects})
        ids = poses + [g.point_id(c) for c in g.labels]
        self.start, offset = {}, 0
        for v in ids:
            self.start[v] = offset
            offset += 3 if v < g.num_poses else 2
        self.sigma = np.array(joint_marginal_covariances(g.graph, [ids])[0])
        self.delta = np.zeros(offset)
        self.factor_a, self.factor_b = np.zeros((offset, 2 * len(suspects))), np.zeros((offset, 2 * len(suspects)))
        self.used = 0
        self.landmark_start = np.array([self.start[g.point_id(c)] for c in g.labels], dtype=np.int64)
        self.landmark_rows = self.landmark_start[:, None] + np.arange(2)
        self._landmark_terms = None  # the leavers' terms of each landmark's block, once they have left

    def columns(self, pose: np.ndarray, landmark: np.ndarray) -> np.ndarray:
        """(n, 5) the dense posterior's columns of (pose, landmark) pairs (pose ids, label slots)."""
        p = np.array([self.start[int(x)] for x in pose], dtype=np.int64)
        return np.column_stack([p, p + 1, p + 2, self.landmark_start[landmark], self.landmark_start[landmark] + 1])

    def remove(self, cols: np.ndarray, h: np.ndarray, w: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Takes out the sighting of Jacobian ``h`` over columns ``cols``, with W = ``w`` and
        innovation ``v`` (Woodbury); returns its new rank-2 term's columns, (n, 2) each factor."""
        used = self.used
        a = (self.sigma[:, cols] + self.factor_b[:, :used] @ self.factor_a[cols, :used].T) @ h.T
        self.delta += a @ (w @ v)
        self.factor_a[:, used:used + 2], self.factor_b[:, used:used + 2] = a, a @ w
        self.used += 2
        self._landmark_terms = None
        return self.factor_a[:, used:used + 2], self.factor_b[:, used:used + 2]

    def pose_landmark_blocks(self, pose: int, free: np.ndarray) -> np.ndarray:
        """(n, 5, 5) the posterior without the leavers over (pose, landmark slot) for slots ``free``."""
        used, fa, fb, landmark_rows = self.used, self.factor_a, self.factor_b, self.landmark_rows
        if self._landmark_terms is None:
            self._landmark_terms = fb[landmark_rows, :used] @ fa[landmark_rows, :used].transpose(0, 2, 1)
        p, rows = self.start[pose] + np.arange(3), landmark_rows[free].ravel()
        k = np.column_stack([np.broadcast_to(p, (len(free), 3)), landmark_rows[free]])
        out = self.sigma[k[:, :, None], k[:, None, :]]
        out[:, :3, :3] += fb[p, :used] @ fa[p, :used].T
        out[:, :3, 3:] += (fb[p, :used] @ fa[rows, :used].T).reshape(3, -1, 2).transpose(1, 0, 2)
        out[:, 3:, :3] += (fb[rows, :used] @ fa[p, :used].T).reshape(-1, 2, 3)
        out[:, 3:, 3:] += self._landmark_terms[free]
        return out


def _eliminate(posterior: _Posterior, g: _Graph, problem: _Problem, tests: _SightingTests, suspects: np.ndarray,
               gate: float) -> List[Tuple[int, float]]:
    """The backward elimination: (sighting, statistic) of each suspect that left, worst first,
    its statistic under the posterior without the ones before it."""
    at = np.searchsorted(tests.rows, suspects)
    cols = posterior.columns(problem.pose_index[suspects], np.searchsorted(g.labels, problem.labels[suspects]))
    h_all, e_all = tests.h[at], tests.e[at]
    q_all = problem.z_covariance[suspects]
    scale = np.linalg.eigvalsh(q_all)[:, -1]
    remaining = np.ones(len(suspects), bool)
    left = []
    # Each suspect's (pose, landmark) block of the posterior, the leavers' terms added as they leave.
    suspect_blocks = posterior.sigma[cols[:, :, None], cols[:, None, :]]
    while remaining.any():
        # Every remaining suspect's leave-one-out statistic under the posterior without the leavers.
        r = np.flatnonzero(remaining)
        h, c = h_all[r], cols[r]
        v = e_all[r] + np.einsum("nij,nj->ni", h, posterior.delta[c])
        m = q_all[r] - h @ suspect_blocks[r] @ h.transpose(0, 2, 1)
        m = 0.5 * (m + m.transpose(0, 2, 1))
        testable = np.linalg.eigvalsh(m)[:, 0] > LEAVE_ONE_OUT_RANK_TOLERANCE * scale[r]
        remaining[r[~testable]] = False  # its landmark now rests on it alone: not testable
        r, v, m = r[testable], v[testable], m[testable]
        if len(r) == 0:
            break
        x = np.einsum("ni,ni->n", v, np.linalg.solve(m, v[:, :, None])[:, :, 0])
        worst = int(np.argmax(x))
        if not x[worst] > gate:
            break
        best = int(r[worst])
        remaining[best] = False
        left.append((int(suspects[best]), float(x[worst])))
        a, b = posterior.remove(cols[best], h_all[best], np.linalg.inv(m[worst]), v[worst])
        suspect_blocks += b[cols] @ a[cols].transpose(0, 2, 1)
    return left


def _destinations(posterior: _Posterior, g: _Graph, problem: _Problem, left: List[Tuple[int, float]], gate: float,
                  next_label: int, iteration: int, new_landmarks: bool) -> List[Split]:
    """Where each sighting that left goes, worst first: the most likely landmark within the gate
    under the posterior without the round's leavers that its scan does not hold and it has not
    left before, else a new landmark (``new_landmarks``) or none."""
    by_pose = np.argsort(problem.pose_index, kind="stable")
    bounds = np.searchsorted(problem.pose_index[by_pose], np.arange(len(problem.poses) + 1))
    labels = problem.labels.copy()
    moves = []
    slots = np.arange(len(g.labels))
    all_marks = np.array([problem.landmarks[int(c)] for c in g.labels])
    for i, stat in left:
        t = int(problem.pose_index[i])
        scan = by_pose[bounds[t]:bounds[t + 1]]
        held = set(labels[scan[scan != i]].tolist())
        excluded = held | problem.left[i] | {int(problem.labels[i])}
        free = slots[~np.isin(g.labels, np.array(sorted(excluded), dtype=np.int64))]
        options = []
        if len(free):
            e, j_pose, j_point = linearize_point_edges(np.repeat(problem.poses[t][None], len(free), 0),
                                                       all_marks[free], np.repeat(problem.z[i][None], len(free), 0))
            h = np.concatenate([j_pose, j_point], axis=2)
            k = posterior.columns(np.full(len(free), t), free)
            v = e + np.einsum("nij,nj->ni", h, posterior.delta[k])
            cov = problem.z_covariance[i][None] + h @ posterior.pose_landmark_blocks(t, free) @ h.transpose(0, 2, 1)
            x = np.einsum("ni,ni->n", v, np.linalg.solve(cov, v[:, :, None])[:, :, 0])
            within = np.flatnonzero(x <= gate)
            options = [(float(y), float(d), int(c)) for y, d, c in
                       zip(x[within] + np.linalg.slogdet(cov[within])[1], x[within], g.labels[free][within])]
        old = int(labels[i])
        if options:
            _, new_d2, new = min(options)
            created = False
        elif new_landmarks:
            new, created, new_d2 = next_label, True, float("nan")
            next_label += 1
        else:
            new, created, new_d2 = UNASSIGNED, False, float("nan")
        labels[i] = new
        moves.append(Split(iteration, i, old, new, stat, new_d2, created, "gate"))
    return moves
