"""GraphSLAM's correspondence test (Probabilistic Robotics ch. 11.6, Tables 11.8 and 11.9) as a
refinement of any landmark filter's result: the filter's poses, sightings and landmark labels
start a GraphSLAM over all sightings (pose vertices only where sightings were taken, the
odometry composed between them), which then, round by round:

0. (first round, ``estimate_noise``) rescales the odometry, range and bearing noise to the
   residuals of the optimum by variance component estimation: a filter's noise is set for the
   filter, often several times the sensor's, and a test against it sees nothing;
1. tests landmark pairs for identity with the full posterior: the joint (4, 4) marginal of the
   pair, cross-covariance included (``graph.joint_marginal_covariances``), gives Table 11.8's
   difference Delta = m_j - m_k and its covariance; a pair merges when the Mahalanobis distance
   of Delta from 0 is within the chi-square quantile ``MERGE_PROBABILITY`` (2 dof), unless the two
   were seen in one scan (one scan sees distinct landmarks, ch. 11.6's refinement); groups join
   only when every pair across them passed;
2. (the undo of 11.6) tests each sighting against its own landmark: the leave-one-out innovation
   of the sighting, its residual at the optimum weighed by the residual's covariance
   Q - H Sigma H^T (equal to the innovation of the sighting against the posterior of all the
   other sightings); the sightings beyond the split gate leave by backward elimination (worst
   first, the posterior updated after each) for the most likely other landmark within the gate,
   else for a new landmark (``new_landmarks``) or none (UNASSIGNED);
3. moves each sighting that another landmark explains better than its own (maximum likelihood,
   each under the posterior of the others; UNASSIGNED sightings join the most likely landmark
   within the gate);

a round makes the first kind of change that has any (merges, else splits, else moves),
optimises again, and the refinement stops when a round changes nothing, or at
``max_iterations``. Every test is exact for the linearised problem at the round's minimum; the
tests in tests/python/test_landmark_refine.py repeat each round by brute force on the dense
inverse.

Units: metres, radians. Poses (x, y, theta) with theta wrapped to (-pi, pi]. Sightings are
range-bearing; the graph holds each as the point in the pose's frame with the information of its
range-bearing noise carried through the polar-to-Cartesian Jacobian (GraphSLAM's linearisation;
the tests measure what the Cartesian form changes against exact range-bearing residuals: 0.02
standard deviations of a landmark).

``refine_landmarks`` works on arrays; each dataset builds them from a filter run over it
(``probslam.datasets.refinement_input``, with ``run_labels`` and ``poses_at_nodes`` from here),
and ``probslam.refine_run`` does both: the one entry point for a run.
``sighting_accuracy`` and ``majority_truth`` (from ``probslam.eval``) score a labelling against
the dataset's ids.
"""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np

from ._args import positive_real, real_array, require_instance, require_integer
from . import geometry
from ._core import (PoseGraph2D, chi_square_quantile, joint_marginal_covariances, linearize_point_edges,
                    linearize_pose_edges, marginal_covariances, optimize)
from .eval import majority_truth, relative_poses, sighting_accuracy  # noqa: F401 (re-exported)

#: A landmark pair merges when the Mahalanobis distance of their difference from 0 is within the
#: chi-square quantile at this probability (2 dof): a true duplicate pair passes with this
#: probability (Delta ~ N(0, Sigma_Delta) when both labels name one landmark), so 1% of the
#: duplicates are missed; a distinct pair merges only when their distance is below ~3 standard
#: deviations of Delta (9.21 = 3.03^2), i.e. when the data cannot tell them apart.
MERGE_PROBABILITY = 0.99

#: The split gate is chosen for the whole run, not per sighting: a run of K sightings tests K
#: residuals, so with a per-sighting quantile p about K (1 - p) correct sightings would leave
#: their landmark (50 at p = 0.99 for MRCLAM's 5000), each becoming a one-sighting landmark that
#: can never merge back (its merge test is its own failed residual test). The gate is the
#: chi-square quantile at p = SPLIT_RUN_PROBABILITY ** (1 / K) (Sidak), so that with this
#: probability no correct sighting of the whole run is split off: for K = 5000, p = 1 - 2.0e-6
#: and the gate is 26.2 (5.1 sigma). A sighting on a wrong landmark metres away scores in the
#: thousands. It is >= the merge gate, so a sighting that left never merges back.
SPLIT_RUN_PROBABILITY = 0.99

#: Rounds of optimise-test-change at most.
MAX_ITERATIONS = 30

#: The residual covariance Q - H Sigma H^T of a sighting is singular when its landmark rests on
#: it alone (one sighting, or others that constrain the point in one direction only): it is not
#: tested when its smallest eigenvalue is below this fraction of Q's largest (rounding in the
#: difference of two nearly equal matrices is ~1e-16 relative; 1e-9 leaves a wide margin).
LEAVE_ONE_OUT_RANK_TOLERANCE = 1e-9

#: MRCLAM odometry between two scans comes from the velocity motion model with two noise terms
#: (v, w): over one command its covariance has rank 2 (Thrun's eq. 5.9 adds a third term for this
#: reason), so two scans within one command would have no information matrix. Each composed
#: covariance's eigenvalues are raised to at least this fraction of its largest: the directions
#: the model says cannot err get a standard deviation 1e-3 of the largest one's, and information
#: entries stay within a factor 1e6 of each other in a pose, well inside what the factorisation
#: resolves.
ODOMETRY_COVARIANCE_FLOOR = 1e-6

#: A given covariance (odometry, measurement noise, and the sighting's point covariance it gives)
#: must be invertible in double precision: its smallest eigenvalue above this fraction of its
#: largest. Below it the inverse is dominated by rounding (an eigenvalue of 1e-16 relative is at
#: the level of one ulp of the entries) and numpy answers "Singular matrix" naming nothing.
COVARIANCE_CONDITION_FLOOR = 1e-13

#: The noise a filter is run with is set for the filter (MRCLAM's CLI default 0.15 m / 0.04 rad
#: is several times the camera's error: at the GraphSLAM optimum of robot 1 of Dataset 7 with
#: the barcodes as labels, chi2 is 722 for a redundancy of about 5000), and a test against a
#: noise several times too large cannot see a wrong sighting. With ``estimate_noise`` the
#: refinement rescales odometry, range and bearing noise by variance component estimation
#: (Foerstner) at each round before it tests, until every factor is within this of 1.
NOISE_TOLERANCE = 0.02

