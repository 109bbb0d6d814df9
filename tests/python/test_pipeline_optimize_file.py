"""pipelines.optimize_file, the graph-file pipeline behind `probslam optimize`: the same optimum
as reading and optimising by hand, each dimension's default start, options refused by field,
and what it writes read back."""

import numpy as np
import pytest

import probslam as ps
from probslam import data, graph as pg
from probslam.pipelines import GraphFileOptions, GraphFileRun, optimize_file


def test_the_bundled_2d_graph_reaches_the_optimum_reading_by_hand_reaches():
    run = optimize_file(data.path("intel_400.g2o"))
    direct = pg.read_pose_graph(data.path("intel_400.g2o"))
    report = pg.optimize(direct)
    assert run.init == "file" and run.dimension == 2 and run.converged
    assert run.report.chi2 == pytest.approx(report.chi2, rel=1e-12)
    np.testing.assert_allclose(run.graph.poses, direct.poses, atol=1e-9)
    assert run.chi2_history[-1] == pytest.approx(run.report.chi2)
    assert "chi2" in run.optimize_summary() and "400 poses" in run.read_summary()


def test_3d_starts_from_the_chordal_relaxation_and_writes_what_it_holds(tmp_path):
    run = optimize_file(data.path("parking_garage_400.g2o"), GraphFileOptions(max_iterations=20))
    assert run.dimension == 3 and run.init == "chordal"
    direct = pg.read_pose_graph_3d(data.path("parking_garage_400.g2o"))
    pg.initialize_chordal(direct)
    assert run.initial_chi2 == pytest.approx(direct.chi2(), rel=1e-9)
    written = run.write(str(tmp_path / "g"))
    back = pg.read_pose_graph_3d(written[0])
    assert back.chi2() == pytest.approx(run.graph.chi2(), rel=1e-6)  # g2o text keeps ~9 digits
    with pytest.warns(UserWarning, match="not planar"):  # read back as 2-D: the count is what is checked
        traj = ps.io.read_trajectory(written[1])
    assert len(traj.poses) == len(run.graph.pose_ids)
    with pytest.raises(ValueError, match="^trajectory_format xyt"):
        run.write(str(tmp_path / "h"), "xyt")


def test_an_incremental_start_takes_its_step():
    path = ps.data.path("intel_400.g2o")
    run = GraphFileRun.read(path, GraphFileOptions(init="incremental", poses_per_step=50))
    run.start()
    assert run.init == "incremental" and "init:       incremental" in run.start_summary()


@pytest.mark.parametrize("fields, exc, message", [
    (dict(kernel_width=2.0), ValueError, "^kernel_width applies with kernel huber or cauchy only"),
    (dict(kernel="huber", kernel_width=-1.0), ValueError, "^kernel_width must be finite and > 0"),
    (dict(poses_per_step=10), ValueError, "^poses_per_step applies with init incremental only"),
    (dict(init="incremental", poses_per_step=0), ValueError, r"^poses_per_step must lie in \[1, 2\^31\)"),
    (dict(max_iterations=2.5), TypeError, "^max_iterations must be an int"),
    (dict(init="magic"), ValueError, "^init must be one of"),
    (dict(kernel="tukey"), ValueError, "^kernel must be one of"),
])
def test_options_are_refused_by_field(fields, exc, message):
    with pytest.raises(exc, match=message):
        GraphFileOptions().replace(**fields)


def test_a_start_of_the_other_dimension_is_refused_naming_init():
    with pytest.raises(ValueError, match="^init chordal applies to 3-D graphs"):
        GraphFileRun.read(data.path("intel_400.g2o"), GraphFileOptions(init="chordal"))
    with pytest.raises(TypeError, match="^options: expected a GraphFileOptions"):
        GraphFileRun.read(data.path("intel_400.g2o"), {"init": "file"})
