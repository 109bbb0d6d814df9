"""``refine_landmarks``: the rounds of optimise, test and change (see the package's docstring)."""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np

from .._args import positive_real, require_integer
from .arguments import _check_input
from .gates import MERGE_PROBABILITY, SPLIT_RUN_PROBABILITY, merge_gate, split_gate
from .merges import _candidate_pairs, _co_observed, _merge_groups, _pair_distances
from .moves import _likelihood_moves
from .noise import NOISE_MAX_ITERATIONS, NOISE_TOLERANCE, _scaled_polar, _variance_factors
from .problem import UNASSIGNED, _Graph, _Problem, _placed
from .results import LandmarkRefinement, Merge, RefinementRound, Split
from .sightings import _sighting_statistics
from .splits import _split_moves


#: Rounds of optimise-test-change at most.
MAX_ITERATIONS = 30


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
    max_iterations = check_options(merge_probability, split_probability, max_iterations, estimate_noise,
                                    new_landmarks)
    _require_one_label_per_scan(index, labels)
    problem = _Problem(poses.copy(), odometry, odo_cov, index, z_polar, np.array(q), labels.copy())
    labelled = np.flatnonzero(labels != UNASSIGNED)
    _start_landmarks(problem, labelled, values)
    run = _Run(merge_gate(merge_probability), split_gate(max(len(labelled), 1), split_probability),
               int(labels.max()) + 1 if len(labels) else 0, new_landmarks)
    converged, chi2, g = False, float("nan"), None
    while True:
        g = _Graph(problem) if len(labelled) else None
        chi2 = g.optimize(problem) if g is not None and g.graph.num_pose_edges + g.graph.num_point_edges else 0.0
        if len(run.rounds) >= max_iterations or g is None:
            converged = g is None
            break
        counts = collections.Counter(int(x) for x in problem.labels[problem.labels != UNASSIGNED])
        if estimate_noise and not run.rounds:
            g, chi2 = _estimate_noise(g, problem, counts, run, odo_cov, q)
        if not _round(g, problem, counts, run):
            converged = True
            break
    return _result(problem, g, run, converged, chi2, time.perf_counter() - start)


def check_options(merge_probability, split_probability, max_iterations, estimate_noise, new_landmarks) -> int:
    """``refine_landmarks``' options checked (ValueError / TypeError naming the option); max_iterations
    as an int."""
    for name, p in (("merge_probability", merge_probability), ("split_probability", split_probability)):
        if positive_real(p, name) >= 1.0:
            raise ValueError(f"{name} must lie in (0, 1), got {p!r}")
    max_iterations = require_integer(max_iterations, "max_iterations", 0, 10 ** 6)
    for name, flag in (("estimate_noise", estimate_noise), ("new_landmarks", new_landmarks)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"{name} must be a bool, got {type(flag).__name__}")
    return max_iterations


def _require_one_label_per_scan(index: np.ndarray, labels: np.ndarray) -> None:
    """One scan sees distinct landmarks: two sightings of a pose with one label are a bad input."""
    order = np.lexsort((labels, index))
    twice = (np.diff(index[order]) == 0) & (np.diff(labels[order]) == 0) & (labels[order][1:] != UNASSIGNED)
    if twice.any():
        raise ValueError(f"labels: two sightings of pose {index[order][1:][twice][0]} (one scan) name the same "
                         "landmark")


def _start_landmarks(problem: _Problem, labelled: np.ndarray, values: Dict[int, np.ndarray]) -> None:
    """Each label's landmark at its given value, else at the mean of its sightings placed from
    the filter's poses."""
    labels = problem.labels
    points = _placed(problem, labelled)
    for label in np.unique(labels[labelled]):
        label = int(label)
        problem.landmarks[label] = values.get(label, points[labels[labelled] == label].mean(axis=0))


@dataclass
class _Run:
    """The gates, the next free label, and what the rounds so far changed."""

    gate_merge: float
    gate_split: float
    next_label: int
    new_landmarks: bool
    merges: List[Merge] = field(default_factory=list)
    splits: List[Split] = field(default_factory=list)
    rounds: List[RefinementRound] = field(default_factory=list)
    variance: np.ndarray = field(default_factory=lambda: np.ones(3))  # odometry, range, bearing over the given


