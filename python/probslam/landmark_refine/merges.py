"""Step 1 of a round, Table 11.8: landmark pairs tested for identity with the full posterior,
and the groups of mutually passing labels that merge."""

from __future__ import annotations

import collections
from typing import Dict, List, Tuple

import numpy as np

from .._core import joint_marginal_covariances
from .problem import UNASSIGNED, _Graph, _Problem


def _co_observed(problem: _Problem) -> set:
    """Label pairs (a, b), a < b, that share a scan (a pose): never one landmark."""
    by_pose: Dict[int, set] = collections.defaultdict(set)
    for i in np.flatnonzero(problem.labels != UNASSIGNED):
        by_pose[int(problem.pose_index[i])].add(int(problem.labels[i]))
    pairs = set()
    for labels in by_pose.values():
        if len(labels) > 1:
            ordered = sorted(labels)
            pairs.update((a, b) for k, a in enumerate(ordered) for b in ordered[k + 1:])
    return pairs


#: Landmarks compared per block of the spatial gate (bounds its memory: 512 x N distances).
_GATE_BLOCK = 512


def _candidate_pairs(g: _Graph, problem: _Problem, gate: float, excluded: set) -> List[Tuple[int, int]]:
    """Pairs of labels that can pass the merge test. Delta = m_a - m_b has, along any direction,
    a standard deviation at most s_a + s_b (s: the square root of the largest eigenvalue of each
    landmark's marginal; Minkowski's inequality holds whatever their correlation), so its squared
    Mahalanobis distance is at least |mu_Delta|^2 / (s_a + s_b)^2: a pair farther apart than
    sqrt(gate) (s_a + s_b) cannot pass and is not tested. Exact, not a heuristic."""
    labels = g.labels
    if len(labels) < 2:
        return []
    cov = g.landmark_marginals()
    s = np.sqrt(np.linalg.eigvalsh(cov)[:, -1])
    m = np.array([problem.landmarks[int(x)] for x in labels])
    root = np.sqrt(gate)
    out = []
    for start in range(0, len(labels), _GATE_BLOCK):
        rows = np.arange(start, min(start + _GATE_BLOCK, len(labels)))
        dist = np.hypot(m[rows, None, 0] - m[None, :, 0], m[rows, None, 1] - m[None, :, 1])
        near = dist <= root * (s[rows, None] + s[None, :])
        for a, b in zip(*np.nonzero(near)):
            a = int(rows[a])
            if b > a:
                pair = (int(labels[a]), int(labels[b]))
                if pair not in excluded:
                    out.append(pair)
    return out


def _pair_distances(g: _Graph, problem: _Problem, pairs: List[Tuple[int, int]]) -> np.ndarray:
    """Table 11.8 for each pair: mu_Delta^T Sigma_Delta^-1 mu_Delta, Sigma_Delta = D Sigma D^T
    with D = (I, -I) and Sigma the pair's joint marginal."""
    if not pairs:
        return np.empty(0)
    joint = np.array(joint_marginal_covariances(g.graph, [[g.point_id(a), g.point_id(b)] for a, b in pairs]))
    d = np.hstack([np.eye(2), -np.eye(2)])
    cov = d @ joint @ d.T
    mu = np.array([problem.landmarks[a] - problem.landmarks[b] for a, b in pairs])
    return np.einsum("ni,ni->n", mu, np.linalg.solve(cov, mu[:, :, None])[:, :, 0])


def _merge_groups(passing: List[Tuple[int, int, float]], counts: Dict[int, int]) -> List[Tuple[int, int, float]]:
    """Groups of mutually passing labels, joined most probable pair first (complete linkage: two
    groups join only when every pair across them passed, so a chain A~B~C never merges A with C
    unless A~C passed too). Returns (kept, merged, distance2) per absorbed label: the label with
    most sightings (then the smaller) is kept."""
    passed = {(a, b): d2 for a, b, d2 in passing}
    passed.update({(b, a): d2 for a, b, d2 in passing})
    group = {}
    for a, b, _ in sorted(passing, key=lambda x: (x[2], x[0], x[1])):
        ga, gb = group.get(a, (a,)), group.get(b, (b,))
        if ga == gb or not all((x, y) in passed for x in ga for y in gb):
            continue
        joined = tuple(sorted(ga + gb))
        for x in joined:
            group[x] = joined
    out = []
    for members in sorted(set(group.values())):
        kept = max(members, key=lambda x: (counts.get(x, 0), -x))
        out.extend((kept, x, passed[(kept, x)]) for x in members if x != kept)
    return out
