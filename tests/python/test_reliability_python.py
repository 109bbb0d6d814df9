"""Issue 33's property tests of the pure-Python modules: the learned inverse model (ch. 9.3) and
the relations metric (probslam.eval). Odd arrays and values (policy.py) must give a finite result
or a ValueError / TypeError naming the argument, and a call that raised leaves the grid or model
exactly as it was. The calls covered are listed in ``COVERED``."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import policy
import probslam as ps
from probslam import eval as ev
from probslam import inverse_learning as il

#: Calls the property tests below drive with odd arguments.
COVERED = (
    "inverse_learning.field_features(grid, pose, ranges, beam_angles, max_range, half_angle)",
    "LearnedInverseModel.insert_scan(grid, pose, ranges, beam_angles, max_range, half_angle)",
    "LearnedInverseModel.probability(inputs)",
    "LearnedInverseModel.train(data, rng, max_iterations)",
    "eval.nees(error, covariance)",
    "eval.interpolate_poses(timestamps, poses, query_times)",
    "eval.relative_poses(a, b)",
    "eval.relations_error(timestamps, poses, relations)",
    "eval.ate(times_est, poses_est, times_ref, poses_ref, align, max_time_difference)",
    "eval.rpe(times_est, poses_est, times_ref, poses_ref, delta, delta_unit, align, max_time_difference)",
    "io.write_trajectory(timestamps, poses, path, format) and io.read_trajectory(path)",
    "eval.position_error(times_est, poses_est, times_ref, positions_ref)",
)

PROPERTY = policy.PROPERTY
INPUTS = 2 + il.NEIGHBOURS


def model(hidden=3):
    """A model with fixed weights, as load builds it (no training)."""
    m = il.LearnedInverseModel(hidden=hidden)
    m.weights = np.linspace(-1.0, 1.0, m.n_weights(INPUTS))
    m.mean, m.scale, m.prior = np.full(INPUTS, 0.5), np.full(INPUTS, 2.0), 0.3
    return m


def names_one_of(error, *names):
    """The policy's last rule: a refused call says which argument was wrong."""
    assert any(n in str(error) for n in names), f"{error!r} names none of {names}"


SCAN_ARGUMENTS = ("grid", "pose", "ranges", "beam_angles", "max_range", "half_angle")


def model_state(m):
    return policy.state_of(m, "hidden", "weights", "mean", "scale", "prior", "final_objective")


def grid():
    g = ps.OccupancyGrid2D(0.1, 30, 25, origin=(-1.0, -0.5))
    g.log_odds[:] = np.linspace(-1.0, 1.0, g.log_odds.size).reshape(g.log_odds.shape)
    return g


scan_values = st.one_of(policy.floats(), st.sampled_from([None, "x", True]))
beams = st.integers(0, 7).flatmap(lambda n: st.tuples(policy.arrays((n,)), policy.arrays((n,))))
pose = st.one_of(policy.arrays((3,)), policy.arrays(), policy.odd_objects())


@PROPERTY
@given(p=pose, scan=beams, max_range=scan_values, half=scan_values, absolute=st.booleans())
def test_insert_scan_changes_the_grid_only_when_it_succeeds(p, scan, max_range, half, absolute):
    m, g = model(), grid()
    state = model_state(m)
    ranges, angles = np.abs(scan[0]) if absolute else scan[0], scan[1]
    raised, out = policy.check_call(lambda: m.insert_scan(g, p, ranges, angles, max_range, half),
                                    snapshot=lambda: policy.state_of(g, "log_odds"))
    assert np.all(np.isfinite(g.log_odds))
    assert policy.same_state(state, model_state(m))
    if raised:
        names_one_of(out, *SCAN_ARGUMENTS)
    else:
        assert np.all(np.isfinite(g.probability()))


@PROPERTY
@given(p=pose, scan=beams, max_range=scan_values, half=scan_values)
def test_field_features_are_finite_or_refused(p, scan, max_range, half):
    g = grid()
    raised, out = policy.check_call(lambda: il.field_features(g, p, scan[0], scan[1], max_range, half),
                                    snapshot=lambda: policy.state_of(g, "log_odds"))
    if raised:
        names_one_of(out, *SCAN_ARGUMENTS)
    else:
        cells, x = out
        assert cells.shape[0] == x.shape[0] and np.all((cells >= 0) & (cells < g.log_odds.size))