#: Variance component iterations per round at most (they converge linearly, within ~10 here).
NOISE_MAX_ITERATIONS = 20

#: The tests are made at a minimum: the leave-one-out statistic e^T (Q - H Sigma H^T)^-1 e
#: equals the innovation against the other sightings' posterior only where the gradient is zero.
#: Each optimisation runs until its largest step is below this (m, rad); a relative decrease of
#: 1e-10 stopped one 3.6e-5 m short of the minimum on a graph with chi2 5e4, off by 3e-5 in a
#: statistic of 39.
MINIMUM_STEP = 1e-9

#: ... or until an iteration lowers chi2 by less than this fraction, two decades above chi2's
#: rounding: near a minimum of a graph of thousands of poses the steps of its weakest directions
#: stay at rounding level (~1e-8) while chi2 no longer changes (1e-12 stopped 3e-6 m short on a
#: simulated graph of chi2 5e4, off by 2e-7 in a statistic of 0.009). On MRCLAM Dataset 1 robot 5 after a
#: joint-compatibility EKF, Gauss-Newton went from a minimum of chi2 16100 to 9.6e6 when the
#: noise was rescaled by 4%: these optimisations are damped.
MINIMUM_DECREASE = 1e-14

#: The optimisations between two noise estimates stop at this relative decrease of chi2: the
#: factors they feed change by far less than NOISE_TOLERANCE; the optimum the tests are made at
#: is then reached to MINIMUM_STEP.
NOISE_OPTIMIZE_TOLERANCE = 1e-6

#: A covariance given whose transpose differs by more than this fraction of its largest entry
#: is refused as not symmetric (rounding in a computed covariance is ~1e-16 relative).
COVARIANCE_SYMMETRY = 1e-9

UNASSIGNED = -1  # label of a sighting that belongs to no landmark


@dataclass(frozen=True)
class Merge:
    """Landmark ``merged`` joined landmark ``kept`` in round ``iteration`` (0-based);
    ``distance2``: the pair's squared Mahalanobis distance, ``probability`` = P(chi2_2 >= it)."""

    iteration: int
    kept: int
    merged: int
    distance2: float
    probability: float


@dataclass(frozen=True)
class Split:
    """Sighting ``sighting`` left landmark ``old`` for ``new`` in round ``iteration``:
    ``distance2`` its leave-one-out statistic against ``old`` when it left (the sightings that
    left before it in the round excluded too), ``new_distance2`` against ``new`` under the
    posterior without any of the round's leavers (NaN when ``new`` is a landmark created for it,
    ``created`` True; UNASSIGNED when it went to none). ``reason``: "gate" (its statistic
    exceeded the split gate) or "likelihood" (``new`` explains it better by more than
    REASSOCIATION_MARGIN)."""

    iteration: int
    sighting: int
    old: int
    new: int
    distance2: float
    new_distance2: float
    created: bool
    reason: str


@dataclass(frozen=True)
class RefinementRound:
    """One round: the labels it started from and the optimum it tested at (poses (T, 3),
    landmarks {label: (2,)}), the pairs it tested (P, 3) rows (label a, label b, distance2), each
    sighting's leave-one-out statistic against its landmark (K,) (NaN: not tested, or the round
    merged and skipped the sighting test), what it changed, and the noise it tested with
    (``noise_scale`` (3,): standard deviations of odometry, range and bearing over the given)."""

    iteration: int
    labels: np.ndarray
    poses: np.ndarray
    landmarks: Dict[int, np.ndarray]
    pair_tests: np.ndarray
    sighting_tests: np.ndarray
    merges: Tuple[Merge, ...]
    splits: Tuple[Split, ...]
    noise_scale: np.ndarray


@dataclass(frozen=True)
class LandmarkRefinement:
    """The refined solution: poses (T, 3), landmarks {label: (2,)} (those holding a sighting),
    labels (K,) per sighting (UNASSIGNED for those left out), every merge and split, the rounds
    run (``iterations``; ``converged``: the last one changed nothing), the gates used
    (``merge_gate``, ``split_gate``: squared Mahalanobis distances), the final chi2, seconds, and
    the noise of the final solution (``noise_scale`` (3,): standard deviations of odometry,
    range and bearing over the given ones; ones without ``estimate_noise``) and each landmark's
    marginal covariance there (``landmark_covariances``)."""

    poses: np.ndarray
    landmarks: Dict[int, np.ndarray]
    labels: np.ndarray
    merges: Tuple[Merge, ...]
    splits: Tuple[Split, ...]
    iterations: int
    converged: bool
    merge_gate: float
    split_gate: float
    chi2: float
    seconds: float
    rounds: Tuple[RefinementRound, ...]
    noise_scale: np.ndarray
    #: {label: (2, 2)} each landmark's marginal covariance at the final optimum (m^2).
    landmark_covariances: Dict[int, np.ndarray]


def merge_gate(probability: float = MERGE_PROBABILITY) -> float:
    """The squared Mahalanobis distance within which a pair merges (chi-square, 2 dof)."""
    return float(chi_square_quantile(probability, 2))


def split_gate(num_sightings: int, probability: float = SPLIT_RUN_PROBABILITY) -> float:
    """The squared leave-one-out distance beyond which a sighting leaves its landmark, for a run
    of ``num_sightings`` tested sightings (see SPLIT_RUN_PROBABILITY)."""
    num_sightings = require_integer(num_sightings, "num_sightings", 1)
    return float(chi_square_quantile(probability ** (1.0 / num_sightings), 2))


# ---------------------------------------------------------------------------------------------
# The linearised measurement: a sighting as the point in the pose's frame.


