"""The landmark pipeline (probslam.pipelines.LandmarkRun, what ``probslam ekf-slam`` / ``fastslam``
run): from Python it gives what the command line prints and writes, its numbers are the drivers'
and scores' own, and a bad option is refused by its field's name before the data is read."""

import re

import numpy as np
import pytest

import probslam as ps
from probslam import cli, data, io
from probslam.datasets import LandmarkDataset, mrclam
from probslam.pipelines import LandmarkRun, LandmarkRunOptions, run_landmark_dataset

MRCLAM = data.path("mrclam7_robot1_120s")
VICTORIA = data.path("victoria_park_1000.txt")
#: Times printed (wall or CPU seconds) differ from run to run; everything else is the same.
TIMES = re.compile(r"\d+\.\d+ s\b")


def _lines(text):
    return [TIMES.sub("X s", line) for line in text.splitlines()
            if not line.startswith(("time:", "wrote:"))]


@pytest.mark.parametrize("argv, options", [
    (["ekf-slam", "--unknown"], LandmarkRunOptions(unknown=True)),
    (["fastslam", "--unknown", "--particles", "10", "--variant", "2", "--seed", "3", "--refine", "graphslam"],
     LandmarkRunOptions(method="fastslam", unknown=True, fastslam=dict(num_particles=10, version=2, seed=3),
                        refine="graphslam")),
    (["fastslam", VICTORIA, "--particles", "5"], LandmarkRunOptions(method="fastslam", fastslam=dict(num_particles=5))),
    (["ekf-slam", "--unknown", "--association", "mht", "--bearing-offset", "0.03", "--seconds", "30"],
     LandmarkRunOptions(unknown=True, association="mht", seconds=30.0,
                        hypotheses=ps.MultiHypothesisOptions(bearing_offset_sigma=0.03))),
])
def test_a_run_from_python_is_what_the_command_prints_and_writes(tmp_path, capsys, argv, options):
    assert cli.main(argv + ["--no-plot", "--no-progress", "-o", str(tmp_path / "cli")]) == 0
    printed = capsys.readouterr().out
    path = VICTORIA if VICTORIA in argv else MRCLAM
    run = run_landmark_dataset(path, options, progress=False)
    assert _lines(run.summary()) == _lines(printed)
    assert run.write(str(tmp_path / "py")) == [str(tmp_path / "py_trajectory.tum")]
    assert (tmp_path / "py_trajectory.tum").read_bytes() == (tmp_path / "cli_trajectory.tum").read_bytes()


def test_the_run_is_the_drivers_and_its_score_the_scorers():
    """The filter's run equals the dataset driver's with the same noise; the printed RMSEs are
    eval.score_mrclam's of it."""
    options = LandmarkRunOptions(unknown=True, association="jcbb", sigma_phi=0.05)
    run = run_landmark_dataset(MRCLAM, options, progress=False)
    robot = mrclam.load(MRCLAM)
    direct = mrclam.run_ekf(robot, mrclam.MOTION_NOISE, np.diag([mrclam.MEASUREMENT_SIGMA[0] ** 2, 0.05 ** 2]),
                            known=False, association="jcbb")
    np.testing.assert_array_equal(run.result.poses, direct.poses)
    np.testing.assert_array_equal(run.result.associations.ids, direct.associations.ids)
    score = ps.eval.score_mrclam(direct, robot, ps.eval.majority_labels(direct))
    assert f"path RMSE:     {score.path_rmse:.3f} m raw, {score.path_rmse_aligned:.3f} m aligned" in run.summary()
    assert run.score.values["score"].landmark_rmse_aligned == score.landmark_rmse_aligned


def test_fastslam_threads_change_nothing_and_the_seed_does():
    def poses(**options):
        return run_landmark_dataset(MRCLAM, LandmarkRunOptions(method="fastslam", unknown=True,
                                                               fastslam=dict(num_particles=20, **options)),
                                    progress=False).result.poses

    one = poses(seed=5)
    np.testing.assert_array_equal(one, poses(seed=5, threads=3))
    assert not np.array_equal(one, poses(seed=6))


def test_a_dataset_already_read_runs_as_its_path():
    options = LandmarkRunOptions(method="fastslam", fastslam=dict(num_particles=10), seconds=60.0)
    robot = mrclam.MrclamRobot(mrclam.load(MRCLAM, seconds=60.0), MRCLAM, seconds=60.0)
    assert isinstance(robot, LandmarkDataset)
    a = run_landmark_dataset(robot, options.replace(seconds=None), progress=False)
    b = run_landmark_dataset(MRCLAM, options, progress=False)
    np.testing.assert_array_equal(a.result.poses, b.result.poses)
    assert a.summary().split("filter:")[0] == b.summary().split("filter:")[0]
    with pytest.raises(ValueError, match="^seconds"):
        LandmarkRun.read(robot, options)