@PROPERTY
@given(x=policy.arrays(max_side=5))
def test_probability_is_finite_or_refused(x):
    m = model()
    state = model_state(m)
    raised, out = policy.check_call(lambda: m.probability(x))
    assert policy.same_state(state, model_state(m))
    if raised:
        names_one_of(out, "inputs")
    else:
        assert np.all((out > 0) & (out < 1))


LABELS = {"bool": np.arange(6) % 2 == 0, "one class": np.zeros(6, dtype=bool), "ints": np.arange(6) % 2,
          "not 0/1": np.arange(6) * 0.5, "too few": np.ones(5, dtype=bool)}


@PROPERTY
@given(x=st.one_of(policy.arrays((6, 7), special=False), policy.arrays(max_side=6, max_dims=2)), labels=st.sampled_from(sorted(LABELS)),
       rng=st.sampled_from(["generator", 3, None]), iterations=st.sampled_from([2, 0, 2.5, True]))
def test_train_is_all_or_nothing(x, labels, rng, iterations):
    m = model()
    state = model_state(m)
    generator = np.random.default_rng(1) if rng == "generator" else rng
    raised, out = policy.check_call(lambda: m.train(il.TrainingSet(x, LABELS[labels]), generator, iterations))
    if raised:
        assert policy.same_state(state, model_state(m))
        names_one_of(out, "data", "inputs", "occupied", "rng", "max_iterations")
    else:
        assert np.all(np.isfinite(m.weights)) and 0 < m.prior < 1


@PROPERTY
@given(e=st.one_of(policy.arrays(max_side=4), policy.odd_objects()),
       p=st.one_of(policy.arrays(max_side=4), policy.odd_objects()))
def test_nees_is_finite_or_refused(e, p):
    raised, out = policy.check_call(lambda: ev.nees(e, p))
    if raised:
        names_one_of(out, "error", "covariance")


@PROPERTY
@given(e=policy.arrays((2, 3)), scale=policy.floats())
def test_nees_of_matching_shapes_is_finite_or_refused(e, scale):
    p = np.broadcast_to(np.diag([scale, 1.0, scale]), (2, 3, 3)).copy()
    raised, out = policy.check_call(lambda: ev.nees(e, p))
    if raised:
        names_one_of(out, "error", "covariance")


def sometimes_ordinary(shape):
    """Arrays of the shape, half of them without special values (so that calls get past the
    checks and into the arithmetic)."""
    return st.one_of(policy.arrays(shape, special=False), policy.arrays(shape))


trajectory = st.tuples(sometimes_ordinary((4,)), sometimes_ordinary((4, 3)))


@PROPERTY
@given(traj=trajectory, q=policy.arrays((3,)))
def test_interpolate_poses_is_finite_or_refused(traj, q):
    ts = np.sort(traj[0]) if np.all(np.isfinite(traj[0])) else traj[0]
    raised, out = policy.check_call(lambda: ev.interpolate_poses(ts, traj[1], q))
    if raised:
        names_one_of(out, "timestamps", "poses", "query_times")


@PROPERTY
@given(a=st.one_of(policy.arrays((3,)), policy.arrays((2, 3)), policy.arrays()), b=policy.arrays((2, 3)))
def test_relative_poses_are_finite_or_refused(a, b):
    raised, out = policy.check_call(lambda: ev.relative_poses(a, b))
    if raised:
        names_one_of(out, "a:", "b:", "a and b")


@PROPERTY
@given(traj=trajectory, t1=sometimes_ordinary((3,)), t2=sometimes_ordinary((3,)), delta=sometimes_ordinary((3, 3)))
def test_relations_error_is_finite_or_refused_and_leaves_the_relations(traj, t1, t2, delta):
    ts = np.sort(traj[0]) if np.all(np.isfinite(traj[0])) else traj[0]
    rel = ev.Relations(t1, t2, delta)
    raised, out = policy.check_call(lambda: ev.relations_error(ts, traj[1], rel),
                                    snapshot=lambda: policy.state_of(rel, "t1", "t2", "delta"))
    if raised:
        names_one_of(out, "timestamps", "poses", "relations")
    else:
        assert np.all(np.isfinite(out.translational)) and np.all(np.isfinite(out.rotational))
        assert np.all(t2[out.used] >= t1[out.used])