def _point_covariances(measurements: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """The robot-frame point covariances (K, 2, 2) of range-bearing sightings, through the
    Jacobian of (r cos phi, r sin phi)."""
    r, phi = measurements[:, 0], measurements[:, 1]
    c, s = np.cos(phi), np.sin(phi)
    jac = np.stack([np.column_stack([c, -r * s]), np.column_stack([s, r * c])], axis=1)
    cov = jac @ noise @ jac.transpose(0, 2, 1)
    return 0.5 * (cov + cov.transpose(0, 2, 1))


def polar_to_point(measurements: np.ndarray, noise: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Range-bearing (K, 2) with covariances (K, 2, 2) as robot-frame points (K, 2) with their
    information (K, 2, 2)."""
    r, phi = measurements[:, 0], measurements[:, 1]
    return np.column_stack([r * np.cos(phi), r * np.sin(phi)]), np.linalg.inv(_point_covariances(measurements, noise))


def _require_invertible(covs: np.ndarray, name: str, what: str = "matrix") -> None:
    """ValueError naming ``name`` and the first covariance of ``covs`` (N, n, n) that is not
    positive definite or not invertible within COVARIANCE_CONDITION_FLOOR."""
    if len(covs) == 0:
        return
    w = np.linalg.eigvalsh(covs)
    bad = np.flatnonzero(~(w[:, 0] > COVARIANCE_CONDITION_FLOOR * np.abs(w[:, -1])))
    if len(bad):
        i = int(bad[0])
        kind = "positive definite" if w[i, 0] <= 0 else f"invertible (eigenvalue ratio above {COVARIANCE_CONDITION_FLOOR:g})"
        raise ValueError(f"{name}: must be positive definite and invertible; {what} {i} is not {kind}: "
                         f"eigenvalues {w[i, 0]:.6g} .. {w[i, -1]:.6g}")


def _rotation_t(theta: np.ndarray) -> np.ndarray:
    """R(theta)^T, (..., 2, 2)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)


# ---------------------------------------------------------------------------------------------
# The refinement.


class _Problem:
    """The refinement's state: the data, the current noise (polar (K, 2, 2) and odometry
    (T - 1, 3, 3) covariances, and what the graph needs of them), labels and values."""

    def __init__(self, poses, odometry, odometry_covariances, pose_index, polar, polar_noise, labels):
        self.poses = poses  # (T, 3) current values
        self.odometry = odometry  # (T - 1, 3)
        self.pose_index = pose_index  # (K,)
        self.polar = polar  # (K, 2) range, bearing
        self.labels = labels  # (K,) current labels
        self.landmarks: Dict[int, np.ndarray] = {}
        # Sighting -> the landmarks it has left: it never goes back to one (see _split_moves).
        self.left: Dict[int, set] = collections.defaultdict(set)
        self.set_noise(odometry_covariances, polar_noise)

    def set_noise(self, odometry_covariances: np.ndarray, polar_noise: np.ndarray) -> None:
        self.odometry_covariances = odometry_covariances
        self.odometry_information = np.linalg.inv(odometry_covariances)
        self.polar_noise = polar_noise
        self.z, self.z_information = polar_to_point(self.polar, polar_noise)
        self.z_covariance = np.linalg.inv(self.z_information)


def _placed(problem: _Problem, rows: np.ndarray) -> np.ndarray:
    """World positions (n, 2) of sightings ``rows`` placed from their poses' current values."""
    x = problem.poses[problem.pose_index[rows]]
    r = np.transpose(_rotation_t(x[:, 2]), (0, 2, 1))
    return x[:, :2] + np.einsum("nij,nj->ni", r, problem.z[rows])


class _Graph:
    """The GraphSLAM of the current labels: pose vertex k has id k, landmark `label` the id
    T + its slot in ``labels`` (sorted)."""

    def __init__(self, problem: _Problem):
        p = problem
        t = len(p.poses)
        self.labels = np.array(sorted({int(x) for x in p.labels[p.labels != UNASSIGNED]}), dtype=np.int64)
        self.slot = {int(label): k for k, label in enumerate(self.labels)}
        self.num_poses = t
        g = PoseGraph2D()
        for k in range(t):
            g.add_pose(k, p.poses[k])
        g.set_fixed(0)  # the filters' start pose is known exactly: the gauge
        for k in range(t - 1):
            g.add_pose_edge(k, k + 1, p.odometry[k], p.odometry_information[k])
        for label in self.labels:
            g.add_point(t + self.slot[int(label)], p.landmarks[int(label)])
        self.rows = np.flatnonzero(p.labels != UNASSIGNED)
        for i in self.rows:
            g.add_point_edge(int(p.pose_index[i]), t + self.slot[int(p.labels[i])], p.z[i], p.z_information[i])
        self.graph = g

    def point_id(self, label) -> int:
        return self.num_poses + self.slot[int(label)]

    def point_ids(self, labels: np.ndarray) -> np.ndarray:
        """``point_id`` of each of an array of held labels."""
        return self.num_poses + np.searchsorted(self.labels, labels)

    def landmark_marginals(self) -> np.ndarray:
        """(L, 2, 2) marginal covariances of the landmarks in ``labels`` order, computed once."""
        if getattr(self, "_marginals", None) is None:
            ids = [self.point_id(x) for x in self.labels]
            self._marginals = np.array(marginal_covariances(self.graph, ids)).reshape(-1, 2, 2)
        return self._marginals

    def optimize(self, problem: _Problem, precise: bool = True) -> float:
        """Minimise from the current values (Levenberg-Marquardt: its first damping is tiny, so
        where Gauss-Newton's steps are good they are taken as they are, and a start far off, a
        filter that went astray or a rescaled noise, is still safe). ``precise``: to
        MINIMUM_STEP / MINIMUM_DECREASE, the tests' requirement; else to
        NOISE_OPTIMIZE_TOLERANCE (between two noise estimates)."""
        tolerance = dict(relative_tolerance=MINIMUM_DECREASE, step_tolerance=MINIMUM_STEP) if precise else \
            dict(relative_tolerance=NOISE_OPTIMIZE_TOLERANCE)
        report = optimize(self.graph, algorithm="levenberg-marquardt", **tolerance)
        self._marginals = None
        problem.poses = self.graph.poses
        points = self.graph.points
        problem.landmarks = {int(label): points[k].copy() for k, label in enumerate(self.labels)}
        return float(report.chi2)


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


@dataclass
class _SightingTests:
    """What the sighting test computed for the labelled sightings of landmarks with two or more:
    rows (n,), residuals e (n, 2), Jacobians h (n, 2, 5) over (pose, landmark), residual
    covariances Q - h Sigma h^T (n, 2, 2), their inverses (NaN where not testable, ``ok``
    False), and the statistic e^T (Q - h Sigma h^T)^-1 e per sighting of the problem (K,)."""

    rows: np.ndarray
    e: np.ndarray
    h: np.ndarray
    residual_cov: np.ndarray
    inverse: np.ndarray
    ok: np.ndarray
    stats: np.ndarray
    joint: np.ndarray  # (n, 5, 5) of (pose, landmark)


def _sighting_statistics(g: _Graph, problem: _Problem, counts: Dict[int, int]) -> _SightingTests:
    """Each labelled sighting's leave-one-out statistic e^T (Q - H Sigma H^T)^-1 e against its
    landmark (NaN where not testable: a landmark of one sighting, or a residual covariance of
    less than full rank), and what the re-association and the noise estimate need of it."""
    k = len(problem.labels)
    stats = np.full(k, np.nan)
    rows = np.array([i for i in g.rows if counts[int(problem.labels[i])] >= 2], dtype=np.int64)
    if len(rows) == 0:
        empty = np.empty((0, 2, 2))
        return _SightingTests(rows, np.empty((0, 2)), np.empty((0, 2, 5)), empty, empty, np.zeros(0, bool), stats,
                              np.empty((0, 5, 5)))
    t = problem.pose_index[rows]
    groups = np.column_stack([t, g.point_ids(problem.labels[rows])]).tolist()
    joint = np.array(joint_marginal_covariances(g.graph, groups))
    marks = np.array([problem.landmarks[int(c)] for c in g.labels])
    m = marks[np.searchsorted(g.labels, problem.labels[rows])]
    e, j_pose, j_point = linearize_point_edges(problem.poses[t], m, problem.z[rows])
    h = np.concatenate([j_pose, j_point], axis=2)  # (n, 2, 5)
    residual_cov = problem.z_covariance[rows] - h @ joint @ h.transpose(0, 2, 1)
    residual_cov = 0.5 * (residual_cov + residual_cov.transpose(0, 2, 1))
    smallest = np.linalg.eigvalsh(residual_cov)[:, 0]
    scale = np.linalg.eigvalsh(problem.z_covariance[rows])[:, -1]
    ok = smallest > LEAVE_ONE_OUT_RANK_TOLERANCE * scale
    inv = np.full_like(residual_cov, np.nan)
    inv[ok] = np.linalg.inv(residual_cov[ok])
    stats[rows[ok]] = np.einsum("ni,nij,nj->n", e[ok], inv[ok], e[ok])
    return _SightingTests(rows, e, h, residual_cov, inv, ok, stats, joint)


def _variance_factors(g: _Graph, problem: _Problem, tests: _SightingTests, gate: float) -> np.ndarray:
    """Variance component estimation (Foerstner): for each noise group (odometry, range,
    bearing), sum of e^T Q^-1 e over its residuals divided by its redundancy, the sum of
    tr(Q^-1 (Q - J Sigma J^T)) (the residuals' share of the observations' freedom); 1 for a group
    whose noise is right. Sightings beyond the split gate are left out (they are about to leave:
    their residuals are errors of association, not noise). Range and bearing are the components
    of the sighting's residual mapped back to polar through the inverse of its Jacobian."""
    factors = np.ones(3)
    t = len(problem.poses)
    if t > 1:
        joint = np.array(joint_marginal_covariances(g.graph, [[k, k + 1] for k in range(t - 1)]))
        e, d_from, d_to = linearize_pose_edges(problem.poses[:-1], problem.poses[1:], problem.odometry)
        jac = np.concatenate([d_from, d_to], axis=2)
        info = problem.odometry_information
        residual = problem.odometry_covariances - jac @ joint @ jac.transpose(0, 2, 1)
        redundancy = np.einsum("nij,nji->", info, residual)
        if redundancy > 0:
            factors[0] = np.einsum("ni,nij,nj->", e, info, e) / redundancy
    keep = tests.ok & (tests.stats[tests.rows] <= gate)
    if keep.any():
        rows = tests.rows[keep]
        r, phi = problem.polar[rows, 0], problem.polar[rows, 1]
        c, s = np.cos(phi), np.sin(phi)
        to_polar = np.stack([np.column_stack([c, s]), np.column_stack([-s / r, c / r])], axis=1)
        e = np.einsum("nij,nj->ni", to_polar, tests.e[keep])
        residual = to_polar @ tests.residual_cov[keep] @ to_polar.transpose(0, 2, 1)
        q = problem.polar_noise[rows]
        for c_ in range(2):
            redundancy = np.sum(residual[:, c_, c_] / q[:, c_, c_])
            if redundancy > 0:
                factors[1 + c_] = np.sum(e[:, c_] ** 2 / q[:, c_, c_]) / redundancy
    return factors


#: A sighting that passes its own landmark's test still moves to another landmark that explains
#: it better: when its likelihood there is more than this many times its likelihood on its own
#: (both under the posterior of all the other sightings). 1: maximum likelihood, as the filters
#: associate, no prior in favour of the filter's label (measured on the ten MRCLAM runs of three
#: filters: odds of 10 gained 2-5 points of correct sightings where maximum likelihood gained
#: 3-12; bench_landmark_refine.py).
REASSOCIATION_ODDS = 1.0
REASSOCIATION_MARGIN = 2.0 * float(np.log(REASSOCIATION_ODDS))  # in -2 log likelihood

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
    suspects = suspects[:MAX_SUSPECTS_PER_ROUND]
    if not suspects:
        return []
    # One dense joint posterior of the suspects' poses and every landmark.
    poses = sorted({int(problem.pose_index[i]) for i in suspects})
    ids = poses + [g.point_id(c) for c in g.labels]
    start = {}
    offset = 0
    for v in ids:
        start[v] = offset
        offset += 3 if v < g.num_poses else 2
    sigma = np.array(joint_marginal_covariances(g.graph, [ids])[0])
    delta = np.zeros(offset)
    # The posterior without the leavers is sigma + B A^T, one rank-2 term (a W, a) per leaver:
    # kept as factors, so each leaver costs O(n * leavers) for the blocks read, not O(n^2).
    factor_a, factor_b = np.zeros((offset, 2 * len(suspects))), np.zeros((offset, 2 * len(suspects)))
    used = 0

    landmark_start = np.array([start[g.point_id(c)] for c in g.labels], dtype=np.int64)

    def columns(pose: np.ndarray, landmark: np.ndarray) -> np.ndarray:
        """(n, 5) the dense posterior's columns of (pose, landmark) pairs (pose ids, label slots)."""
        p = np.array([start[int(x)] for x in pose], dtype=np.int64)
        return np.column_stack([p, p + 1, p + 2, landmark_start[landmark], landmark_start[landmark] + 1])

    suspects = np.array(suspects, dtype=np.int64)
    at = np.searchsorted(tests.rows, suspects)
    cols = columns(problem.pose_index[suspects], np.searchsorted(g.labels, problem.labels[suspects]))
    h_all, e_all = tests.h[at], tests.e[at]
    q_all = problem.z_covariance[suspects]
    scale = np.linalg.eigvalsh(q_all)[:, -1]
    remaining = np.ones(len(suspects), bool)
    left = []
    # Each suspect's (pose, landmark) block of the posterior, the leavers' terms added as they leave.
    suspect_blocks = sigma[cols[:, :, None], cols[:, None, :]]
    while remaining.any():
        # Every remaining suspect's leave-one-out statistic under the posterior without the leavers.
        r = np.flatnonzero(remaining)
        h, c = h_all[r], cols[r]
        v = e_all[r] + np.einsum("nij,nj->ni", h, delta[c])
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
        a = (sigma[:, cols[best]] + factor_b[:, :used] @ factor_a[cols[best], :used].T) @ h_all[best].T
        w = np.linalg.inv(m[worst])
        remaining[best] = False
        left.append((int(suspects[best]), float(x[worst])))
        delta += a @ (w @ v[worst])
        factor_a[:, used:used + 2], factor_b[:, used:used + 2] = a, a @ w
        suspect_blocks += factor_b[cols, used:used + 2] @ factor_a[cols, used:used + 2].transpose(0, 2, 1)
        used += 2
    by_pose = np.argsort(problem.pose_index, kind="stable")
    bounds = np.searchsorted(problem.pose_index[by_pose], np.arange(len(problem.poses) + 1))
    labels = problem.labels.copy()
    moves = []
    slots = np.arange(len(g.labels))
    # The final posterior's blocks the moves read: (the leaver's pose, each landmark).
    landmark_rows = landmark_start[:, None] + np.arange(2)
    landmark_terms = factor_b[landmark_rows, :used] @ factor_a[landmark_rows, :used].transpose(0, 2, 1)

    def pose_landmark_blocks(pose: int, free: np.ndarray) -> np.ndarray:
        """(n, 5, 5) the posterior without the leavers over (pose, landmark slot) for slots ``free``."""
        p, rows = start[pose] + np.arange(3), landmark_rows[free].ravel()
        k = np.column_stack([np.broadcast_to(p, (len(free), 3)), landmark_rows[free]])
        out = sigma[k[:, :, None], k[:, None, :]]
        out[:, :3, :3] += factor_b[p, :used] @ factor_a[p, :used].T
        out[:, :3, 3:] += (factor_b[p, :used] @ factor_a[rows, :used].T).reshape(3, -1, 2).transpose(1, 0, 2)
        out[:, 3:, :3] += (factor_b[rows, :used] @ factor_a[p, :used].T).reshape(-1, 2, 3)
        out[:, 3:, 3:] += landmark_terms[free]
        return out

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
            k = columns(np.full(len(free), t), free)
            v = e + np.einsum("nij,nj->ni", h, delta[k])
            cov = problem.z_covariance[i][None] + h @ pose_landmark_blocks(t, free) @ h.transpose(0, 2, 1)
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


def _reassociation_distances(g: _Graph, problem: _Problem, queries: List[Tuple[int, int]],
                             tests: _SightingTests) -> np.ndarray:
    """Squared Mahalanobis distance of sighting i to landmark c, for each query (i, c), under the
    posterior of all the sightings but i: with J the sighting's Jacobian over (pose, own landmark)
    and W = (Q - J Sigma J^T)^-1, removing it moves the mean by Sigma J^T W e and the covariance by
    + Sigma J^T W J Sigma (Woodbury); the innovation against c is then c's residual plus H (mean
    shift), with covariance Q + H Sigma' H^T. One factorisation for all the queries."""
    if not queries:
        return np.empty(0)
    rows = np.array([i for i, _ in queries], dtype=np.int64)
    t = problem.pose_index[rows]
    candidates = np.array([c for _, c in queries], dtype=np.int64)
    groups = np.column_stack([t, g.point_ids(problem.labels[rows]), g.point_ids(candidates)]).tolist()
    joint = np.array(joint_marginal_covariances(g.graph, groups))  # (n, 7, 7): candidate, pose, own
    n = len(queries)
    at = np.searchsorted(tests.rows, rows)
    e, h_own, w = tests.e[at], tests.h[at], tests.inverse[at]
    j_own = np.zeros((n, 2, 7))
    j_own[:, :, 0:5] = h_own
    a = joint @ j_own.transpose(0, 2, 1)  # Sigma J^T (n, 7, 2)
    shift = np.einsum("nij,nj->ni", a, np.einsum("nij,nj->ni", w, e))
    loo = joint + a @ w @ a.transpose(0, 2, 1)
    marks = np.array([problem.landmarks[int(c)] for c in g.labels])
    m = marks[np.searchsorted(g.labels, candidates)]
    e_c, j_pose, j_point = linearize_point_edges(problem.poses[t], m, problem.z[rows])
    h = np.zeros((n, 2, 7))
    h[:, :, 0:3] = j_pose
    h[:, :, 5:7] = j_point
    v = e_c + np.einsum("nij,nj->ni", h, shift)
    s = problem.z_covariance[rows] + h @ loo @ h.transpose(0, 2, 1)
    return np.einsum("ni,ni->n", v, np.linalg.solve(s, v[:, :, None])[:, :, 0]), np.linalg.slogdet(s)[1]


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
    t = problem.pose_index[rows]
    q = problem.z_covariance[rows]
    # The posterior without the sighting: its pose's covariance and the shift of its mean.
    pose_cov = np.zeros((len(rows), 3, 3))
    if len(lone):
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
    scores: Dict[int, Tuple[float, int, float]] = {}  # sighting -> (score to beat, best candidate, its d2)
    if own_queries:
        d2, logdet = _reassociation_distances(g, problem, own_queries, tests)
        at = {int(i): k for k, i in enumerate(rows[:n_own])}
        for (i, c), x, ld in zip(own_queries, d2, logdet):
            gain = own_score[at[i]] - (x + ld)
            if c in problem.left[i]:
                continue
            if x <= gate and gain > REASSOCIATION_MARGIN and gain > scores.get(i, (-np.inf,))[0]:
                scores[i] = (float(gain), c, float(x))
    if lone_queries:
        joint = np.array(joint_marginal_covariances(g.graph, [[int(problem.pose_index[i]), g.point_id(c)]
                                                              for i, c in lone_queries]))
        i_ = np.array([i for i, _ in lone_queries])
        mk = np.array([problem.landmarks[c] for _, c in lone_queries])
        e_c, j_pose, j_point = linearize_point_edges(problem.poses[problem.pose_index[i_]], mk, problem.z[i_])
        h = np.concatenate([j_pose, j_point], axis=2)
        s_c = problem.z_covariance[i_] + h @ joint @ h.transpose(0, 2, 1)
        d2 = np.einsum("ni,ni->n", e_c, np.linalg.solve(s_c, e_c[:, :, None])[:, :, 0])
        logdet = np.linalg.slogdet(s_c)[1]
        for (i, c), x, ld in zip(lone_queries, d2, logdet):
            if c in problem.left[i]:
                continue
            if x <= gate and -(x + ld) > scores.get(i, (-np.inf,))[0]:
                scores[i] = (float(-(x + ld)), c, float(x))
    scan_of = collections.defaultdict(set)
    for i in np.flatnonzero(problem.labels != UNASSIGNED):
        scan_of[int(problem.pose_index[i])].add(int(problem.labels[i]))
    moves = []
    # Labelled sightings by their gain first, then the unassigned by likelihood.
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


def _scaled_polar(noise: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """Polar covariances (K, 2, 2) with range and bearing scaled by the factors ``variance``
    (2,): S Q S with S = diag(sqrt(variance))."""
    s = np.sqrt(variance)
    return noise * np.outer(s, s)[None]


def _integer_vector(value, name: str, k: int) -> np.ndarray:
    """value as a (k,) integer array: TypeError naming it for other dtypes, ValueError for another shape."""
    a = np.asarray(value)
    if a.dtype.kind not in "iu":
        raise TypeError(f"{name}: expected integers, got dtype {a.dtype}")
    if a.shape != (k,):
        raise ValueError(f"{name}: expected shape ({k},), got {a.shape}")
    return a


def _check_input(poses, odometry, odometry_covariances, pose_index, measurements, labels, measurement_noise,
                 landmarks):
    poses = real_array(poses, "poses", (None, 3))
    t = len(poses)
    if t < 1:
        raise ValueError("poses: need at least one pose")
    odometry = real_array(odometry, "odometry", (t - 1, 3))
    odometry_covariances = real_array(odometry_covariances, "odometry_covariances", (t - 1, 3, 3))
    measurements = real_array(measurements, "measurements", (None, 2))
    k = len(measurements)
    if np.any(measurements[:, 0] <= 0):
        raise ValueError(f"measurements: ranges must be > 0 (row {int(np.argmax(measurements[:, 0] <= 0))})")
    index = _integer_vector(pose_index, "pose_index", k)
    if k and (index.min() < 0 or index.max() >= t):
        raise ValueError(f"pose_index: must lie in [0, {t - 1}] (the rows of poses)")
    lab = _integer_vector(labels, "labels", k)
    if k and lab.min() < UNASSIGNED:
        raise ValueError(f"labels: a landmark label is >= 0, {UNASSIGNED} marks a sighting of none; got {lab.min()}")
    q = real_array(measurement_noise, "measurement_noise", None)
    if q.shape == (2, 2):
        q = np.broadcast_to(q, (k, 2, 2))
    elif q.shape != (k, 2, 2):
        raise ValueError(f"measurement_noise: expected shape (2, 2) or ({k}, 2, 2), got {q.shape}")
    for name, covs in (("odometry_covariances", odometry_covariances), ("measurement_noise", q)):
        largest = np.abs(covs).max(axis=(1, 2))[:, None, None] if len(covs) else 0.0
        if len(covs) and np.any(np.abs(covs - covs.transpose(0, 2, 1)) > COVARIANCE_SYMMETRY * largest):
            raise ValueError(f"{name}: must be symmetric")
        _require_invertible(covs, name)
    # The point covariance a sighting gives (a range near 0 makes it singular).
    _require_invertible(_point_covariances(measurements, q), "measurements, measurement_noise", "sighting")
    values: Dict[int, np.ndarray] = {}
    if landmarks is not None:
        require_instance(landmarks, dict, "landmarks")
        for key, value in landmarks.items():
            label = require_integer(key, "landmarks", 0)
            values[label] = real_array(value, f"landmarks[{label}]", (2,))
    return poses, odometry, odometry_covariances, index.astype(np.int64), measurements, lab.astype(np.int64), q, values


def refine_landmarks(poses, odometry, odometry_covariances, pose_index, measurements, labels, measurement_noise,
                     landmarks: Optional[Dict[int, np.ndarray]] = None, *,
                     merge_probability: float = MERGE_PROBABILITY,
                     split_probability: float = SPLIT_RUN_PROBABILITY,
                     max_iterations: int = MAX_ITERATIONS, estimate_noise: bool = True,
                     new_landmarks: bool = False) -> LandmarkRefinement:
    """Refine a landmark filter's data association with GraphSLAM (ch. 11.6, see the module).

    ``poses`` (T, 3): the filter's poses where sightings were taken (row 0 the start, held fixed
    as the gauge); ``odometry`` (T - 1, 3): the motion from each pose to the next in the former's
    frame, with ``odometry_covariances`` (T - 1, 3, 3); ``pose_index`` (K,): the pose of each
    sighting; ``measurements`` (K, 2): range m, bearing rad; ``labels`` (K,): the filter's landmark
    of each sighting (>= 0), or UNASSIGNED (-1) for one it put on none (left out and left so);
    ``measurement_noise``: (2, 2) range-bearing covariance, or (K, 2, 2) per sighting;
    ``landmarks``: {label: (2,)} starting values (others start at their sightings' mean).
    ``merge_probability``: the pair gate's chi-square probability; ``split_probability``: the
    probability that no correct sighting of the run is split off (see SPLIT_RUN_PROBABILITY);
    ``estimate_noise``: rescale the odometry, range and bearing noise to the residuals of the
    first optimum (variance components, see NOISE_TOLERANCE) before the first test;
    ``new_landmarks``: a sighting that leaves its landmark and passes no other founds a landmark
    of its own (labels above the largest given), else it is left UNASSIGNED (see the module).

    Each round makes one kind of change, in this order of precedence: merges (step 1), sightings
    leaving by the split gate (step 2), sightings moving to a landmark that explains them better
    (``_likelihood_moves``); it stops when a round changes nothing. Sightings of one pose are one
    scan: its labels stay distinct. Returns a LandmarkRefinement."""
    start = time.perf_counter()
    poses, odometry, odo_cov, index, z_polar, labels, q, values = _check_input(
        poses, odometry, odometry_covariances, pose_index, measurements, labels, measurement_noise, landmarks)
    for name, p in (("merge_probability", merge_probability), ("split_probability", split_probability)):
        if positive_real(p, name) >= 1.0:
            raise ValueError(f"{name} must lie in (0, 1), got {p!r}")
    max_iterations = require_integer(max_iterations, "max_iterations", 0, 10 ** 6)
    for name, flag in (("estimate_noise", estimate_noise), ("new_landmarks", new_landmarks)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"{name} must be a bool, got {type(flag).__name__}")
    order = np.lexsort((labels, index))
    twice = (np.diff(index[order]) == 0) & (np.diff(labels[order]) == 0) & (labels[order][1:] != UNASSIGNED)
    if twice.any():
        raise ValueError(f"labels: two sightings of pose {index[order][1:][twice][0]} (one scan) name the same landmark")
    problem = _Problem(poses.copy(), odometry, odo_cov, index, z_polar, np.array(q), labels.copy())
    labelled = np.flatnonzero(labels != UNASSIGNED)
    points = _placed(problem, labelled)
    for label in np.unique(labels[labelled]):
        label = int(label)
        problem.landmarks[label] = values.get(label, points[labels[labelled] == label].mean(axis=0))
    gate_merge = merge_gate(merge_probability)
    gate_split = split_gate(max(len(labelled), 1), split_probability)
    next_label = int(labels.max()) + 1 if len(labels) else 0
    merges: List[Merge] = []
    splits: List[Split] = []
    rounds: List[RefinementRound] = []
    converged, chi2, iteration = False, float("nan"), 0
    g: Optional[_Graph] = None
    variance = np.ones(3)  # of odometry, range, bearing over the given noise
    while True:
        g = _Graph(problem) if len(labelled) else None
        chi2 = g.optimize(problem) if g is not None and g.graph.num_pose_edges + g.graph.num_point_edges else 0.0
        if iteration >= max_iterations or g is None:
            converged = g is None
            break
        counts = collections.Counter(int(x) for x in problem.labels[problem.labels != UNASSIGNED])
        for _ in range(NOISE_MAX_ITERATIONS if estimate_noise and iteration == 0 else 0):
            factors = _variance_factors(g, problem, _sighting_statistics(g, problem, counts), gate_split)
            if np.all(np.abs(factors - 1.0) <= NOISE_TOLERANCE):
                break
            variance *= factors
            problem.set_noise(odo_cov * variance[0], _scaled_polar(q, variance[1:]))
            g = _Graph(problem)
            chi2 = g.optimize(problem, precise=False)
        if variance is not None and estimate_noise and iteration == 0:
            chi2 = g.optimize(problem)  # the tests' minimum
        before = problem.labels.copy()
        excluded = _co_observed(problem)
        pairs = _candidate_pairs(g, problem, gate_merge, excluded)
        d2 = _pair_distances(g, problem, pairs)
        passing = [(a, b, float(x)) for (a, b), x in zip(pairs, d2) if x <= gate_merge]
        round_merges = [Merge(iteration, kept, gone, d, float(np.exp(-0.5 * d)))
                        for kept, gone, d in _merge_groups(passing, counts)]
        stats = np.full(len(labels), np.nan)
        round_splits: List[Split] = []
        if round_merges:
            target = {m.merged: m.kept for m in round_merges}
            problem.labels = np.array([target.get(int(x), int(x)) for x in problem.labels], dtype=np.int64)
            for i, gone in problem.left.items():
                problem.left[i] = {target.get(x, x) for x in gone}
        else:
            tests = _sighting_statistics(g, problem, counts)
            stats = tests.stats
            round_splits = _split_moves(g, problem, tests, gate_split, next_label, iteration, new_landmarks)
            if not round_splits:
                round_splits = _likelihood_moves(g, problem, tests, gate_split, iteration)
            for s in round_splits:
                if s.old != UNASSIGNED:
                    problem.left[s.sighting].add(s.old)
                problem.labels[s.sighting] = s.new
                if s.created:
                    problem.landmarks[s.new] = _placed(problem, np.array([s.sighting]))[0]
                    next_label = max(next_label, s.new + 1)
        rounds.append(RefinementRound(iteration, before, problem.poses.copy(),
                                      {k: v.copy() for k, v in problem.landmarks.items() if k in g.slot},
                                      np.array([(a, b, x) for (a, b), x in zip(pairs, d2)]).reshape(-1, 3),
                                      stats, tuple(round_merges), tuple(round_splits), np.sqrt(variance)))
        merges.extend(round_merges)
        splits.extend(round_splits)
        iteration += 1
        if not round_merges and not round_splits:
            converged = True
            break
    held = {int(x) for x in problem.labels[problem.labels != UNASSIGNED]}
    # The last graph is the one of the final labels (a round that changed them is followed by a
    # new graph before the loop ends), optimised: its marginals are the final map's.
    covariances = {} if g is None else {int(k): c for k, c in zip(g.labels, g.landmark_marginals())}
    return LandmarkRefinement(problem.poses.copy(), {k: problem.landmarks[k].copy() for k in sorted(held)},
                              problem.labels.copy(), tuple(merges), tuple(splits), len(rounds), converged,
                              gate_merge, gate_split, chi2, time.perf_counter() - start, tuple(rounds),
                              np.sqrt(variance), {k: covariances[k] for k in sorted(held)})


# ---------------------------------------------------------------------------------------------
# From a filter run over a dataset.


def compose_increments(deltas: np.ndarray, covariances: np.ndarray, nodes: np.ndarray):
    """Relative motions between chain nodes: ``deltas`` (n, 3) move node i to node i + 1 in node
    i's frame, with ``covariances`` (n, 3, 3), independent. For consecutive entries a <= b of
    ``nodes`` (m,), returns node b in node a's frame (m - 1, 3) and its covariance (m - 1, 3, 3)
    (first order: each increment's Jacobian rotates it into a's frame and, for its heading,
    swings the rest of the segment about its end point; a segment a == b is no motion, zero
    covariance). Vectorised over all increments at once: the chain is laid out in node 0's
    frame, each increment's share of its segment's covariance summed per segment."""
    deltas = np.asarray(deltas, float)
    covariances = np.asarray(covariances, float)
    nodes = np.asarray(nodes, np.int64)
    heading = np.concatenate([[0.0], np.cumsum(deltas[:, 2])])  # unwrapped, node 0's frame
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])
    step = np.column_stack([c * deltas[:, 0] - s * deltas[:, 1], s * deltas[:, 0] + c * deltas[:, 1]])
    position = np.vstack([np.zeros(2), np.cumsum(step, axis=0)])
    a, b = nodes[:-1], nodes[1:]
    frame = np.zeros((len(a), 3, 3))  # blockdiag(R(heading_a), 1): a's frame in node 0's
    frame[:, :2, :2] = np.transpose(_rotation_t(heading[a]), (0, 2, 1))
    frame[:, 2, 2] = 1.0
    rel = np.empty((len(a), 3))
    rel[:, :2] = np.einsum("nji,nj->ni", frame[:, :2, :2], position[b] - position[a])
    rel[:, 2] = np.arctan2(np.sin(heading[b] - heading[a]), np.cos(heading[b] - heading[a]))
    world = np.zeros((len(a), 3, 3))
    moving = np.flatnonzero(b > a)
    if len(moving):
        i = np.arange(a[moving[0]], b[moving[-1]])
        segment = np.searchsorted(b, i, side="right")  # a[segment] <= i < b[segment]
        g = np.zeros((len(i), 3, 3))
        g[:, 0, 0], g[:, 0, 1], g[:, 1, 0], g[:, 1, 1] = c[i], -s[i], s[i], c[i]
        arm = position[b[segment]] - position[i + 1]  # the heading of increment i swings the rest about its end
        g[:, 0, 2], g[:, 1, 2], g[:, 2, 2] = -arm[:, 1], arm[:, 0], 1.0
        world[moving] = np.add.reduceat(g @ covariances[i] @ g.transpose(0, 2, 1), a[moving] - i[0], axis=0)
    cov = frame.transpose(0, 2, 1) @ world @ frame
    return rel, 0.5 * (cov + cov.transpose(0, 2, 1))


