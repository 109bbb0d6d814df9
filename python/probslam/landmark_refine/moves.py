"""Step 3 of a round: sightings that another landmark explains better than their own move to it
(maximum likelihood), and sightings on no landmark join the most likely one within the gate."""

from __future__ import annotations

import collections
from typing import Dict, List, Tuple

import numpy as np

from .._core import joint_marginal_covariances, linearize_point_edges, marginal_covariances
from .merges import _GATE_BLOCK
from .problem import UNASSIGNED, _Graph, _Problem, _placed
from .results import Split
from .sightings import _SightingTests, _reassociation_distances


#: A sighting that passes its own landmark's test still moves to another landmark that explains
#: it better: when its likelihood there is more than this many times its likelihood on its own
#: (both under the posterior of all the other sightings). 1: maximum likelihood, as the filters
#: associate, no prior in favour of the filter's label (measured on the ten MRCLAM runs of three
#: filters: odds of 10 gained 2-5 points of correct sightings where maximum likelihood gained
#: 3-12; benchmarks/sweeps/landmark_refine.toml).
REASSOCIATION_ODDS = 1.0
REASSOCIATION_MARGIN = 2.0 * float(np.log(REASSOCIATION_ODDS))  # in -2 log likelihood


def _likelihood_moves(g: _Graph, problem: _Problem, tests: _SightingTests, gate: float,
                      iteration: int) -> List[Split]:
    """Sightings another landmark explains better than their own, each under the posterior of all
    the other sightings: the innovation against own has covariance S = Q M^-1 Q (M = Q - H Sigma
    H^T; its distance is the leave-one-out statistic), against a candidate S_c; a sighting moves
    when -2 log of the likelihood ratio, (d_own + ln det S_own) - (d_c + ln det S_c), exceeds
    REASSOCIATION_MARGIN and the candidate passes the split gate, best ratio first, never onto a
    landmark another sighting of its scan holds nor one it has left before. A sighting on no
    landmark (UNASSIGNED) joins the most likely landmark within the gate.

    Candidates are only the landmarks that can win: a winner has d_c below the gate and below
    the budget d_own + ln det S_own - ln det Q - margin (as S_c >= Q). With the leave-one-out
    shift of the pose delta_t, P = H Sigma H^T and W = M^-1, the candidate's innovation is at
    least |m_c - p| - |H_x delta_t| - sigma_c sqrt(lmax P) |W e| long (p: where the sighting
    lands, sigma_c: the root of the largest eigenvalue of c's marginal; Cauchy-Schwarz bounds its
    cross-covariance with the sighting's variables), and its covariance's largest eigenvalue at
    most (sigma_Q + sigma_x + sigma_c sqrt(1 + lmax P lmax W))^2 (Minkowski), so a landmark
    farther than that many standard deviations times the root of the bound cannot win. Exact,
    not a heuristic."""
    if len(g.labels) == 0:
        return []
    labelled_at = np.flatnonzero(tests.ok & (tests.stats[tests.rows] <= gate))
    lone = np.flatnonzero(problem.labels == UNASSIGNED)
    rows = np.concatenate([tests.rows[labelled_at], lone]).astype(np.int64)
    if len(rows) == 0:
        return []
    n_own = len(labelled_at)
    own_score, reach, per_sigma = _reach(g, problem, tests, labelled_at, rows, gate)
    own_queries, lone_queries = _near_landmarks(g, problem, rows, n_own, reach, per_sigma)
    scores: Dict[int, Tuple[float, int, float]] = {}  # sighting -> (score to beat, best candidate, its d2)
    _score_own(g, problem, tests, own_queries, dict(zip(rows[:n_own].tolist(), own_score)), gate, scores)
    _score_lone(g, problem, lone_queries, gate, scores)
    return _moves(problem, tests, scores, iteration)


