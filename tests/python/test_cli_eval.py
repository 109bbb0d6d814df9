"""`probslam eval EST REF` (issue 36): what evo_ape / evo_rpe print, or the relations error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from probslam import cli
from probslam import eval as ev
from probslam import io


def write_pair(tmp_path, n=200, seed=0):
    rng = np.random.default_rng(seed)
    times = 50.0 + np.cumsum(rng.uniform(0.05, 0.2, n))
    theta = np.cumsum(rng.normal(0.0, 0.1, n))
    ref = np.column_stack([np.cumsum(0.3 * np.cos(theta)), np.cumsum(0.3 * np.sin(theta)), np.angle(np.exp(1j * theta))])
    est = ref + rng.normal(0.0, [0.05, 0.05, 0.02], (n, 3))
    est[:, :2] = est[:, :2] @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + 5.0  # another frame
    io.write_trajectory(times, ref, tmp_path / "ref.tum")
    io.write_trajectory(times, est, tmp_path / "est.tum")
    return times, ref, est


def table(out):
    """{name: value} of the statistics rows printed."""
    rows = [line.split("\t") for line in out.splitlines() if "\t" in line]
    return {name.strip(): float(value) for name, value in rows}


def test_eval_prints_the_ate_table_as_evo_ape(tmp_path, capsys):
    times, ref, est = write_pair(tmp_path)
    assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "ref.tum")]) == 0
    out = capsys.readouterr().out
    assert "APE w.r.t. translation part (m)\n(with SE(2) Umeyama alignment)\n\n       max\t" in out
    assert f"associated:    {len(times)} of {len(times)} possible pose pairs within 0.01 s" in out
    est_read, ref_read = io.read_trajectory(tmp_path / "est.tum"), io.read_trajectory(tmp_path / "ref.tum")
    result = ev.ate(est_read.timestamps, est_read.poses, ref_read.timestamps, ref_read.poses)
    assert list(table(out)) == ["max", "mean", "median", "min", "rmse", "sse", "std"]
    assert table(out) == {name: round(value, 6) for name, value in result.statistics.items()}
    assert 0.0 < result.rmse < 0.2


def test_eval_output_is_evo_apes(tmp_path, capsys):
    """The lines evo's Result.pretty_str prints, character for character (the title's alignment
    line aside: SE(2) here, SE(3) in evo)."""
    pytest.importorskip("evo", reason="evo (a test-only dependency) is not installed")
    import copy

    from evo.core import metrics, sync
    from evo.tools import file_interface

    write_pair(tmp_path, seed=3)
    ref = file_interface.read_tum_trajectory_file(str(tmp_path / "ref.tum"))
    est = file_interface.read_tum_trajectory_file(str(tmp_path / "est.tum"))
    ref, est = sync.associate_trajectories(ref, est)
    aligned = copy.deepcopy(est)
    aligned.align(ref)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, aligned))
    evo_rows = ape.get_result().pretty_str(title=False)
    assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "ref.tum")]) == 0
    assert capsys.readouterr().out.endswith("\n\n" + evo_rows)
    rpe = metrics.RPE(metrics.PoseRelation.translation_part, delta=3, delta_unit=metrics.Unit.frames)
    rpe.process_data((ref, est))
    assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "ref.tum"), "--rpe", "--delta", "3"]) == 0
    out = capsys.readouterr().out
    assert "RPE w.r.t. translation part (m)\nfor delta = 3 (frames) using consecutive pairs\n(not aligned)" in out
    assert out.endswith("\n\n" + rpe.get_result().pretty_str(title=False))


def test_eval_options(tmp_path, capsys):
    write_pair(tmp_path)
    est, ref = str(tmp_path / "est.tum"), str(tmp_path / "ref.tum")
    assert cli.main(["eval", est, ref, "--no-align"]) == 0
    out = capsys.readouterr().out
    assert "(not aligned)" in out and table(out)["min"] > 1.0  # another frame: metres off
    assert cli.main(["eval", est, ref, "--rpe", "--delta", "2", "--delta-unit", "m", "--align"]) == 0
    out = capsys.readouterr().out
    assert "for delta = 2 (m) using consecutive pairs\n(with SE(2) Umeyama alignment)" in out
    # KITTI and 't x y theta' files are read as well (KITTI's times from its times file).
    e = io.read_trajectory(est)
    io.write_trajectory(e.timestamps, e.poses, tmp_path / "est.kitti", format="kitti")
    assert cli.main(["eval", str(tmp_path / "est.kitti"), ref]) == 0
    assert "(KITTI)" in capsys.readouterr().out


def test_eval_against_relations_as_slam_scores_them(tmp_path, capsys):
    """REF a relations file: the relations error of the estimate (Kümmerle et al.), the same
    numbers as probslam.eval.relations_error."""
    times, ref, est = write_pair(tmp_path, n=100)
    pairs = [(i, i + 5) for i in range(0, 90, 3)]
    delta = ev.relative_poses(ref[[i for i, _ in pairs]], ref[[j for _, j in pairs]])
    with open(tmp_path / "run.relations", "w") as f:
        for (i, j), d in zip(pairs, delta):
            f.write(f"{times[i]:.9f} {times[j]:.9f} {d[0]:.9f} {d[1]:.9f} 0 0 0 {d[2]:.9f}\n")
    assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "run.relations")]) == 0
    out = capsys.readouterr().out
    read = io.read_trajectory(tmp_path / "est.tum")
    error = ev.relations_error(read.timestamps, read.poses, tmp_path / "run.relations")
    assert f"relations:     {len(pairs)} used, 0 outside" in out
    first, second = out.split("relations error w.r.t. rotation")
    assert table(first)["mean"] == round(error.trans_mean, 6)
    assert table(second)["mean"] == round(math.degrees(np.mean(error.rotational)), 6)
    assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "run.relations"), "--rpe"]) == 2
    assert "--rpe applies to a reference trajectory, not to relations" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--delta", "0"], "--delta must be finite and > 0"),
    (["--rpe", "--delta", "1.5"], "--delta must be a whole number of frames"),
    (["--max-time-difference", "nan"], "--max-time-difference must be finite and > 0"),
])
def test_eval_option_errors_are_one_line(tmp_path, capsys, argv, message):
    write_pair(tmp_path, n=20)
    assert cli.main(["eval", str(tmp_path / "est.tum"), str(tmp_path / "ref.tum")] + argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_eval_file_errors_name_the_file(tmp_path, capsys):
    write_pair(tmp_path, n=20)
    assert cli.main(["eval", str(tmp_path / "missing.tum"), str(tmp_path / "ref.tum")]) == 2
    assert "missing.tum: no such file" in capsys.readouterr().err
    (tmp_path / "words.tum").write_text("not a trajectory\n")
    assert cli.main(["eval", str(tmp_path / "words.tum"), str(tmp_path / "ref.tum")]) == 2
    assert "words.tum: no valid trajectory rows" in capsys.readouterr().err
    far = io.read_trajectory(tmp_path / "ref.tum")
    io.write_trajectory(far.timestamps + 1000.0, far.poses, tmp_path / "later.tum")
    assert cli.main(["eval", str(tmp_path / "later.tum"), str(tmp_path / "ref.tum")]) == 2
    assert "no pose within --max-time-difference" in capsys.readouterr().err