def floor_covariances(covariances: np.ndarray) -> np.ndarray:
    """Covariances with eigenvalues raised to ODOMETRY_COVARIANCE_FLOOR of their largest."""
    values, vectors = np.linalg.eigh(covariances)
    values = np.maximum(values, ODOMETRY_COVARIANCE_FLOOR * values[:, -1:])
    return np.einsum("nij,nj,nkj->nik", vectors, values, vectors)


@dataclass(frozen=True)
class RefinementInput:
    """The arrays ``refine_landmarks`` takes, built from a run over a dataset, and what scoring
    needs: ``times`` (T,) of the poses (s; chain positions for Victoria Park), ``rows`` (K,) each
    sighting's row in the dataset's measurements, ``truth`` (K,) its true landmark (the barcode's
    subject, Victoria Park's landmark id)."""

    times: np.ndarray
    poses: np.ndarray
    odometry: np.ndarray
    odometry_covariances: np.ndarray
    pose_index: np.ndarray
    measurements: np.ndarray
    labels: np.ndarray
    measurement_noise: np.ndarray
    landmarks: Dict[int, np.ndarray]
    rows: np.ndarray
    truth: np.ndarray

    def arguments(self) -> dict:
        """Keyword arguments of ``refine_landmarks``."""
        return dict(poses=self.poses, odometry=self.odometry, odometry_covariances=self.odometry_covariances,
                    pose_index=self.pose_index, measurements=self.measurements, labels=self.labels,
                    measurement_noise=self.measurement_noise, landmarks=self.landmarks)


