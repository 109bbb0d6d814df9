"""A 3-D file straight to a PoseGraph3D (``probslam.graph.read_pose_graph_3d``), the graph back to
g2o (``probslam.graph.write_g2o_3d``), priors, and the dimension of a file: checked against a
plain-Python parse of the text (g2o3d_text) and scipy's rotations."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import probslam
from probslam import graph as pg
from g2o3d_text import parse as read_arrays

IDENTITY_INFORMATION = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1"
#: One normalisation of a quaternion already unit to rounding moves it by a few ulps.
NORMALISATION = 1e-15
#: Sums of the same e^T Omega e terms over a few hundred edges, in different orders.
SUM_ROUNDING = 1e-12

BUNDLED_3D = "parking_garage_400.g2o"


def by_hand(arrays):
    """The graph the file's text describes, built one element at a time (the reference)."""
    g = probslam.PoseGraph3D()
    for i, q, t, fixed in zip(arrays.vertex_ids, arrays.quaternions, arrays.translations, arrays.fixed):
        g.add_pose(int(i), np.r_[t, q])
        if fixed:
            g.set_fixed(int(i))
    for (i, j), q, t, info in zip(arrays.edges, arrays.edge_quaternions, arrays.edge_translations, arrays.information):
        g.add_pose_edge(int(i), int(j), np.r_[t, q], info)
    for i, q, t, info in zip(arrays.prior_ids, arrays.prior_quaternions, arrays.prior_translations,
                             arrays.prior_information):
        g.add_pose_prior(int(i), np.r_[t, q], info)
    return g


def assert_same_graph(a, b, atol=0.0):
    np.testing.assert_array_equal(a.pose_ids, b.pose_ids)
    np.testing.assert_allclose(a.poses, b.poses, rtol=0, atol=atol)
    assert [a.is_fixed(int(i)) for i in a.pose_ids] == [b.is_fixed(int(i)) for i in b.pose_ids]
    for x, y in zip(a.pose_edges() + a.pose_priors(), b.pose_edges() + b.pose_priors()):
        np.testing.assert_allclose(x, y, rtol=0, atol=atol)


def test_bundled_file_to_graph_equals_the_graph_of_its_text():
    path = probslam.data.path(BUNDLED_3D)
    g = pg.read_pose_graph_3d(path)
    assert (g.num_vertices, g.num_pose_edges, g.num_pose_priors) == (400, 500, 0)
    reference = by_hand(read_arrays(path))
    assert_same_graph(g, reference, atol=NORMALISATION)  # numpy's normalisation beside Eigen's
    assert g.chi2() == pytest.approx(reference.chi2(), rel=SUM_ROUNDING)


def test_priors_and_fix_reach_the_graph_and_survive_a_round_trip(tmp_path):
    text = ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0.5 0 0 0.6 0.8\nFIX 1\n"
            "PARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\n"
            "EDGE_SE3_PRIOR 0 0 0.1 0.2 0.3 0 0.6 0 0.8" + IDENTITY_INFORMATION + "\n"
            "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0.6 0.8" + IDENTITY_INFORMATION + "\n")
    (tmp_path / "g.g2o").write_text(text)
    g = pg.read_pose_graph_3d(tmp_path / "g.g2o")
    assert g.is_fixed(1) and not g.is_fixed(0) and g.num_pose_priors == 1
    ids, z, info = g.pose_priors()
    np.testing.assert_array_equal(ids, [0])
    np.testing.assert_array_equal(z, [[0.1, 0.2, 0.3, 0, 0.6, 0, 0.8]])
    np.testing.assert_array_equal(info, [np.eye(6)])
    # The prior's error [t_e, Log(R_e)] of z^-1 x, from scipy: x is the identity here.
    rz = Rotation.from_quat([0, 0.6, 0, 0.8])
    e = np.r_[rz.inv().apply(-np.array([0.1, 0.2, 0.3])), rz.inv().as_rotvec()]
    np.testing.assert_allclose(g.prior_chi2(), [e @ e], rtol=1e-14)
    assert g.chi2() == pytest.approx(e @ e + g.edge_chi2().sum(), rel=1e-14)

    out = tmp_path / "out.g2o"
    pg.write_g2o_3d(g, out)
    back = pg.read_pose_graph_3d(out)
    assert_same_graph(g, back, atol=NORMALISATION)
    pg.write_g2o_3d(back, tmp_path / "again.g2o")
    assert_same_graph(back, pg.read_pose_graph_3d(tmp_path / "again.g2o"), atol=NORMALISATION)


def test_optimised_bundled_graph_round_trips(tmp_path):
    g = pg.read_pose_graph_3d(probslam.data.path(BUNDLED_3D))
    pg.initialize_chordal(g)
    pg.optimize(g)
    pg.write_g2o_3d(g, tmp_path / "o.g2o")
    back = pg.read_pose_graph_3d(tmp_path / "o.g2o")
    assert_same_graph(g, back, atol=NORMALISATION)
    assert back.chi2() == pytest.approx(g.chi2(), rel=SUM_ROUNDING)


