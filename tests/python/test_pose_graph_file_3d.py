"""3-D pose graph files: probslam.graph.read_pose_graph_3d / write_g2o_3d against the shipped
graphs, a plain-Python parse of the same text (g2o3d_text), scipy's rotations, and (marked slow)
GTSAM's own reader and error on the same files."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import probslam
from probslam import graph as pg
from g2o3d_text import graph_arrays, parse


def read_pose_graph_3d(path, **options):
    """The graph the reader builds, seen as arrays (g2o3d_text.graph_arrays), with its report."""
    read = pg.read_pose_graph_3d_with_report(path, rows=options.pop("rows", "strict"), **options)
    view = graph_arrays(read.graph, read.report)
    view.graph = read.graph
    return view

#: (file under pose_graphs, vertices, edges): the counts each folder's README.md gives (verified
#: there with grep).
SHIPPED = [
    ("sphere2500/sphere2500.g2o", 2500, 4949),
    ("parking_garage/parking-garage.g2o", 1661, 6275),
    ("torus3d/torus3D.g2o", 5000, 9048),
    ("gtsam_examples/pose3example.txt", 5, 6),
    ("sphere2500/sphere2500.txt", 2500, 4949),  # iSAM: no vertices listed, dead-reckoned
]

#: Values composed from parsed decimals with a few products: double rounding only.
ROUNDING = 1e-12

IDENTITY_INFORMATION = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1"


def shipped(shared_data, relative):
    path = shared_data / "pose_graphs" / relative
    if not path.is_file():
        pytest.skip(f"dataset not present: {path}")
    return path


def write_text(tmp_path, text, name="g.g2o"):
    path = tmp_path / name
    path.write_text(text)
    return path


def chain_text(n):
    """A g2o file of n + 1 poses and n odometry edges."""
    lines = [f"VERTEX_SE3:QUAT {i} {i} 0 0 0 0 0 1" for i in range(n + 1)]
    lines += [f"EDGE_SE3:QUAT {i} {i + 1} 1 0 0 0 0 0 1" + IDENTITY_INFORMATION for i in range(n)]
    return "\n".join(lines) + "\n"


#: A quaternion normalised once more (a graph written and read back, or numpy's normalisation
#: beside Eigen's) moves by an ulp or two.
NORMALISATION = 1e-15


def assert_same_graph(a, b, atol=0.0):
    for name in ("vertex_ids", "quaternions", "translations", "fixed", "edges", "edge_quaternions",
                 "edge_translations", "information", "prior_ids", "prior_quaternions", "prior_translations",
                 "prior_information"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=atol, err_msg=name)


@pytest.mark.parametrize("relative, vertices, edges", SHIPPED)
def test_shipped_graphs_have_their_readme_counts(shared_data, relative, vertices, edges):
    g = read_pose_graph_3d(shipped(shared_data, relative))
    assert g.vertex_ids.shape == (vertices,) and g.quaternions.shape == (vertices, 4)
    assert g.translations.shape == (vertices, 3) and g.fixed.shape == (vertices,)
    assert g.edges.shape == (edges, 2) and g.information.shape == (edges, 6, 6)
    assert g.report.rows == (edges if relative.endswith(".txt") and "sphere" in relative else vertices + edges)
    assert g.report.skipped_rows == 0
    np.testing.assert_allclose(np.linalg.norm(g.quaternions, axis=1), 1.0, rtol=0, atol=ROUNDING)
    assert np.all(np.linalg.eigvalsh(g.information) > 0)
    np.testing.assert_array_equal(g.information, np.swapaxes(g.information, 1, 2))


def test_quaternions_are_x_y_z_w_and_euler_angles_are_zyx(tmp_path):
    q = Rotation.from_rotvec([0.3, -1.2, 0.4]).as_quat().tolist()  # scipy: (x, y, z, w)
    text = f"VERTEX_SE3:QUAT 0 1 2 3 {q[0]!r} {q[1]!r} {q[2]!r} {q[3]!r}\n"
    g = read_pose_graph_3d(write_text(tmp_path, text))
    np.testing.assert_allclose(g.quaternions[0], q, rtol=0, atol=ROUNDING)
    np.testing.assert_array_equal(g.translations[0], [1, 2, 3])
    roll, pitch, yaw = 0.4, -0.3, 2.9
    text = f"EDGE3 0 1 0.5 0 0 {roll} {pitch} {yaw}" + IDENTITY_INFORMATION + "\n"
    g = read_pose_graph_3d(write_text(tmp_path, text, "e.txt"))
    expected = Rotation.from_euler("ZYX", [yaw, pitch, roll])  # intrinsic z-y'-x'': Rz Ry Rx
    assert (Rotation.from_quat(g.edge_quaternions[0]) * expected.inv()).magnitude() < ROUNDING
    # dead reckoning: vertex 1 = vertex 0 (origin) composed with the edge
    np.testing.assert_array_equal(g.vertex_ids, [0, 1])
    np.testing.assert_allclose(g.translations[1], [0.5, 0, 0], atol=ROUNDING)


def test_isam_noise_is_square_root_information_by_default(tmp_path):
    text = "EDGE3 0 1 0 0 0 0 0 0 10 0 0 0 0 0 10 0 0 0 0 10 0 0 0 100 0 0 100 0 25\n"
    path = write_text(tmp_path, text, "s.txt")
    np.testing.assert_array_equal(np.diag(read_pose_graph_3d(path).information[0]), [100, 100, 100, 1e4, 1e4, 625])
    as_gtsam = read_pose_graph_3d(path, noise="information")  # how GTSAM's load3D reads these numbers
    np.testing.assert_array_equal(np.diag(as_gtsam.information[0]), [10, 10, 10, 100, 100, 25])


def test_round_trip_is_exact_to_one_normalisation(shared_data, tmp_path):
    for relative in ("gtsam_examples/pose3example.txt", "sphere2500/sphere2500.txt"):
        original = read_pose_graph_3d(shipped(shared_data, relative))
        out = tmp_path / "out.g2o"
        pg.write_g2o_3d(original.graph, out)
        back = read_pose_graph_3d(out)
        assert_same_graph(original, back, atol=NORMALISATION)


def test_round_trip_keeps_fix_and_priors(tmp_path):
    text = ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0.6 0.8\nFIX 1\n"
            "PARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\n"
            "EDGE_SE3_PRIOR 0 0 0.1 0.2 0.3 0 0 0 1" + IDENTITY_INFORMATION + "\n"
            "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0.6 0.8" + IDENTITY_INFORMATION + "\n")
    g = read_pose_graph_3d(write_text(tmp_path, text))
    np.testing.assert_array_equal(g.fixed, [False, True])
    np.testing.assert_array_equal(g.prior_ids, [0])
    np.testing.assert_array_equal(g.prior_translations, [[0.1, 0.2, 0.3]])
    pg.write_g2o_3d(g.graph, tmp_path / "out.g2o")
    assert_same_graph(g, read_pose_graph_3d(tmp_path / "out.g2o"))


def test_the_reader_equals_a_plain_parse_of_the_text(tmp_path):
    """Every number of a g2o file with fixed vertices, priors, points and point edges, as the
    plain-Python parse reads the same text."""
    text = ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0.5 -2 0 0 0.6 0.8\nFIX 1\n"
            "PARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\nPARAMS_SE3OFFSET 1 0.1 0 0.2 0 0 0.6 0.8\n"
            "EDGE_SE3_PRIOR 0 0 0.1 0.2 0.3 0 0 0 1" + IDENTITY_INFORMATION + "\n"
            "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0.6 0.8 4 0.5 0 0 0 0 3 0 0 0 0 2 0 0 0 9 0 0 8 0 7\n"
            "VERTEX_TRACKXYZ 5 1 2 3.25\nEDGE_SE3_TRACKXYZ 1 5 1 0.5 1 2 4 0.5 0 4 0 4\n")
    path = write_text(tmp_path, text)
    assert_same_graph(read_pose_graph_3d(path), parse(path), atol=NORMALISATION)
    g, ref = read_pose_graph_3d(path), parse(path)
    for name in ("point_ids", "points", "point_edges", "point_measurements", "point_information",
                 "point_offset_quaternions", "point_offset_translations"):
        np.testing.assert_array_equal(getattr(g, name), getattr(ref, name), err_msg=name)
    with pytest.raises(TypeError, match="graph: expected a PoseGraph3D"):
        pg.write_g2o_3d({"vertex_ids": []}, tmp_path / "out.g2o")
    assert not (tmp_path / "out.g2o").exists()


@pytest.mark.parametrize("line, message", [
    ("EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0", "EDGE_SE3:QUAT has 12 fields, expected at least 31"),
    ("VERTEX_SE3:QUAT 9 0 0 0 0 0 0 1.01", r"quaternion \(qx qy qz qw\) has norm 1.01, not 1"),
    ("VERTEX_SE3:QUAT 9 0 0 0 nan 0 0 1", "quaternion must be finite"),
    ("EDGE_SE3:QUAT 0 999 1 0 0 0 0 0 1" + IDENTITY_INFORMATION, "unknown vertex 999"),
    ("EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1" + IDENTITY_INFORMATION.replace(" 1", " -1"),
     "information is not positive definite"),
])
def test_malformed_line_is_named_or_skipped(tmp_path, line, message):
    n = 150  # one bad line in 2n + 2 records: within MAX_BAD_ROW_FRACTION
    path = write_text(tmp_path, chain_text(n) + line + "\n")
    bad_line = 2 * n + 2
    with pytest.raises(ValueError, match=f"g.g2o:{bad_line}: {message}"):
        read_pose_graph_3d(path)
    g = read_pose_graph_3d(path, rows="skip")
    assert g.report.skipped_rows == 1 and g.report.skipped_lines == [bad_line]
    assert g.edges.shape == (n, 2)


def test_truncated_last_line_is_reported_by_line(tmp_path):
    n = 150
    path = write_text(tmp_path, chain_text(n) + "EDGE_SE3:QUAT 150 0 1 0 0 0")  # cut: no newline
    with pytest.raises(ValueError, match=f"g.g2o:{2 * n + 2}: EDGE_SE3:QUAT has 7 fields"):
        read_pose_graph_3d(path)
    g = read_pose_graph_3d(path, rows="skip")
    assert g.report.skipped_lines == [2 * n + 2]
    assert g.edges.shape == (n, 2) and g.vertex_ids.shape == (n + 1,)


def test_wrong_dimension_and_missing_file(tmp_path, shared_data):
    with pytest.raises(ValueError, match=r"this is a 3-D graph \(VERTEX_SE3:QUAT\): use read_pose_graph_3d"):
        probslam.graph.read_pose_graph(shipped(shared_data, "gtsam_examples/pose3example.txt"))
    with pytest.raises(ValueError, match=r"this is a 3-D graph \(EDGE3\)"):
        probslam.graph.read_pose_graph(shipped(shared_data, "sphere2500/sphere2500.txt"), rows="skip")
    with pytest.raises(ValueError, match=r"this is a 2-D graph \(VERTEX_SE2\): use read_pose_graph"):
        read_pose_graph_3d(shipped(shared_data, "gtsam_examples/pose2example.txt"))
    with pytest.raises(FileNotFoundError):
        read_pose_graph_3d(tmp_path / "missing.g2o")
    with pytest.raises(ValueError, match="format"):
        read_pose_graph_3d(write_text(tmp_path, chain_text(1)), format="ply")
    with pytest.raises(TypeError, match="path"):
        read_pose_graph_3d(3)


# --- against GTSAM ----------------------------------------------------------------------------

def se3_log_error(g) -> np.ndarray:
    """(E, 6) errors [rho, omega] = Log(z^-1 x_i^-1 x_j) with SE(3)'s exponential coordinates (the
    chart of GTSAM's Pose3), in g2o's order [translation, rotation], from scipy rotations."""
    index = {int(v): k for k, v in enumerate(g.vertex_ids)}
    i = np.array([index[int(a)] for a in g.edges[:, 0]])
    j = np.array([index[int(b)] for b in g.edges[:, 1]])
    r = Rotation.from_quat(g.quaternions)
    ri, rj, rz = r[i], r[j], Rotation.from_quat(g.edge_quaternions)
    t_ij = ri.inv().apply(g.translations[j] - g.translations[i])  # x_i^-1 x_j
    r_err = rz.inv() * ri.inv() * rj
    t_err = rz.inv().apply(t_ij - g.edge_translations)  # z^-1 (x_i^-1 x_j)
    omega = r_err.as_rotvec()
    theta = np.linalg.norm(omega, axis=1)
    w = np.zeros((len(omega), 3, 3))
    w[:, 0, 1], w[:, 0, 2], w[:, 1, 2] = -omega[:, 2], omega[:, 1], -omega[:, 0]
    w -= np.swapaxes(w, 1, 2)
    small = theta < 1e-4  # the series' next terms are below double rounding there
    th = np.where(small, 1.0, theta)
    a = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(th)) / th**2)
    b = np.where(small, 1.0 / 6 - theta**2 / 120, (th - np.sin(th)) / th**3)
    v = np.eye(3) + a[:, None, None] * w + b[:, None, None] * (w @ w)  # left Jacobian of SO(3)
    rho = np.linalg.solve(v, t_err[..., None])[..., 0]
    return np.hstack([rho, omega])


def dense_chi2(g) -> float:
    e = se3_log_error(g)
    return float(np.einsum("ei,eij,ej->", e, g.information, e))


#: GTSAM computes the same error with its own formulas (Rot3 logmap, Pose3 logmap) and sums in
#: another order: agreement to rounding over up to 9048 terms.
GTSAM_AGREEMENT = 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("relative", [s[0] for s in SHIPPED if s[0].endswith((".g2o", "pose3example.txt"))])
def test_chi2_of_initial_values_matches_gtsam(shared_data, relative):
    gtsam = pytest.importorskip("gtsam")
    path = shipped(shared_data, relative)
    g = read_pose_graph_3d(path)
    graph, initial = gtsam.readG2o(str(path), True)
    assert graph.size() == len(g.edges) and initial.size() == len(g.vertex_ids)
    ours = dense_chi2(g)
    theirs = 2 * graph.error(initial)
    assert math.isclose(ours, theirs, rel_tol=GTSAM_AGREEMENT), (ours, theirs)


def _upper(matrix):
    """The 21 upper-triangle entries of a (6, 6) matrix as g2o text."""
    return "".join(f" {float(matrix[i, j])!r}" for i in range(6) for j in range(i, 6))


def _floored(information):
    """The information-repair policy written plainly: eigenvalues raised to the floor times the
    largest, eigenvectors kept."""
    w, v = np.linalg.eigh(information)
    return (v * np.maximum(w, probslam.graph.INFORMATION_EIGENVALUE_FLOOR * w.max())) @ v.T


def test_information_with_a_negative_eigenvalue_is_repaired_and_counted(tmp_path, capsys):
    # Issue 48: SE-Sync's cubicle.g2o has 5,021 of 16,869 edges whose information has a negative
    # eigenvalue, and the reader refused the whole file at the first (line 5753). Such edges are
    # now repaired under a stated policy and counted, in both readers and in probslam optimize.
    rng = np.random.default_rng(4)
    n = 40
    lines = chain_text(n).splitlines()
    bad = {}
    for k in (5, 17, 33):  # edges k -> k + 1, cubicle-like: dominant rotation weight, one direction < 0
        q, _ = np.linalg.qr(rng.normal(size=(6, 6)))
        info = (q * np.array([400.0, 300.0, 200.0, 9000.0, 8000.0, -35.0])) @ q.T
        info = 0.5 * (info + info.T)
        lines[n + 1 + k] = f"EDGE_SE3:QUAT {k} {k + 1} 1 0 0 0 0 0 1" + _upper(info)
        bad[n + 2 + k] = info
    path = write_text(tmp_path, "\n".join(lines) + "\n", "cubicle_like.g2o")
    for strict in ("strict", "skip"):
        read = probslam.graph.read_pose_graph_3d_with_report(path, rows=strict)
        assert read.report.repaired_rows == 3 and read.report.skipped_rows == 0
        assert read.report.repaired_lines == sorted(bad)
        assert all("smallest eigenvalue -35" in r for r in read.report.repaired_reasons)
        _, _, infos = read.graph.pose_edges()
        for line, info in bad.items():
            np.testing.assert_allclose(infos[line - n - 2], _floored(np.triu(info) + np.triu(info, 1).T),
                                       rtol=1e-9, atol=1e-9 * np.abs(info).max())
        probslam.optimize(read.graph)
    arrays = read_pose_graph_3d(path)
    assert arrays.report.repaired_rows == 3
    # The 2-D reader keeps the same policy.
    two = tmp_path / "two.g2o"
    two.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 4 1 0 -2 0 9\n")
    read2 = probslam.graph.read_pose_graph_with_report(two)
    assert (read2.report.repaired_rows, read2.report.repaired_lines) == (1, [3])
    info2 = np.array([[4.0, 1, 0], [1, -2, 0], [0, 0, 9]])
    np.testing.assert_allclose(read2.graph.pose_edges()[2][0], _floored(info2), rtol=1e-12, atol=1e-12)
    # probslam optimize says how many it repaired.
    from probslam import cli
    capsys.readouterr()
    cli.main(["optimize", str(path), "--no-plot", "--no-progress", "-o", str(tmp_path / "out")])
    assert "3 edges with an information matrix not positive definite" in capsys.readouterr().out