def run_labels(run, truth: np.ndarray) -> np.ndarray:
    """Per sighting, the run's landmark (UNASSIGNED where it put the sighting on none): from its
    association record (hidden correspondences), else the true ids (known), less the sightings
    an EKF's outlier gate rejected."""
    if run.associations is None:
        labels = truth.astype(np.int64).copy()
        innovations = getattr(run, "innovations", None)
        if innovations is not None and len(innovations) == len(truth):
            labels[innovations[:, 3] == 0] = UNASSIGNED
        return labels
    record = run.associations
    if len(record.ids) != len(truth) or np.any(np.asarray(record.truth) != truth):
        raise ValueError("run: its associations do not follow the data's sightings (was it run on this data?)")
    return np.where(np.asarray(record.ids) >= 0, record.ids, UNASSIGNED).astype(np.int64)


def poses_at_nodes(times: np.ndarray, poses: np.ndarray, chain_times: np.ndarray, chain: np.ndarray) -> np.ndarray:
    """The run's pose at each chain node time: its latest recorded pose at or before it, moved
    on by the dead-reckoned motion since (the run's poses may be recorded at other times than
    the sightings', e.g. the EKF's at the odometry stamps)."""
    # A recorded time matches a node up to rounding (FastSLAM adds dt to the previous stamp).
    k = np.searchsorted(times, chain_times + 1e-9, side="right") - 1
    k = np.clip(k, 0, len(times) - 1)
    node = np.clip(np.searchsorted(chain_times, times[k] + 1e-9, side="right") - 1, 0, len(chain_times) - 1)
    return geometry.compose(poses[k], geometry.between(chain[node], chain))