def test_a_prior_holds_the_graph_instead_of_the_first_pose():
    # Two poses that should coincide, priors 2 m apart along z (unit information): the optimum
    # of a^2 + (b - a)^2 + (b - 2)^2 puts them at z = 2/3 and 4/3, chi2 4/3; the first pose moves.
    g = probslam.PoseGraph3D()
    identity = [0, 0, 0, 0, 0, 0, 1]
    g.add_pose(0, identity)
    g.add_pose(1, identity)
    g.add_pose_edge(0, 1, identity, np.eye(6))
    g.add_pose_prior(0, identity, np.eye(6))
    g.add_pose_prior(1, [0, 0, 2, 0, 0, 0, 1], np.eye(6))
    report = pg.optimize(g)
    assert report.chi2 == pytest.approx(4 / 3, abs=1e-9)
    np.testing.assert_allclose(g.poses[:, 2], [2 / 3, 4 / 3], atol=1e-9)
    cov = pg.marginal_covariances(g, [0])[0]  # defined: the priors fix the gauge
    assert cov.shape == (6, 6) and np.all(np.linalg.eigvalsh(cov) > 0)


def test_bad_priors_and_writer_arguments_are_refused(tmp_path):
    g = probslam.PoseGraph3D()
    g.add_pose(0, [0, 0, 0, 0, 0, 0, 1])
    with pytest.raises(ValueError, match="unknown vertex id 5"):
        g.add_pose_prior(5, [0, 0, 0, 0, 0, 0, 1], np.eye(6))
    with pytest.raises(ValueError, match="information"):
        g.add_pose_prior(0, [0, 0, 0, 0, 0, 0, 1], -np.eye(6))
    with pytest.raises(ValueError, match="measurement"):
        g.add_pose_prior(0, [0, 0, 0, 0, 0, 0, 2], np.eye(6))
    assert g.num_pose_priors == 0
    with pytest.raises(TypeError, match="graph: expected a PoseGraph3D"):
        pg.write_g2o_3d(probslam.PoseGraph2D(), tmp_path / "x.g2o")
    with pytest.raises(TypeError, match="path"):
        pg.write_g2o_3d(g, 3)
    assert not (tmp_path / "x.g2o").exists()


def test_wrong_dimension_is_named(tmp_path):
    with pytest.raises(ValueError, match=r"this is a 2-D graph \(VERTEX_SE2\): use read_pose_graph"):
        pg.read_pose_graph_3d(probslam.data.path("intel_400.g2o"))
    with pytest.raises(FileNotFoundError):
        pg.read_pose_graph_3d(tmp_path / "missing.g2o")


@pytest.mark.parametrize("text, dimension", [
    ("# a comment\nFIX 0\nVERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n", 3),
    ("EDGE3 0 1 1 0 0 0 0 0" + " 1" * 21 + "\n", 3),
    ("VERTEX3 0 0 0 0 0 0 0\n", 3),
    ("VERTEX_SE2 0 0 0 0\n", 2),
    ("ODOMETRY 0 1 1 0 0 1 0 0 1 0 1\n", 2),
    ("x" * 5000 + " VERTEX_SE3:QUAT\nEDGE2 0 1 1 0 0 1 0 1 0 0 1\n", 2),  # a tag deep in a long line is no tag
    ("nothing known\n", 2),
])
def test_pose_graph_dimension(tmp_path, text, dimension):
    (tmp_path / "g.txt").write_text(text)
    assert pg.pose_graph_dimension(tmp_path / "g.txt") == dimension


def test_pose_graph_dimension_of_the_bundled_graphs():
    assert pg.pose_graph_dimension(probslam.data.path(BUNDLED_3D)) == 3
    assert pg.pose_graph_dimension(probslam.data.path("intel_400.g2o")) == 2
    assert pg.pose_graph_dimension(probslam.data.path("victoria_park_1000.txt")) == 2


def test_write_trajectory_3d(tmp_path):
    rng = np.random.default_rng(0)
    q = Rotation.random(4, random_state=1)
    poses = np.column_stack([rng.normal(size=(4, 3)), q.as_quat()])
    times = np.arange(4.0)
    (tum,) = probslam.io.write_trajectory_3d(times, poses, tmp_path / "t.tum")
    np.testing.assert_allclose(np.loadtxt(tum), np.column_stack([times, poses]), atol=1e-9)
    kitti, times_file = probslam.io.write_trajectory_3d(times, poses, tmp_path / "t.kitti", format="kitti")
    rows = np.loadtxt(kitti).reshape(4, 3, 4)
    np.testing.assert_allclose(rows[:, :, :3], q.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(rows[:, :, 3], poses[:, :3], atol=1e-9)
    np.testing.assert_allclose(np.loadtxt(times_file), times)
    with pytest.raises(ValueError, match="format"):
        probslam.io.write_trajectory_3d(times, poses, tmp_path / "t.txt", format="xyt")
    with pytest.raises(ValueError, match="poses"):
        probslam.io.write_trajectory_3d(times, poses[:, :6], tmp_path / "t.tum")