def _fields(result):
    """A TrajectoryError's numbers, for the finiteness check."""
    return {name: getattr(result, name) for name in ("errors", "rotation", "translation")} | result.statistics


def test_an_alignment_that_overflows_is_refused_by_name():
    """Found by the property below: reference positions near the largest double made the
    cross-covariance inf - inf = NaN, and numpy's SVD raised LinAlgError."""
    times, zeros, huge = np.arange(4.0), np.zeros((4, 3)), np.full((4, 3), 1e308)
    with pytest.raises(ValueError, match="^poses_est and poses_ref: the alignment overflows"):
        ev.ate(times, zeros, times, huge)
    with pytest.raises(ValueError, match="^estimate and truth: the cross-covariance overflows"):
        ev.align_rigid(zeros[:, :2], huge[:, :2])


@PROPERTY
@given(est=trajectory, ref=trajectory, align=st.sampled_from(ev.ALIGNMENTS + ("odd",)),
       limit=st.sampled_from([0.01, 1e300, 0.0, float("nan"), -1.0]),
       delta=st.sampled_from([(1, "frames"), (2, "frames"), (0.5, "m"), (1.0, "s"), (1.5, "frames"), (0, "s")]))
def test_ate_and_rpe_are_finite_or_refused(est, ref, align, limit, delta):
    """Times in any order (a clock jump is read, not refused), odd poses and options."""
    raised, out = policy.check_call(lambda: _fields(ev.ate(est[0], est[1], ref[0], ref[1], align=align,
                                                           max_time_difference=limit)))
    if raised:
        names_one_of(out, "times_est", "poses_est", "times_ref", "poses_ref", "align", "max_time_difference")
    raised, out = policy.check_call(lambda: _fields(ev.rpe(est[0], est[1], ref[0], ref[1], delta=delta[0],
                                                           delta_unit=delta[1], align=align,
                                                           max_time_difference=limit)))
    if raised:
        names_one_of(out, "times_est", "poses_est", "times_ref", "poses_ref", "align", "max_time_difference",
                     "delta")


@PROPERTY
@given(traj=trajectory, fmt=st.sampled_from(ps.io.TRAJECTORY_FORMATS))
def test_trajectory_files_are_written_finite_and_read_back_or_refused(tmp_path_factory, traj, fmt):
    path = tmp_path_factory.mktemp("traj") / f"t.{fmt}"
    raised, out = policy.check_call(lambda: ps.io.write_trajectory(traj[0], traj[1], path, format=fmt))
    if raised:
        names_one_of(out, "timestamps", "poses")
        assert not path.exists()
        return
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # times in any order are read with a warning
        read = ps.io.read_trajectory(path)
    assert read.format == fmt and len(read) == len(traj[0])
    assert np.all(np.isfinite(read.poses)) and np.all(np.isfinite(read.timestamps))


@PROPERTY
@given(est=trajectory, ref=st.tuples(sometimes_ordinary((5,)), sometimes_ordinary((5, 2))),
       positions=st.booleans())
def test_position_error_is_finite_or_refused(est, ref, positions):
    """Estimate times sorted when they can be (else refused by name), the reference's in any
    order, odd values; (N, 2) positions as well as (N, 3) poses."""
    ts = np.sort(est[0]) if np.all(np.isfinite(est[0])) else est[0]
    poses = est[1][:, :2] if positions and np.ndim(est[1]) == 2 else est[1]

    def call():
        r = ev.position_error(ts, poses, ref[0], ref[1])
        return {"errors": r.errors, "errors_aligned": r.errors_aligned, "rmse": r.rmse,
                "rmse_aligned": r.rmse_aligned, "rotation": r.rotation, "translation": r.translation}

    raised, out = policy.check_call(call)
    if raised:
        names_one_of(out, "times_est", "poses_est", "times_ref", "positions_ref")