@dataclass(frozen=True)
class RunRefinement:
    """``refine_run``'s result: the input built from the run, and the refinement."""

    input: RefinementInput
    result: LandmarkRefinement

    def as_landmark_slam_result(self, run):
        """The refinement as a ``LandmarkSlamResult`` of ``run``'s method (poses at the sightings'
        times, the refined map, every sighting's refined label in ``associations``), so the run's
        scores (``probslam.eval``) and writers apply to it; ``filter`` stays the run's."""
        from .landmark_slam import Associations, LandmarkSlamResult

        sighted = self.input.times[self.input.pose_index]
        record = Associations(sighted, self.input.truth.astype(np.int64), self.result.labels.astype(np.int64))
        return LandmarkSlamResult(run.method, self.input.times, self.result.poses, dict(self.result.landmarks),
                                  run.filter, run.seconds + self.result.seconds, record)


__all__ = ["LEAVE_ONE_OUT_RANK_TOLERANCE", "MAX_ITERATIONS", "MERGE_PROBABILITY", "ODOMETRY_COVARIANCE_FLOOR",
           "SPLIT_RUN_PROBABILITY", "UNASSIGNED", "LandmarkRefinement", "Merge", "RefinementInput", "RefinementRound",
           "RunRefinement", "Split", "compose_increments", "floor_covariances", "majority_truth",
           "merge_gate", "poses_at_nodes", "polar_to_point", "refine_landmarks", "run_labels",
           "sighting_accuracy", "split_gate"]
