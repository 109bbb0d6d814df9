"""A first run's defaults (issue 49): each command with no option the user must know works on the
bundled and shared datasets. optimize starts a landmark graph where its landmarks are placed
well; ekf-slam --unknown associates MRCLAM sightings with multiple hypotheses; map with a learned
model uses the model's own cell size and range and says what it is doing; map on raw odometry
says how to correct it; slam's bundled log closes a loop."""

from __future__ import annotations

import re

import numpy as np
import pytest

import probslam as ps
from probslam import cli, io
from probslam import inverse_learning as il
from probslam.pipelines.map_run import BUNDLED_INVERSE_MODEL
from probslam.data import path as data_path

#: Victoria Park's optimum from a start near it (docs/pose_graphs.md, README: chi2 6184.12).
VICTORIA_PARK_CHI2 = 6184.12


def run(capsys, *argv):
    rc = cli.main([*argv, "--no-progress", "--no-plot"])
    captured = capsys.readouterr()
    return rc, captured.out, captured.err


# --- optimize: the start of a landmark graph ------------------------------------------------------

def test_optimize_starts_a_landmark_graph_from_the_ekf_by_default(tmp_path, capsys):
    """The bundled Victoria Park excerpt (1000 poses, trees as landmarks): with no --init the
    start is the EKF's, which places each landmark from the filter's estimate, and Gauss-Newton
    converges; a pose-only graph keeps the file's values."""
    path = ps.data.path("victoria_park_1000.txt")
    rc, out, _ = run(capsys, "optimize", path, "-o", str(tmp_path / "v"))
    assert rc == 0, out
    assert "init:       ekf (the graph has landmarks: the EKF SLAM estimate places them)" in out
    g = ps.graph.read_pose_graph(path)
    ps.graph.initialize(g, "ekf")
    report = ps.graph.optimize(g)
    assert report.converged and f"result:     chi2 {report.chi2:.6f} after {report.iterations} iterations" in out
    rc, out, _ = run(capsys, "optimize", "-o", str(tmp_path / "i"))
    assert rc == 0 and "init:" not in out  # intel_400: the file's values, as before


@pytest.mark.slow
def test_optimize_victoria_park_converges_with_no_option(shared_data, tmp_path, capsys):
    """The whole Victoria Park graph (iSAM's file): main's default (the file's dead reckoning)
    ran 100 iterations to chi2 3.4e7 and exit 3."""
    rc, out, _ = run(capsys, "optimize", str(shared_data / "landmark_slam" / "victoria_park" / "victoriaPark.txt"),
                     "-o", str(tmp_path / "v"))
    assert rc == 0, out
    chi2 = float(re.search(r"result:\s+chi2 (\S+) after (\d+) iterations", out).group(1))
    assert chi2 == pytest.approx(VICTORIA_PARK_CHI2, abs=0.01)


@pytest.mark.slow
def test_optimize_reads_gtsams_copy_of_victoria_park_as_covariances(shared_data, tmp_path, capsys):
    """GTSAM's victoria_park.txt holds the same measurements with covariances where iSAM's holds
    square-root information (1e-4 for 100): with no option it is read as written, and reaches
    the same optimum (main refused it: 'information matrix is singular')."""
    rc, out, _ = run(capsys, "optimize", str(shared_data / "landmark_slam" / "victoria_park" /
                                             "victoria_park_gtsam.txt"), "-o", str(tmp_path / "g"))
    assert rc == 0, out
    assert "noise:      covariance" in out
    chi2 = float(re.search(r"result:\s+chi2 (\S+) after (\d+) iterations", out).group(1))
    assert chi2 == pytest.approx(VICTORIA_PARK_CHI2, rel=1e-4)


# --- ekf-slam --unknown: the association ----------------------------------------------------------

def test_ekf_slam_unknown_defaults_to_multiple_hypotheses_on_mrclam(tmp_path, capsys):
    rc, out, _ = run(capsys, "ekf-slam", "--unknown", "-o", str(tmp_path / "e"))
    assert rc == 0 and "unknown (mht) correspondences" in out
    # Victoria Park's EKF takes the file's correspondences: --unknown still runs there.
    rc, out, _ = run(capsys, "ekf-slam", ps.data.path("victoria_park_1000.txt"), "--unknown", "-o", str(tmp_path / "v"))
    assert rc == 0, out


@pytest.mark.slow
def test_ekf_slam_unknown_maps_dataset_1_robot_1_by_default(shared_data, tmp_path, capsys):
    """MRCLAM Dataset 1, robot 1, barcodes hidden, no --association: main's JCBB got 80.6% right
    with 40 landmarks for 15; the default now finds every barcode's landmark once."""
    rc, out, _ = run(capsys, "ekf-slam", str(shared_data / "landmark_slam" / "mrclam_dataset1"), "--unknown",
                     "-o", str(tmp_path / "e"))
    assert rc == 0, out
    correct = float(re.search(r"associations:\s+(\S+)% correct", out).group(1))
    landmarks = int(re.search(r"landmarks:\s+(\d+) in the map", out).group(1))
    assert correct >= 99.0 and landmarks == 15, out