def _reach(g: _Graph, problem: _Problem, tests: _SightingTests, labelled_at: np.ndarray, rows: np.ndarray,
           gate: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For sightings ``rows`` (the labelled ones, ``labelled_at`` of the tests, first): the score
    a candidate must beat (d_own + ln det S_own, labelled only), and the distance within which a
    candidate landmark can win, ``reach + per_sigma * sigma_c`` (see ``_likelihood_moves``)."""
    n_own = len(labelled_at)
    t = problem.pose_index[rows]
    q = problem.z_covariance[rows]
    # The posterior without the sighting: its pose's covariance and the shift of its mean.
    pose_cov = np.zeros((len(rows), 3, 3))
    if len(rows) > n_own:  # sightings on no landmark: their pose as the graph has it
        pose_cov[n_own:] = np.array(marginal_covariances(g.graph, [int(a) for a in t[n_own:]])).reshape(-1, 3, 3)
    shift_x = np.zeros((len(rows), 3))
    lmax_p, lmax_w, e_w = (np.zeros(len(rows)) for _ in range(3))
    if n_own:
        e, h, w = tests.e[labelled_at], tests.h[labelled_at], tests.inverse[labelled_at]
        joint = tests.joint[labelled_at]
        a_ = joint @ h.transpose(0, 2, 1)  # Sigma J^T (n, 5, 2)
        shift_x[:n_own] = np.einsum("nij,nj->ni", a_, np.einsum("nij,nj->ni", w, e))[:, :3]
        pose_cov[:n_own] = (joint + a_ @ w @ a_.transpose(0, 2, 1))[:, :3, :3]
        lmax_p[:n_own] = np.maximum(np.linalg.eigvalsh(h @ joint @ h.transpose(0, 2, 1))[:, -1], 0.0)
        lmax_w[:n_own] = np.linalg.eigvalsh(w)[:, -1]
        e_w[:n_own] = np.linalg.norm(np.einsum("nij,nj->ni", w, e), axis=1)
    _, hx, _ = linearize_point_edges(problem.poses[t], _placed(problem, rows), problem.z[rows])
    sigma_x = np.sqrt(np.maximum(np.linalg.eigvalsh(hx @ pose_cov @ hx.transpose(0, 2, 1))[:, -1], 0.0))
    sigma_q = np.sqrt(np.linalg.eigvalsh(q)[:, -1])
    # The distance a candidate must stay within: the gate, and for a labelled sighting the
    # likelihood to beat, d_c < d_own + ln det S_own - ln det S_c - margin with S_c >= Q.
    logdet_q = np.linalg.slogdet(q)[1]
    budget = np.full(len(rows), gate)
    own_score = np.empty(0)
    if n_own:
        own_score = tests.stats[rows[:n_own]] + 2.0 * logdet_q[:n_own] - \
            np.linalg.slogdet(tests.residual_cov[labelled_at])[1]
        budget[:n_own] = np.minimum(gate, own_score - logdet_q[:n_own] - REASSOCIATION_MARGIN)
    root = np.sqrt(np.maximum(budget, 0.0))
    reach = np.linalg.norm(np.einsum("nij,nj->ni", hx, shift_x), axis=1) + root * (sigma_q + sigma_x)
    per_sigma = np.sqrt(lmax_p) * e_w + root * np.sqrt(1.0 + lmax_p * lmax_w)
    reach[budget <= 0.0] = -np.inf  # nothing can beat its own landmark
    return own_score, reach, per_sigma


def _near_landmarks(g: _Graph, problem: _Problem, rows: np.ndarray, n_own: int, reach: np.ndarray,
                    per_sigma: np.ndarray) -> Tuple[List[Tuple[int, int]], List[Tuple[int, int]]]:
    """(sighting, label) pairs within reach, of the labelled sightings and of the lone ones."""
    marginal = g.landmark_marginals()
    sigma_c = np.sqrt(np.linalg.eigvalsh(marginal)[:, -1])
    marks = np.array([problem.landmarks[int(c)] for c in g.labels])
    placed = _placed(problem, rows)
    own_queries, lone_queries = [], []
    for start in range(0, len(rows), _GATE_BLOCK):
        block = slice(start, min(start + _GATE_BLOCK, len(rows)))
        dist = np.hypot(placed[block, None, 0] - marks[None, :, 0], placed[block, None, 1] - marks[None, :, 1])
        near = dist <= reach[block, None] + per_sigma[block, None] * sigma_c[None, :]
        near &= g.labels[None, :] != problem.labels[rows[block]][:, None]
        for n, c in zip(*np.nonzero(near)):
            (own_queries if start + n < n_own else lone_queries).append((int(rows[start + n]), int(g.labels[c])))
    return own_queries, lone_queries


def _score_own(g: _Graph, problem: _Problem, tests: _SightingTests, queries: List[Tuple[int, int]],
               own_score: Dict[int, float], gate: float, scores: Dict[int, Tuple[float, int, float]]) -> None:
    """Each labelled sighting's best candidate within the gate whose gain over its own landmark
    exceeds REASSOCIATION_MARGIN, into ``scores``."""
    if not queries:
        return
    d2, logdet = _reassociation_distances(g, problem, queries, tests)
    for (i, c), x, ld in zip(queries, d2, logdet):
        gain = own_score[i] - (x + ld)
        if c in problem.left[i]:
            continue
        if x <= gate and gain > REASSOCIATION_MARGIN and gain > scores.get(i, (-np.inf,))[0]:
            scores[i] = (float(gain), c, float(x))


def _score_lone(g: _Graph, problem: _Problem, queries: List[Tuple[int, int]], gate: float,
                scores: Dict[int, Tuple[float, int, float]]) -> None:
    """Each sighting on no landmark: its most likely candidate within the gate, into ``scores``."""
    if not queries:
        return
    joint = np.array(joint_marginal_covariances(g.graph, [[int(problem.pose_index[i]), g.point_id(c)]
                                                          for i, c in queries]))
    i_ = np.array([i for i, _ in queries])
    mk = np.array([problem.landmarks[c] for _, c in queries])
    e_c, j_pose, j_point = linearize_point_edges(problem.poses[problem.pose_index[i_]], mk, problem.z[i_])
    h = np.concatenate([j_pose, j_point], axis=2)
    s_c = problem.z_covariance[i_] + h @ joint @ h.transpose(0, 2, 1)
    d2 = np.einsum("ni,ni->n", e_c, np.linalg.solve(s_c, e_c[:, :, None])[:, :, 0])
    logdet = np.linalg.slogdet(s_c)[1]
    for (i, c), x, ld in zip(queries, d2, logdet):
        if c in problem.left[i]:
            continue
        if x <= gate and -(x + ld) > scores.get(i, (-np.inf,))[0]:
            scores[i] = (float(-(x + ld)), c, float(x))


def _moves(problem: _Problem, tests: _SightingTests, scores: Dict[int, Tuple[float, int, float]],
           iteration: int) -> List[Split]:
    """The moves, labelled sightings by their gain first, then the unassigned by likelihood, each
    onto a landmark no other sighting of its scan holds (as the earlier moves left them)."""
    scan_of = collections.defaultdict(set)
    for i in np.flatnonzero(problem.labels != UNASSIGNED):
        scan_of[int(problem.pose_index[i])].add(int(problem.labels[i]))
    moves = []
    order = sorted(scores, key=lambda i: (problem.labels[i] == UNASSIGNED, -scores[i][0], i))
    for i in order:
        _, c, x = scores[i]
        held = scan_of[int(problem.pose_index[i])]
        if c in held:
            continue
        old = int(problem.labels[i])
        held.discard(old)
        held.add(c)
        stat = float(tests.stats[i]) if old != UNASSIGNED else float("nan")
        moves.append(Split(iteration, int(i), old, c, stat, x, False, "likelihood"))
    return moves
