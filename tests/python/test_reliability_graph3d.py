"""Issue 48 for the 3-D pose graph: property tests of PoseGraph3D's public calls (a failing call
leaves every field as it was, compared field by field; a result is finite; set_poses /
set_points are tested with the 2-D graph's in test_reliability_graph.py), and errors that
name the argument across the graph APIs (2-D and 3-D) instead of pybind11's list of signatures."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import policy
import probslam
from probslam import graph as pg
from test_pose_graph import two_pose_graph

#: The public calls the property tests below (and test_reliability_graph's set_values) exercise.
COVERED = (
    "PoseGraph3D.add_pose", "PoseGraph3D.add_point", "PoseGraph3D.add_pose_edge", "PoseGraph3D.add_point_edge",
    "PoseGraph3D.add_pose_prior", "PoseGraph3D.set_fixed", "PoseGraph3D.set_poses", "PoseGraph3D.set_points",
    "optimize", "marginal_covariances", "joint_marginal_covariances", "initialize_odometry", "initialize_chordal",
    "optimize_incremental",
)

PROPERTY = policy.PROPERTY


def graph3d_state(g):
    return policy.state_of(g, "pose_ids", "point_ids", "poses", "points", "edge_ids", "pose_edges", "point_edges",
                           "pose_priors", "num_pose_edges", "num_point_edges", "num_pose_priors", "num_vertices")


def row(rotvec, t):
    return np.concatenate([t, Rotation.from_rotvec(rotvec).as_quat()])


def small_graph3d(seed=3):
    """Five poses in a loop, a prior, two points seen through an offset."""
    rng = np.random.default_rng(seed)
    g = probslam.PoseGraph3D()
    for i in range(5):
        g.add_pose(i, row(0.1 * rng.normal(size=3), [i, 0.1 * i, 0.0]))
    for i in range(5):
        g.add_pose_edge(i, (i + 1) % 5, row(0.05 * rng.normal(size=3), rng.normal(size=3)), np.eye(6) * 10)
    g.add_pose_prior(0, row(np.zeros(3), np.zeros(3)), np.eye(6))
    for k in (10, 11):
        g.add_point(k, rng.normal(size=3))
        g.add_point_edge(k - 10, k, rng.normal(size=3), np.eye(3), offset=row([0, 0, 0.2], [0.1, 0, 0.3]))
        g.add_point_edge(k - 8, k, rng.normal(size=3), np.eye(3))
    return g


SOME_IDS = st.one_of(st.sampled_from([0, 1, 2, 3, 4, 10, 11, 100]), st.integers(-3, 110), st.just(2**31),
                     st.just(2**40))


@PROPERTY
@given(vid=SOME_IDS,
       value=st.one_of(policy.arrays(shape=(7,)), policy.arrays(shape=(3,)), policy.arrays(max_dims=2),
                       policy.odd_objects()),
       info=st.one_of(policy.arrays(shape=(6, 6)), policy.arrays(shape=(3, 3)), policy.arrays(max_dims=3),
                      policy.odd_objects()),
       kind=st.sampled_from(["pose", "point", "pose_edge", "point_edge", "prior", "fix", "unfix"]))
def test_property_construction(vid, value, info, kind):
    g = small_graph3d()
    calls = {
        "pose": lambda: g.add_pose(vid, value),
        "point": lambda: g.add_point(vid, value),
        "pose_edge": lambda: g.add_pose_edge(0, vid, value, info),
        "point_edge": lambda: g.add_point_edge(vid, 10, value, info),
        "prior": lambda: g.add_pose_prior(vid, value, info),
        "fix": lambda: g.set_fixed(vid),
        "unfix": lambda: g.set_fixed(vid, value),
    }
    policy.check_call(calls[kind], snapshot=lambda: graph3d_state(g))


@PROPERTY
@given(scale=policy.floats(), info_scale=st.sampled_from([1e-12, 1.0, 1e12, 1e200]),
       algorithm=st.sampled_from(["gauss-newton", "levenberg-marquardt"]),
       kernel=st.sampled_from(["none", "huber", "cauchy"]), width=policy.floats(),
       iterations=st.integers(-1, 20), tolerance=policy.floats())
def test_property_optimize(scale, info_scale, algorithm, kernel, width, iterations, tolerance):
    g = small_graph3d()
    with np.errstate(all="ignore"):
        poses = g.poses[1:].copy()
        poses[:, :3] *= scale
    try:
        g.set_poses(g.pose_ids[1:], poses)
    except ValueError:
        pass
    g.add_pose_edge(0, 3, row([0, 0, 0.3], [1.0, 2.0, 0.0]), info_scale * np.eye(6))
    raised, result = policy.check_call(
        lambda: probslam.optimize(g, algorithm=algorithm, kernel=kernel, kernel_width=width,
                                  max_iterations=iterations, relative_tolerance=tolerance),
        snapshot=lambda: graph3d_state(g))
    if not raised:
        assert np.isfinite(result.chi2) and policy.all_finite(g.poses) and policy.all_finite(g.points)


@PROPERTY
@given(ids=st.one_of(st.lists(SOME_IDS, max_size=4), policy.odd_objects()),
       groups=st.one_of(st.lists(st.lists(SOME_IDS, max_size=3), max_size=3), policy.odd_objects()))
def test_property_marginals(ids, groups):
    g = small_graph3d()
    policy.check_call(lambda: probslam.marginal_covariances(g, ids), snapshot=lambda: graph3d_state(g))
    policy.check_call(lambda: probslam.joint_marginal_covariances(g, groups), snapshot=lambda: graph3d_state(g))


@PROPERTY
@given(scale=policy.floats(), step=st.one_of(st.integers(-2, 8), policy.odd_objects()), fix=st.booleans())
def test_property_initialisation(scale, step, fix):
    g = small_graph3d()
    if fix:
        g.set_fixed(3)
    with np.errstate(all="ignore"):
        try:
            g.add_pose_edge(1, 4, row([0, 0, 0], [scale, scale, 0.0]), np.eye(6))
        except ValueError:
            pass
    policy.check_call(lambda: pg.initialize_odometry(g), snapshot=lambda: graph3d_state(g))
    policy.check_call(lambda: pg.initialize_chordal(g), snapshot=lambda: graph3d_state(g))
    policy.check_call(lambda: pg.optimize_incremental(g, poses_per_step=step), snapshot=lambda: graph3d_state(g))


# ---------------------------------------------------------------- errors that name the argument

BAD_CALLS = [  # (call on a graph, the argument the one-line error must name)
    (lambda g: g.set_fixed(1, "x"), "fixed"),
    (lambda g: g.set_fixed(1, 1), "fixed"),
    (lambda g: g.set_fixed("1"), "id"),
    (lambda g: probslam.marginal_covariances(g, [2**40]), "ids"),
    (lambda g: probslam.marginal_covariances(g, "01"), "ids"),
    (lambda g: probslam.marginal_covariances(g, [0.5]), "ids"),
    (lambda g: probslam.joint_marginal_covariances(g, [[0], [2**40]]), r"groups\[1\]"),
    (lambda g: probslam.joint_marginal_covariances(g, 3), "groups"),
    (lambda g: probslam.marginal_covariances(g, [0], method=3), "method"),
    (lambda g: probslam.marginal_covariances(g, [0], options={"method": "auto"}), "options"),
    (lambda g: probslam.joint_marginal_covariances(g, [[0]], ordering="nd"), "ordering"),
    (lambda g: probslam.optimize(g, algorithm=None), "algorithm"),
    (lambda g: probslam.optimize(g, relative_tolerance="small"), "relative_tolerance"),
    (lambda g: probslam.optimize(g, step_tolerance=[1e-3]), "step_tolerance"),
    (lambda g: probslam.optimize(g, kernel_width="1"), "kernel_width"),
    (lambda g: probslam.optimize(g, damping=1), "damping"),
    (lambda g: probslam.optimize(g, linear_solver={"ordering": "nd"}), r"linear_solver\.ordering"),
    (lambda g: probslam.optimize(g, linear_solver="simplicial"), "linear_solver"),
    (lambda g: probslam.optimize(g, max_iterations=-1), "max_iterations"),
    (lambda g: probslam.optimize_incremental(g, step={"kernel": 0}), r"step\.kernel"),
    (lambda g: probslam.optimize_incremental(g, step={"relative_tolerance": None}), r"step\.relative_tolerance"),
    (lambda g: probslam.optimize_incremental(g, step={"max_iterations": -1}), r"step\.max_iterations"),
    (lambda g: probslam.optimize_incremental(g, poses_per_step=0), "poses_per_step"),
]


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("call, name", BAD_CALLS)
def test_bad_arguments_are_named_in_one_line(dim, call, name):
    # Issue 48: these gave pybind11's multi-line "incompatible function arguments" list.
    g = two_pose_graph() if dim == 2 else small_graph3d()
    before = graph3d_state(g) if dim == 3 else policy.state_of(g, "poses", "points", "edge_ids")
    with pytest.raises((TypeError, ValueError), match=f"^{name}") as caught:
        call(g)
    assert "\n" not in str(caught.value) and "incompatible function arguments" not in str(caught.value)
    after = graph3d_state(g) if dim == 3 else policy.state_of(g, "poses", "points", "edge_ids")
    assert policy.same_state(before, after)


# ---------------------------------------------------------------- a graph of the wrong type

#: The functions that take a PoseGraph2D or a PoseGraph3D, with the arguments after the graph.
EITHER_GRAPH = [
    (probslam.optimize, {}),
    (probslam.optimize, {"algorithm": "levenberg-marquardt", "callback": lambda i, chi2: True}),
    (probslam.optimize_incremental, {"poses_per_step": 2}),
    (probslam.marginal_covariances, {"ids": [0]}),
    (probslam.marginal_covariances, {"ids": [0], "method": "simplicial", "ordering": "amd"}),
    (probslam.joint_marginal_covariances, {"groups": [[0, 1]]}),
    (probslam.initialize_odometry, {}),
]
#: Objects that are no pose graph: an int, None, an array, a path, another probslam class.
NOT_GRAPHS = [3, None, np.zeros((3, 3)), "graph.g2o", probslam.Pose2()]


@pytest.mark.parametrize("function, options", EITHER_GRAPH)
@pytest.mark.parametrize("wrong", NOT_GRAPHS, ids=lambda w: type(w).__name__)
def test_a_wrong_graph_is_a_type_error_naming_graph(function, options, wrong):
    # Issue 48: a typed overload per graph class answered with pybind11's list of signatures.
    positional = list(options.values())[:1] if function in (probslam.marginal_covariances,
                                                             probslam.joint_marginal_covariances) else []
    rest = dict(list(options.items())[len(positional):])
    for call in (lambda: function(wrong, *positional, **rest), lambda: function(graph=wrong, **options)):
        with pytest.raises(TypeError, match=r"^graph: expected a PoseGraph2D or PoseGraph3D, got ") as caught:
            call()
        assert type(wrong).__name__ in str(caught.value) and "\n" not in str(caught.value)


@pytest.mark.parametrize("call", [lambda g, tmp: probslam._core.initialize_chordal(g),
                                  lambda g, tmp: probslam._core.write_g2o_3d(str(tmp / "g.g2o"), g)])
@pytest.mark.parametrize("wrong", NOT_GRAPHS + [two_pose_graph()], ids=lambda w: type(w).__name__)
def test_a_3d_only_call_names_graph_for_anything_else(call, wrong, tmp_path):
    with pytest.raises(TypeError, match=r"^graph: expected a PoseGraph3D, got " + type(wrong).__name__) as caught:
        call(wrong, tmp_path)
    assert "\n" not in str(caught.value)
    assert not (tmp_path / "g.g2o").exists()


def grid_graph(dim, n=10):
    """An n x n grid of poses with an edge to each right and upper neighbour: big enough that the
    fill of the Cholesky factor shows which ordering ran (AMD and METIS differ by tens of entries)."""
    rng = np.random.default_rng(0)
    g = probslam.PoseGraph2D() if dim == 2 else probslam.PoseGraph3D()
    still = [] if dim == 2 else [0.0, 0.0, 0.0, 1.0]
    for i in range(n * n):
        x, y = i % n + 0.1 * rng.normal(), i // n + 0.1 * rng.normal()
        g.add_pose(i, [x, y, 0.0] + still if dim == 3 else [x, y, 0.1 * rng.normal()])
    info = np.eye(3 if dim == 2 else 6)
    for i in range(n * n):
        if i % n < n - 1:
            g.add_pose_edge(i, i + 1, [1.0, 0.0, 0.0] + still, info)
        if i // n < n - 1:
            g.add_pose_edge(i, i + n, [0.0, 1.0, 0.0] + still, info)
    return g


@pytest.mark.parametrize("dim, default, other", [(2, "amd", "metis"), (3, "metis", "amd")])
def test_one_binding_per_function_keeps_each_graph_types_results_and_defaults(dim, default, other):
    """The fill ordering "default" (SparseCholeskyOptions') is AMD for a 2-D graph and METIS for a
    3-D one, as the typed overloads had it: the same factor fill and values as naming it, another
    fill than the other ordering; fields, the options object and the callback reach the graph's
    own optimiser."""
    runs = {}
    for ordering in (None, "default", default, other):
        g = grid_graph(dim)
        seen = []
        options = {} if ordering is None else {"linear_solver": {"ordering": ordering}}
        report = probslam.optimize(g, algorithm="gauss-newton", max_iterations=20,
                                   callback=lambda i, chi2: seen.append((i, chi2)), **options)
        assert [i for i, _ in seen] == list(range(1, report.iterations + 1)) and seen[-1][1] == report.chi2
        runs[ordering] = (report.factor_nonzeros, g.poses)
    assert runs[None][0] == runs["default"][0] == runs[default][0] != runs[other][0]
    np.testing.assert_array_equal(runs[None][1], runs[default][1])
    g = grid_graph(dim)
    covariances = probslam.marginal_covariances(g, [0, 55])
    width = 3 if dim == 2 else 6
    assert [c.shape for c in covariances] == [(width, width)] * 2
    np.testing.assert_array_equal(covariances[1], probslam.marginal_covariances(g, [55], ordering=default)[0])
    joint = probslam.joint_marginal_covariances(graph=g, groups=[[0, 55]])[0]
    np.testing.assert_allclose(joint[width:, width:], covariances[1], rtol=1e-9, atol=1e-12)
    report = probslam.optimize_incremental(g, poses_per_step=25, step={"max_iterations": 3})
    assert report.steps == 4


@pytest.mark.parametrize("dim", [2, 3])
def test_an_options_object_and_the_same_fields_by_keyword_run_alike(dim):
    """Issue 52: optimize / optimize_incremental / the marginals take their typed options or the
    same fields by keyword, with identical results (bit for bit); the defaults are the C++
    structs' (optimize_incremental's step stops sooner than optimize)."""
    fields = dict(algorithm="levenberg-marquardt", max_iterations=7, kernel="huber", kernel_width=2.0,
                  linear_solver={"method": "simplicial"})
    by_keyword, by_object = grid_graph(dim), grid_graph(dim)
    a = probslam.optimize(by_keyword, **fields)
    b = probslam.optimize(by_object, options=probslam.OptimizerOptions(**fields))
    assert (a.iterations, a.chi2, a.factor_nonzeros) == (b.iterations, b.chi2, b.factor_nonzeros)
    np.testing.assert_array_equal(by_keyword.poses, by_object.poses)
    # A keyword replaces that field of the object, the others kept.
    c = probslam.optimize(grid_graph(dim), options=probslam.OptimizerOptions(**fields), max_iterations=1)
    assert c.iterations == 1 and c.chi2 != a.chi2
    step = probslam.OptimizerOptions(max_iterations=3, relative_tolerance=1e-8)
    incremental = [probslam.optimize_incremental(grid_graph(dim), poses_per_step=30, step=step),
                   probslam.optimize_incremental(grid_graph(dim), poses_per_step=30, step=step.as_dict()),
                   probslam.optimize_incremental(grid_graph(dim), options=probslam.IncrementalOptions(
                       poses_per_step=30, step=step))]
    assert len({(r.steps, r.iterations, r.chi2) for r in incremental}) == 1
    defaults = probslam.IncrementalOptions()
    assert (defaults.poses_per_step, defaults.step.max_iterations, defaults.step.relative_tolerance) == (100, 10, 1e-6)
    assert (probslam.OptimizerOptions().max_iterations, probslam.OptimizerOptions().relative_tolerance) == (100, 1e-10)
    g = grid_graph(dim)
    probslam.optimize(g)
    solver = probslam.SparseCholeskyOptions(method="simplicial", ordering="amd")
    np.testing.assert_array_equal(probslam.marginal_covariances(g, [5, 40], method="simplicial", ordering="amd"),
                                  probslam.marginal_covariances(g, [5, 40], options=solver))
    np.testing.assert_array_equal(probslam.joint_marginal_covariances(g, [[5, 40]], method="simplicial",
                                                                      ordering="amd"),
                                  probslam.joint_marginal_covariances(g, [[5, 40]], options=solver))
    # A bad field names its path; the graph is left as it was.
    before = g.poses.copy()
    with pytest.raises(ValueError, match=r"^linear_solver\.ordering must be one of"):
        probslam.optimize(g, options=probslam.OptimizerOptions(), linear_solver={"ordering": "colamd"})
    with pytest.raises(TypeError, match=r"^step\.max_iterations"):
        probslam.optimize_incremental(g, step={"max_iterations": 2.5})
    with pytest.raises(TypeError, match=r"^options: expected an? OptimizerOptions"):
        probslam.optimize(g, options=probslam.SparseCholeskyOptions())
    np.testing.assert_array_equal(g.poses, before)