# --- map with a learned inverse model -------------------------------------------------------------

def test_a_model_file_records_the_resolution_and_range_it_was_trained_at(tmp_path):
    model = il.LearnedInverseModel.load(ps.data.path(BUNDLED_INVERSE_MODEL))
    assert (model.resolution, model.max_range) == (0.1, 10.0)  # studies/eval_inverse_real.py's RES, MAX_RANGE
    assert il.learned_map_geometry(model) == (0.1, 10.0)
    assert il.learned_map_geometry(model, 0.2, None) == (0.2, 10.0)
    model.save(tmp_path / "m.npz")
    back = il.LearnedInverseModel.load(tmp_path / "m.npz")
    assert (back.resolution, back.max_range) == (0.1, 10.0)
    back.resolution = back.max_range = None  # a model that does not say: map_laser_log's defaults
    back.save(tmp_path / "n.npz")
    unsaid = il.LearnedInverseModel.load(tmp_path / "n.npz")
    assert il.learned_map_geometry(unsaid) == (ps.mapping.DEFAULT_RESOLUTION, ps.mapping.DEFAULT_MAX_RANGE) == (0.05, 30.0)
    model.max_range = -1.0
    with pytest.raises(ValueError, match="max_range"):
        model.save(tmp_path / "bad.npz")


@pytest.mark.slow  # 180 scans through the learned model: 18 s under the sanitizers
def test_map_with_the_bundled_model_uses_its_own_resolution_and_range(tmp_path, capsys):
    """Main mapped at the ray model's 0.05 m and 30 m, 36x the cells of the model's own 0.1 m and
    10 m, in 118 s without a word; now the model's own, said before the work starts."""
    rc, out, _ = run(capsys, "map", "--inverse-model", "bundled", "-o", str(tmp_path / "m"))
    assert rc == 0
    first = out.splitlines()[0]
    assert first.startswith("mapping:") and "0.1 m cells, readings to 10 m (the model's own --resolution and " \
                                                "--max-range)" in first
    grid = io.load_ros_map(tmp_path / "m.yaml")
    assert grid.resolution == pytest.approx(0.1)
    model = il.LearnedInverseModel.load(ps.data.path(BUNDLED_INVERSE_MODEL))
    same = il.map_laser_log_learned(model, io.read_carmen_log(data_path(cli.BUNDLED_LOG)).scans, 0.1, 10.0, progress=False).grid
    assert grid.same_geometry(same)
    # Given options win.
    rc, out, _ = run(capsys, "map", "--inverse-model", "bundled", "--resolution", "0.2", "-o", str(tmp_path / "n"))
    assert rc == 0 and "0.2 m cells, readings to 10 m (the model's own --max-range)" in out
    assert io.load_ros_map(tmp_path / "n.yaml").resolution == pytest.approx(0.2)


# --- map on raw odometry --------------------------------------------------------------------------

def test_map_on_a_log_of_odometry_says_that_slam_corrects_it(tmp_path, capsys):
    """A CARMEN log's poses may be raw or corrected (both write the same FLASER fields: the Intel
    raw and corrected logs alike), so map says what to do if the map smears; not on the bundled
    corrected excerpt."""
    raw = ps.data.path("intel_raw_loop.log.gz")
    rc, out, _ = run(capsys, "map", raw, "-o", str(tmp_path / "m"))
    assert rc == 0
    assert out.splitlines()[-1] == (f"hint:          map draws the log's poses as they are; if they are raw odometry "
                                    f"(a log as the robot recorded it, not a corrected one), the map smears wherever "
                                    f"it drifts, and 'probslam slam {raw}' corrects them (scan matching, loop "
                                    f"closures)")
    rc, out, _ = run(capsys, "map", "-o", str(tmp_path / "c"))
    assert rc == 0 and "hint:" not in out


# --- slam: the bundled log closes a loop ----------------------------------------------------------

@pytest.mark.slow
def test_slam_with_no_arguments_closes_a_loop(tmp_path, capsys):
    """The bundled raw log comes back to where it started: the first `probslam slam` shows a loop
    closure (main's excerpt ended before the loop closed: 0 accepted)."""
    rc, out, _ = run(capsys, "slam", "-o", str(tmp_path / "s"))
    assert rc == 0
    accepted = int(re.search(r"closures:\s+(\d+) accepted", out).group(1))
    assert accepted >= 1, out
