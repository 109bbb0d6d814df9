"""probslam.refine_landmarks, GraphSLAM's correspondence test (ch. 11.6) after a filter, against
brute force: on a simulated run with an injected duplicate (one landmark under two labels) and
wrong sightings (labels swapped to a far landmark), every round's merges equal the test of every
landmark pair, and its splits the test of every sighting, both on the dense inverse of the same
linearised problem built here (numerical Jacobians of the edge errors, nothing of the
library's); the leave-one-out statistics are computed by removing the sighting and solving
again, not by the Woodbury identity the module uses. Also: the noise estimate against the
simulator's noise, the Cartesian edges against exact range-bearing residuals, the odometry
composition against sequential propagation, the real MRCLAM robot 1 when the shared data is
present, and bad input."""

import collections

import numpy as np
import pytest

import probslam
from probslam import landmark_refine as lr
from probslam import sim

Q = np.diag([0.05, 0.01]) ** 2  # range m, bearing rad
#: Per step, pose space; isotropic in x and y, so the same in the robot's frame as in the world's.
MOTION = np.diag([0.03, 0.03, 0.01]) ** 2
DT = 0.5
V, W = 1.0, 0.2  # a circle of radius 5 m
#: Numerical Jacobians by central differences: error ~ step^2 and ~1e-16 / step, about 1e-10.
STEP = 1e-6
#: Statistics of the module (sparse joint marginals, Woodbury) and of brute force (dense inverse,
#: removal, numerical Jacobians) agree to this relative difference (measured: below 1e-7).
AGREE = 1e-5


def _relative_motion():
    return probslam.velocity_motion(np.zeros(3), V, W, DT)


def simulated(seed, steps=80, n=16):
    """A simulated run as refine_landmarks takes it: the start and one pose per step, the
    commanded motion as odometry, the true landmark of each sighting."""
    rng = np.random.default_rng(seed)
    world = sim.LandmarkWorld.random(n, 7.0, rng, min_separation=2.0)
    world.landmarks += [0.0, 5.0]  # around the circle's centre
    run = sim.simulate(world, sim.circle_controls(steps, V, W), DT, sim.Sensor(Q, max_range=5.0, fov=np.pi),
                       MOTION, rng)
    odometry = np.tile(_relative_motion(), (steps, 1))
    dead = [np.zeros(3)]
    for d in odometry:
        dead.append(lr._compose_pose(dead[-1][None], d[None])[0])
    pose_index = np.concatenate([np.full(len(z), k + 1) for k, z in enumerate(run.measurements)]).astype(np.int64)
    return dict(poses=np.array(dead), odometry=odometry, odometry_covariances=np.tile(MOTION, (steps, 1, 1)),
                pose_index=pose_index, measurements=np.vstack(run.measurements),
                truth=np.concatenate(run.ids).astype(np.int64), world=world.landmarks, true_poses=run.poses)