@pytest.mark.parametrize("field, value, error", [
    ("method", "graphslam", ValueError), ("unknown", 1, TypeError), ("association", "nn", ValueError),
    ("robot", 6, ValueError), ("robot", True, TypeError), ("seconds", float("inf"), ValueError),
    ("seconds", 0, ValueError), ("sigma_v", -0.1, ValueError), ("sigma_w", 1e300, ValueError),
    ("sigma_r", 1e-200, ValueError), ("sigma_phi", "0.1", TypeError), ("refine", "yes", ValueError),
])
def test_a_bad_option_is_refused_by_its_field_before_the_data_is_read(tmp_path, field, value, error):
    options = LandmarkRunOptions(unknown=field == "association")
    setattr(options, field, value)
    missing = tmp_path / "missing"
    with pytest.raises(error, match=f"^{field}\\b"):
        LandmarkRun.read(missing, options)
    with pytest.raises(error, match=f"^{field}\\b"):
        LandmarkRunOptions().replace(**{"unknown": field == "association", field: value})


@pytest.mark.parametrize("path, value, error", [
    ("fastslam.num_particles", 0, ValueError), ("fastslam.num_particles", 2.0, TypeError),
    ("fastslam.version", 3, ValueError), ("fastslam.seed", -1, ValueError), ("fastslam.seed", 2 ** 64, ValueError),
    ("fastslam.threads", 0, ValueError), ("hypotheses.bearing_offset_sigma", -0.1, ValueError),
    ("hypotheses.bearing_offset_sigma", float("nan"), ValueError), ("refinement.max_iterations", -1, ValueError),
    ("refinement.merge_probability", 1.0, ValueError), ("refinement.new_landmarks", 1, TypeError),
])
def test_a_bad_field_of_a_group_is_refused_by_its_path(path, value, error):
    """The filters' options objects (and the refinement's) given as a dict of fields, made or
    replaced: the refusal names the field's whole path, as a sweep and the command line say it."""
    group, name = path.split(".")
    with pytest.raises(error, match=f"^{re.escape(path)}\\b"):
        LandmarkRunOptions(**{group: {name: value}})
    with pytest.raises(error, match=f"^{re.escape(path)}\\b"):
        LandmarkRunOptions().replace(**{group: {name: value}})
    with pytest.raises(TypeError, match=f"^{group}: .*unexpected keyword argument 'nope'"):
        LandmarkRunOptions().replace(**{group: {"nope": 1}})
    with pytest.raises(TypeError, match=f"^{group}: expected"):
        LandmarkRunOptions().replace(**{group: 5})


def test_a_group_is_copied_with_the_options():
    """replace() gives the copy groups of its own: a field set on one leaves the other as it was."""
    a = LandmarkRunOptions(method="fastslam", fastslam=dict(num_particles=10))
    b = a.replace(fastslam={"seed": 4})
    assert (b.fastslam.num_particles, b.fastslam.seed, a.fastslam.seed) == (10, 4, 0)
    b.fastslam.num_particles = 7
    assert a.fastslam.num_particles == 10 and a.replace().fastslam is not a.fastslam


@pytest.mark.parametrize("path, options, field", [
    (VICTORIA, dict(robot=2), "robot"),
    (VICTORIA, dict(sigma_phi=0.02), "sigma_phi"),
    (VICTORIA, dict(unknown=True, refine="graphslam"), "refine"),
    (VICTORIA, dict(unknown=True, association="mht", hypotheses=dict(bearing_offset_sigma=0.03)),
     "hypotheses.bearing_offset_sigma"),
    (MRCLAM, dict(refine="graphslam"), "refine"),
    (MRCLAM, dict(unknown=True, association="jcbb", hypotheses=dict(bearing_offset_sigma=0.03)),
     "hypotheses.bearing_offset_sigma"),
    (MRCLAM, dict(method="fastslam", hypotheses=dict(max_hypotheses=3)), "hypotheses.max_hypotheses"),
    (MRCLAM, dict(unknown=True, refinement=dict(new_landmarks=True)), "refinement.new_landmarks"),
    (MRCLAM, dict(association="ml"), "association"),
    (MRCLAM, dict(fastslam=dict(num_particles=10)), "fastslam.num_particles"),
    (MRCLAM, dict(method="fastslam", unknown=True, association="ml"), "association"),
])
def test_an_option_that_does_not_apply_is_refused_by_its_field(path, options, field):
    with pytest.raises(ValueError, match=f"^{field}\\b"):
        LandmarkRun.read(path, LandmarkRunOptions(**options))


def test_options_must_be_landmark_run_options():
    with pytest.raises(TypeError, match="^options"):
        LandmarkRun.read(MRCLAM, {"method": "ekf"})


def test_the_picture_is_drawn_by_the_run(tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot")
    run = run_landmark_dataset(VICTORIA, progress=False)
    fig = run.draw(plt)
    assert fig.axes[0].get_title() == ("probslam ekf-slam: Victoria Park victoria_park_1000.txt\n"
                                       "EKF SLAM, known correspondences")
    plt.close(fig)
    assert len(io.read_trajectory(run.write(str(tmp_path / "v"), "xyt")[0])) == len(run.result.poses)