def _estimate_noise(g: _Graph, problem: _Problem, counts, run: _Run, odo_cov: np.ndarray, q: np.ndarray):
    """Step 0: the noise rescaled by variance components until every factor is within
    NOISE_TOLERANCE of 1 (the optimisations between two estimates to NOISE_OPTIMIZE_TOLERANCE),
    then the optimum the tests need. Returns the graph and its chi2."""
    for _ in range(NOISE_MAX_ITERATIONS):
        factors = _variance_factors(g, problem, _sighting_statistics(g, problem, counts), run.gate_split)
        if np.all(np.abs(factors - 1.0) <= NOISE_TOLERANCE):
            break
        run.variance *= factors
        problem.set_noise(odo_cov * run.variance[0], _scaled_polar(q, run.variance[1:]))
        g = _Graph(problem)
        g.optimize(problem, precise=False)
    return g, g.optimize(problem)  # the tests' minimum


def _round(g: _Graph, problem: _Problem, counts, run: _Run) -> bool:
    """One round at the optimum of ``g``: merges (step 1), else splits (step 2), else moves
    (step 3), applied to ``problem`` and recorded in ``run``. Whether it changed anything."""
    iteration = len(run.rounds)
    before = problem.labels.copy()
    pairs = _candidate_pairs(g, problem, run.gate_merge, _co_observed(problem))
    d2 = _pair_distances(g, problem, pairs)
    passing = [(a, b, float(x)) for (a, b), x in zip(pairs, d2) if x <= run.gate_merge]
    merges = [Merge(iteration, kept, gone, d, float(np.exp(-0.5 * d)))
              for kept, gone, d in _merge_groups(passing, counts)]
    stats = np.full(len(problem.labels), np.nan)
    splits: List[Split] = []
    if merges:
        _apply_merges(problem, merges)
    else:
        tests = _sighting_statistics(g, problem, counts)
        stats = tests.stats
        splits = _split_moves(g, problem, tests, run.gate_split, run.next_label, iteration, run.new_landmarks)
        if not splits:
            splits = _likelihood_moves(g, problem, tests, run.gate_split, iteration)
        run.next_label = _apply_splits(problem, splits, run.next_label)
    run.rounds.append(RefinementRound(iteration, before, problem.poses.copy(),
                                      {k: v.copy() for k, v in problem.landmarks.items() if k in g.slot},
                                      np.array([(a, b, x) for (a, b), x in zip(pairs, d2)]).reshape(-1, 3),
                                      stats, tuple(merges), tuple(splits), np.sqrt(run.variance)))
    run.merges.extend(merges)
    run.splits.extend(splits)
    return bool(merges or splits)


def _apply_merges(problem: _Problem, merges: List[Merge]) -> None:
    """Each merged label's sightings to the kept one; the landmarks a sighting has left follow."""
    target = {m.merged: m.kept for m in merges}
    problem.labels = np.array([target.get(int(x), int(x)) for x in problem.labels], dtype=np.int64)
    for i, gone in problem.left.items():
        problem.left[i] = {target.get(x, x) for x in gone}


def _apply_splits(problem: _Problem, splits: List[Split], next_label: int) -> int:
    """Each sighting to its new label (a created landmark placed at the sighting), its old one
    remembered as left. Returns the next free label."""
    for s in splits:
        if s.old != UNASSIGNED:
            problem.left[s.sighting].add(s.old)
        problem.labels[s.sighting] = s.new
        if s.created:
            problem.landmarks[s.new] = _placed(problem, np.array([s.sighting]))[0]
            next_label = max(next_label, s.new + 1)
    return next_label


def _result(problem: _Problem, g: Optional[_Graph], run: _Run, converged: bool, chi2: float,
            seconds: float) -> LandmarkRefinement:
    """The refined solution: the landmarks that hold a sighting, with their marginals."""
    held = sorted({int(x) for x in problem.labels[problem.labels != UNASSIGNED]})
    # The last graph is the one of the final labels (a round that changed them is followed by a
    # new graph before the loop ends), optimised: its marginals are the final map's.
    covariances = {} if g is None else {int(k): c for k, c in zip(g.labels, g.landmark_marginals())}
    return LandmarkRefinement(problem.poses.copy(), {k: problem.landmarks[k].copy() for k in held},
                              problem.labels.copy(), tuple(run.merges), tuple(run.splits), len(run.rounds), converged,
                              run.gate_merge, run.gate_split, chi2, seconds, tuple(run.rounds),
                              np.sqrt(run.variance), {k: covariances[k] for k in held})