def injected(problem):
    """The truth with errors a filter makes: the most seen landmark's later sightings under a
    new label (a duplicate), and four sightings each moved to a landmark at least 4 m from their
    own that their scan does not see (wrong sightings). Returns labels and what was injected."""
    truth, index, world = problem["truth"], problem["pose_index"], problem["world"]
    labels = truth.copy()
    counts = collections.Counter(truth.tolist())
    dup = counts.most_common(1)[0][0]
    rows = np.flatnonzero(truth == dup)
    labels[rows[len(rows) // 2:]] = world.shape[0]  # a label no landmark has
    wrong = []
    rng = np.random.default_rng(1)
    for i in rng.permutation(len(truth)):
        if len(wrong) == 4:
            break
        if truth[i] == dup or counts[int(truth[i])] < 4 or any(index[j] == index[i] for j in wrong):
            continue
        seen = set(labels[index == index[i]].tolist())
        far = [k for k in range(len(world)) if np.hypot(*(world[k] - world[truth[i]])) > 4.0 and k not in seen
               and counts[k] >= 2]
        if far:
            labels[i] = far[0]
            wrong.append(int(i))
    return labels, dup, wrong


def arguments(problem, labels):
    return dict(poses=problem["poses"], odometry=problem["odometry"],
                odometry_covariances=problem["odometry_covariances"], pose_index=problem["pose_index"],
                measurements=problem["measurements"], labels=labels, measurement_noise=Q)


# ---------------------------------------------------------------------------------------------
# Brute force: the dense problem of one round, written from the edge errors alone.


def _rotation(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def point_error(x, m, z):
    """The point in the pose's frame minus the measured point."""
    return _rotation(x[2]).T @ (m - x[:2]) - z


def pose_error(a, b, z):
    """t2v(z^-1 a^-1 b)."""
    rel = _rotation(a[2]).T @ (b[:2] - a[:2])
    e = _rotation(z[2]).T @ (rel - z[:2])
    return np.array([e[0], e[1], np.arctan2(np.sin(b[2] - a[2] - z[2]), np.cos(b[2] - a[2] - z[2]))])


def numerical_jacobian(f, x):
    cols = []
    for k in range(len(x)):
        d = np.zeros(len(x))
        d[k] = STEP
        cols.append((f(x + d) - f(x - d)) / (2 * STEP))
    return np.column_stack(cols)


class Dense:
    """The information matrix H, gradient g and per-sighting linearisation of a round's graph:
    poses 1.. T-1 (pose 0 held) then the landmarks of the round's labels, sorted."""

    def __init__(self, problem, rnd):
        poses, labels, marks = rnd.poses, rnd.labels, rnd.landmarks
        scale = rnd.noise_scale
        t = len(poses)
        self.labels = sorted(marks)
        self.slot = {lab: 3 * (t - 1) + 2 * k for k, lab in enumerate(self.labels)}
        n = 3 * (t - 1) + 2 * len(self.labels)
        self.h, self.g = np.zeros((n, n)), np.zeros(n)
        odo_info = np.linalg.inv(problem["odometry_covariances"] * scale[0] ** 2)
        for k in range(t - 1):
            xa, xb, z = poses[k], poses[k + 1], problem["odometry"][k]
            e = pose_error(xa, xb, z)
            j = numerical_jacobian(lambda y: pose_error(y[:3], y[3:], z), np.r_[xa, xb])
            cols = ([] if k == 0 else list(range(3 * (k - 1), 3 * k))) + list(range(3 * k, 3 * k + 3))
            jj = j if k > 0 else j[:, 3:]
            self._add(cols, jj, odo_info[k], e)
        s = np.diag(scale[1:])
        r, phi = problem["measurements"][:, 0], problem["measurements"][:, 1]
        self.z = np.column_stack([r * np.cos(phi), r * np.sin(phi)])
        self.z_cov, self.rows, self.e, self.j, self.cols = {}, [], {}, {}, {}
        for i in range(len(labels)):
            polar = np.array([[np.cos(phi[i]), -r[i] * np.sin(phi[i])], [np.sin(phi[i]), r[i] * np.cos(phi[i])]])
            self.z_cov[i] = polar @ s @ Q @ s @ polar.T
        for i in np.flatnonzero(labels >= 0):
            k = int(problem["pose_index"][i])
            e, j, cols = self.linearise(poses, marks, i, k, int(labels[i]))
            self.e[i], self.j[i], self.cols[i] = e, j, cols
            self._add(cols, j, np.linalg.inv(self.z_cov[i]), e)
            self.rows.append(int(i))
        self.poses, self.marks, self.t = poses, marks, t
        self.pose_index = problem["pose_index"]

    def linearise(self, poses, marks, i, k, label):
        x, m = poses[k], marks[label]
        e = point_error(x, m, self.z[i])
        j = numerical_jacobian(lambda y: point_error(y[:3], y[3:], self.z[i]), np.r_[x, m])
        cols = ([] if k == 0 else list(range(3 * (k - 1), 3 * k))) + list(range(self.slot[label], self.slot[label] + 2))
        return e, (j if k > 0 else j[:, 3:]), cols

    def _add(self, cols, j, info, e):
        self.h[np.ix_(cols, cols)] += j.T @ info @ j
        self.g[cols] += j.T @ info @ e

    def pair_distances(self, sigma):
        """Every pair of labels: squared Mahalanobis distance of their difference."""
        out = {}
        for a_i, a in enumerate(self.labels):
            for b in self.labels[a_i + 1:]:
                sa, sb = slice(self.slot[a], self.slot[a] + 2), slice(self.slot[b], self.slot[b] + 2)
                cov = sigma[sa, sa] + sigma[sb, sb] - sigma[sa, sb] - sigma[sb, sa]
                mu = self.marks[a] - self.marks[b]
                out[(a, b)] = float(mu @ np.linalg.solve(cov, mu))
        return out

    def row(self, i, label=None):
        """(residual, dense Jacobian row block (2, n)) of sighting i against its landmark, or
        against ``label``."""
        k = int(self.pose_index[i])
        e, j, cols = (self.e[i], self.j[i], self.cols[i]) if label is None else \
            self.linearise(self.poses, self.marks, i, k, label)
        jrow = np.zeros((2, len(self.g)))
        jrow[:, cols] = j
        return e, jrow

    def without(self, rows):
        """H and g of the linearised problem with sightings ``rows`` removed."""
        h, g = self.h.copy(), self.g.copy()
        for i in rows:
            e, jrow = self.row(i)
            info = np.linalg.inv(self.z_cov[i])
            h -= jrow.T @ info @ jrow
            g -= jrow.T @ info @ e
        return h, g

    def statistic(self, h, g, i, label=None, log_det=False):
        """Sighting i's squared Mahalanobis distance to its landmark (or ``label``) under the
        linearised problem (h, g) it is not part of, solved densely (with ``log_det``, also the
        log determinant of its innovation covariance)."""
        e, jrow = self.row(i, label)
        solved = np.linalg.solve(h, np.column_stack([g, jrow.T]))  # H^-1 g, H^-1 J^T
        v = e - jrow @ solved[:, 0]  # the residual after the solve's step -H^-1 g
        cov = self.z_cov[i] + jrow @ solved[:, 1:]
        x = float(v @ np.linalg.solve(cov, v))
        return (x, float(np.linalg.slogdet(cov)[1])) if log_det else x

    def statistics(self, h, g, i, labels):
        """``statistic(h, g, i, c, log_det=True)`` for every label c, from one solve."""
        rows = [self.row(i, c) for c in labels]
        solved = np.linalg.solve(h, np.column_stack([g] + [jrow.T for _, jrow in rows]))
        out = {}
        for n, (c, (e, jrow)) in enumerate(zip(labels, rows)):
            v = e - jrow @ solved[:, 0]
            cov = self.z_cov[i] + jrow @ solved[:, 1 + 2 * n:3 + 2 * n]
            out[c] = (float(v @ np.linalg.solve(cov, v)), float(np.linalg.slogdet(cov)[1]))
        return out

    def leave_one_out(self, i):
        return self.statistic(*self.without([i]), i)


def brute_force(problem, rnd):
    dense = Dense(problem, rnd)
    return dense, np.linalg.inv(dense.h)


def co_observed(labels, index):
    pairs = set()
    for k in np.unique(index):
        held = sorted(set(labels[(index == k) & (labels >= 0)].tolist()))
        pairs.update((a, b) for n, a in enumerate(held) for b in held[n + 1:])
    return pairs


@pytest.fixture(scope="module")
def refined():
    problem = simulated(seed=4)
    labels, dup, wrong = injected(problem)
    result = probslam.refine_landmarks(**arguments(problem, labels), estimate_noise=False)
    return problem, labels, dup, wrong, result


def test_the_injected_errors_are_undone(refined):
    problem, labels, dup, wrong, result = refined
    truth = problem["truth"]
    assert len(wrong) == 4
    before, after = lr.sighting_accuracy(labels, truth), lr.sighting_accuracy(result.labels, truth)
    assert after > before
    assert after == 1.0
    assert len(result.landmarks) == len(set(truth.tolist()))
    merged = {frozenset((m.kept, m.merged)) for m in result.merges}
    assert frozenset((dup, 16)) in merged
    # Every merge joins two labels of one landmark; only the injected sightings left theirs
    # (one may first found a landmark of its own, which then merges with its true one).
    label_truth = lr.majority_truth(labels, truth)
    for m in result.merges:
        kept, gone = (label_truth.get(x, None) for x in (m.kept, m.merged))
        assert kept is None or gone is None or kept == gone
    assert sorted(s.sighting for s in result.splits if s.reason == "gate") == sorted(wrong)
    final_truth = lr.majority_truth(result.labels, truth)
    assert all(final_truth[int(result.labels[i])] == truth[i] for i in wrong)
    assert result.converged and result.iterations == len(result.rounds)
    # The last round changed nothing; its optimum is the result.
    np.testing.assert_array_equal(result.rounds[-1].labels, result.labels)
    np.testing.assert_allclose(result.rounds[-1].poses, result.poses)


def test_every_rounds_merges_equal_the_brute_force_pair_test(refined):
    problem, _, _, _, result = refined
    assert any(r.merges for r in result.rounds)
    for rnd in result.rounds:
        dense, sigma = brute_force(problem, rnd)
        d2 = dense.pair_distances(sigma)
        excluded = co_observed(rnd.labels, problem["pose_index"])
        passing = {p for p, x in d2.items() if x <= result.merge_gate and p not in excluded}
        tested = {(int(a), int(b)): x for a, b, x in rnd.pair_tests}
        assert {p for p, x in tested.items() if x <= result.merge_gate} == passing
        for p, x in tested.items():  # the gated pairs it tested, at the brute force's value
            assert x == pytest.approx(d2[p], rel=AGREE)
        # The pairs it did not test fail (the spatial gate is exact, not a heuristic).
        assert all(d2[p] > result.merge_gate or p in excluded for p in d2 if p not in tested)
        assert {(min(m.kept, m.merged), max(m.kept, m.merged)) for m in rnd.merges} <= passing


def test_every_rounds_splits_equal_the_brute_force_sighting_test(refined):
    """Each round without merges against brute force: every sighting's leave-one-out statistic
    by removal and a dense solve; then the backward elimination done literally (remove the worst
    suspect, solve again, test the remaining suspects again); then each leaver's candidates under
    the problem without all the round's leavers. A round where none left moves sightings by the
    likelihood ratio: every sighting against every landmark, each without itself."""
    problem, _, _, _, result = refined
    split_rounds = [r for r in result.rounds if not r.merges]
    assert any(s.reason == "gate" for r in split_rounds for s in r.splits)
    assert any(s.reason == "likelihood" for r in split_rounds for s in r.splits)
    index = problem["pose_index"]
    gate = result.split_gate
    for rnd in split_rounds:
        dense, _ = brute_force(problem, rnd)
        counts = collections.Counter(rnd.labels[rnd.labels >= 0].tolist())
        own = {i: dense.leave_one_out(i) for i in dense.rows if counts[int(rnd.labels[i])] >= 2}
        tested = {i: x for i, x in enumerate(rnd.sighting_tests) if np.isfinite(x)}
        assert set(tested) == set(own)
        for i, x in tested.items():
            assert x == pytest.approx(own[i], rel=AGREE, abs=1e-9)
        remaining = sorted((i for i, x in own.items() if x > gate), key=lambda i: -own[i])
        left = []
        while remaining:
            current = {i: dense.statistic(*dense.without([i for i, _ in left] + [i]), i) for i in remaining}
            worst = max(current, key=current.get)
            if current[worst] <= gate:
                break
            left.append((worst, current[worst]))
            remaining.remove(worst)
        gate_moves = [s for s in rnd.splits if s.reason == "gate"]
        assert [s.sighting for s in gate_moves] == [i for i, _ in left]
        for s, (_, x) in zip(gate_moves, left):
            assert s.distance2 == pytest.approx(x, rel=AGREE)
        h, g = dense.without([i for i, _ in left])
        labels = rnd.labels.copy()
        for s in gate_moves:
            i = s.sighting
            scan = set(labels[index == index[i]].tolist()) - {labels[i]}
            others = {c: dense.statistic(h, g, i, c, log_det=True) for c in dense.labels
                      if c != rnd.labels[i] and c not in scan}
            passing = sorted((x + ld, x, c) for c, (x, ld) in others.items() if x <= gate)
            if passing:
                assert (s.new, s.created) == (passing[0][2], False)
                assert s.new_distance2 == pytest.approx(passing[0][1], rel=AGREE)
            else:
                assert s.new == lr.UNASSIGNED and np.isnan(s.new_distance2)
            labels[i] = s.new
        if left:
            assert all(s.reason == "gate" for s in rnd.splits)
            continue
        # The likelihood moves: the best gain per sighting, then applied best first.
        best = {}
        for i in range(len(rnd.labels)):
            own_label = int(rnd.labels[i])
            if own_label >= 0 and i not in own:
                continue  # its landmark rests on it alone
            if own_label >= 0:
                h, g = dense.without([i])
                x_own, ld_own = dense.statistic(h, g, i, log_det=True)
                score = x_own + ld_own
            else:
                h, g, score = dense.h, dense.g, None
            for c, (x, ld) in dense.statistics(h, g, i, [c for c in dense.labels if c != own_label]).items():
                gain = (score - (x + ld)) if score is not None else -(x + ld)
                if x <= gate and (score is None or gain > lr.REASSOCIATION_MARGIN) and \
                        gain > best.get(i, (-np.inf,))[0]:
                    best[i] = (gain, c, x)
        held = collections.defaultdict(set)
        for i in np.flatnonzero(rnd.labels >= 0):
            held[int(index[i])].add(int(rnd.labels[i]))
        expected = []
        for i in sorted(best, key=lambda i: (rnd.labels[i] < 0, -best[i][0], i)):
            gain, c, x = best[i]
            scan = held[int(index[i])]
            if c in scan:
                continue
            scan.discard(int(rnd.labels[i]))
            scan.add(c)
            expected.append((i, c, x))
        assert [(s.sighting, s.new) for s in rnd.splits] == [(i, c) for i, c, _ in expected]
        for s, (_, _, x) in zip(rnd.splits, expected):
            assert s.new_distance2 == pytest.approx(x, rel=AGREE)
