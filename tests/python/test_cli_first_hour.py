"""What a new user meets first (issue 49, items 5-7): messages that name the command line's
flags and files, compressed and binary input, a closed output pipe, misspelt and inapplicable
options, defaults in --help, -o to a folder, a corrected CARMEN log as eval's reference, and the
docs that tell how to run and how long the build takes."""

import argparse
import bz2
import gzip
import importlib.util
import lzma
import os
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest

import probslam as ps
from probslam import _core, cli, io
from probslam.plot import ELLIPSE_CONFIDENCE, ellipse_label

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _error(capsys, argv):
    """The one stderr line of a user error (exit status 2)."""
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def _printable(text):
    return all(c.isprintable() or c == "\n" for c in text)


def _tum(path, times, poses):
    io.write_trajectory(np.asarray(times, float), np.asarray(poses, float), str(path), format="tum")
    return str(path)


# --- item 5: messages -----------------------------------------------------------------------

@pytest.mark.skipif(importlib.util.find_spec("rosbags") is None, reason="rosbags is not installed")
def test_a_wrong_topic_names_the_flag_without_a_format_tail(tmp_path, capsys):
    bag = tmp_path / "a.bag"
    io.write_rosbag(io.read_carmen_log(ps.data.path(cli.BUNDLED_RAW_LOG)), bag)
    err = _error(capsys, ["slam", str(bag), "--scan-topic", "/laser", "-o", str(tmp_path / "s"), "--no-progress"])
    assert "--scan-topic: no topic '/laser'" in err and str(bag) in err
    assert "scan_topic" not in err and "expected a ROS bag" not in err


def test_no_pose_pair_names_the_files_and_the_flag_without_a_format_tail(tmp_path, capsys):
    poses = np.zeros((3, 3))
    est = _tum(tmp_path / "est.tum", [0.0, 1.0, 2.0], poses)
    ref = _tum(tmp_path / "ref.tum", [100.0, 101.0, 102.0], poses)
    err = _error(capsys, ["eval", est, ref])
    assert f"{est}: no pose within --max-time-difference 0.01 s" in err
    assert "times_est" not in err and "max_time_difference" not in err and "expected a trajectory" not in err


def test_decreasing_timestamps_are_printed_with_the_digits_that_differ(tmp_path):
    # Unix times 0.3 s apart: nine significant digits print both as 976052862.
    path = _tum(tmp_path / "jump.tum", [976052862.0, 976052862.5, 976052862.2, 976052863.0], np.zeros((4, 3)))
    with pytest.warns(UserWarning, match=r"timestamps decrease 1 times, first at line \d+ \(976052862\.5 then "
                                         r"976052862\.2\)"):
        io.read_trajectory(path)
    with pytest.raises(ValueError, match=r"\(976052862\.5 then 976052862\.2\)"):
        ps.eval.interpolate_poses([976052862.0, 976052862.5, 976052862.2], np.zeros((3, 3)), [976052862.1])


def test_optimize_on_a_compressed_graph_says_so_in_one_printable_line(tmp_path, capsys):
    text = open(ps.data.path(cli.BUNDLED_GRAPH), "rb").read()
    for name, packed, compression in (("g.g2o.bz2", bz2.compress(text), "bzip2"),
                                      ("g.g2o.gz", gzip.compress(text), "gzip"),
                                      ("g.g2o.xz", lzma.compress(text), "xz")):
        (tmp_path / name).write_bytes(packed)
        err = _error(capsys, ["optimize", str(tmp_path / name), "-o", str(tmp_path / "o"), "--no-plot",
                              "--no-progress"])
        assert f"{tmp_path / name}: {compression}-compressed data, not text: decompress it first" in err
        assert _printable(err)


def test_the_cpp_readers_refuse_binary_input_in_one_line(tmp_path):
    log = open(ps.data.path(cli.BUNDLED_LOG), "rb").read()  # gzip-compressed CARMEN log
    (tmp_path / "intel.log.gz").write_bytes(log)
    (tmp_path / "zeros.log").write_bytes(b"FLASER \0\0\0\0\n" * 3)
    with pytest.raises(ValueError) as info:
        _core.read_carmen_log(str(tmp_path / "intel.log.gz"))
    assert str(info.value) == (f"{tmp_path / 'intel.log.gz'}: gzip-compressed data, not text: decompress it first "
                               "(this reader takes plain text)")
    with pytest.raises(ValueError, match=r"zeros\.log: binary data \(a NUL byte in the first line\), not a text file"):
        _core.read_carmen_log(str(tmp_path / "zeros.log"))
    # The Python reader takes a compressed log whatever its name, xz too.
    (tmp_path / "named_plain.log").write_bytes(log)
    (tmp_path / "intel.log.xz").write_bytes(lzma.compress(gzip.decompress(log)))
    expected = io.read_carmen_log(ps.data.path(cli.BUNDLED_LOG)).scans.laser_poses
    for name in ("named_plain.log", "intel.log.xz"):
        np.testing.assert_array_equal(io.read_carmen_log(str(tmp_path / name)).scans.laser_poses, expected)


def test_a_text_log_with_a_damaged_later_line_is_still_read(tmp_path):
    path = tmp_path / "log.log"
    path.write_bytes(b"FLASER 3 1 2 1 0 0 0 0 0 0\nFLASER \0\0\nFLASER 3 1 2 1 0.1 0 0 0.1 0 0\n")
    with pytest.warns(UserWarning, match="skipped 1 malformed line"):
        assert len(io.read_carmen_log(str(path)).scans) == 2


def test_a_closed_output_pipe_ends_quietly_with_the_sigpipe_status(tmp_path):
    # The reader closes its end before probslam writes (python -m probslam ... | head -0).
    proc = subprocess.Popen([sys.executable, "-m", "probslam", "optimize", "--no-plot", "--no-progress", "-o",
                             str(tmp_path / "o")], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == cli.EXIT_BROKEN_PIPE == 141
    assert err == ""


@pytest.mark.parametrize("argv, meant, command", [
    (["slam", "--partcles", "5"], "--particles", "slam"),
    (["optimize", "--max-iteratoins=5"], "--max-iterations", "optimize"),
    (["eval", "a", "b", "--rpee"], "--rpe", "eval"),
    (["optimize", "--algorithm", "levenberg"], "levenberg-marquardt", "optimize"),
    (["slma"], "slam", None),
])
def test_a_misspelt_option_or_choice_gets_the_one_meant_and_the_subcommand_help(argv, meant, command, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"did you mean {meant}?" in err
    assert f"(see 'probslam {command} -h')" in err if command else "(see 'probslam -h')" in err


def test_options_given_are_told_from_defaults():
    given = cli.parser.given_options(["slam", "--method", "rbpf", "--partic", "30", "-o", "x", "--no-plot"])
    assert {d: f for d, f in given.items() if d != "command"} == {
        "method": "--method", "particles": "--particles", "output": "--output", "plot": "--no-plot"}
    assert set(cli.parser.given_options(["eval", "a", "b"])) == {"command", "estimate", "reference"}


def _bundled_victoria_park():
    return ps.data.path("victoria_park_1000.txt")


@pytest.mark.parametrize("argv, flag", [
    # The default's own value too: the option does not apply, whatever it says.
    (["slam", "--particles", "30"], "--particles"),
    (["slam", "--proposal", "motion"], "--proposal"),
    (["slam", "--method", "rbpf", "--submap-distance", "5"], "--submap-distance"),
    (["slam", "--method", "rbpf", "--no-loop-closures"], "--no-loop-closures"),
    (["slam", "--resume", "run.psl", "--method", "rbpf"], "--method"),
    (["map", "--inverse-model", "bundled", "--robot-radius", "0.2"], "--robot-radius"),
    (["ekf-slam", "--association", "mht"], "--association"),
    (["ekf-slam", "VP", "--robot", "2"], "--robot"),
    (["fastslam", "VP", "--sigma-r", "0.1"], "--sigma-r"),
    (["optimize", "--poses-per-step", "50"], "--poses-per-step"),
    (["optimize", "--kernel-width", "2"], "--kernel-width"),
    (["optimize", "--edges", "--no-plot"], "--edges"),
    (["eval", "EST", "REF", "--delta", "2"], "--delta"),
    (["eval", "EST", "REF", "--delta-unit", "m"], "--delta-unit"),
    (["eval", "EST", "aces.relations", "--max-time-difference", "0.1"], "--max-time-difference"),
])
def test_an_option_that_does_not_apply_is_refused_by_name(argv, flag, tmp_path, capsys):
    est = _tum(tmp_path / "est.tum", [0.0, 1.0], np.zeros((2, 3)))
    (tmp_path / "aces.relations").write_text("0 1 0 0 0 0 0 0\n")
    files = {"VP": _bundled_victoria_park(), "EST": est, "REF": est, "aces.relations": str(tmp_path / "aces.relations")}
    argv = [files.get(a, a) for a in argv] + ["-o", str(tmp_path / "out")] * (argv[0] != "eval")
    err = _error(capsys, argv)
    assert err.startswith(f"probslam: error: {flag} ")


# --- item 6: gaps ---------------------------------------------------------------------------

def test_eval_scores_against_a_corrected_carmen_log(tmp_path, capsys):
    reference = io.read_carmen_log(ps.data.path(cli.BUNDLED_LOG)).scans
    rng = np.random.default_rng(0)
    noise = np.column_stack([rng.normal(0, 0.05, (len(reference), 2)), np.zeros(len(reference))])
    # The estimate in another frame (turned and moved), with noise: the aligned error is the noise's.
    c, s = np.cos(0.7), np.sin(0.7)
    moved = (reference.laser_poses[:, :2] + noise[:, :2]) @ np.array([[c, -s], [s, c]]).T + [3.0, -1.0]
    est = _tum(tmp_path / "est.tum", reference.timestamps,
               np.column_stack([moved, ps.wrap_angle(reference.laser_poses[:, 2] + 0.7)]))
    assert cli.main(["eval", est, ps.data.path(cli.BUNDLED_LOG)]) == 0
    out = capsys.readouterr().out
    expected = ps.eval.ate(reference.timestamps, reference.laser_poses + noise, reference.timestamps,
                           reference.laser_poses)
    assert f"{len(reference)} poses (CARMEN log" in out
    assert re.search(rf"rmse\s+{expected.rmse:.6f}", out), out
    # Against the numpy definition: the RMS of the noise after the best rigid fit.
    assert abs(expected.rmse - np.sqrt(np.mean(np.sum(noise[:, :2] ** 2, axis=1)))) < 0.01


def test_eval_says_when_a_carmen_reference_has_another_clock(tmp_path, capsys):
    reference = io.read_carmen_log(ps.data.path(cli.BUNDLED_LOG)).scans
    # The ipc time of the raw log where the corrected one carries the logger time.
    est = _tum(tmp_path / "est.tum", reference.timestamps + 976052857.0, reference.laser_poses)
    err = _error(capsys, ["eval", est, ps.data.path(cli.BUNDLED_LOG)])
    assert "do not overlap the estimate's" in err and "logger time" in err


def test_an_output_folder_holds_files_named_for_the_command(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    assert cli.main(["optimize", "--no-progress", "-o", str(out) + "/"]) == 0
    assert cli.main(["map", "--no-progress", "--no-plot", "-o", str(out)]) == 0
    capsys.readouterr()
    names = sorted(p.name for p in out.iterdir())
    assert names == ["map.pgm", "map.yaml", "optimized.g2o", "optimized.png", "optimized_trajectory.tum"]
    err = _error(capsys, ["map", "--no-progress", "-o", str(tmp_path / "missing") + "/"])
    assert f"folder {tmp_path / 'missing'} does not exist" in err


def _subparsers(parser):
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def test_every_option_with_a_value_shows_its_default_in_help():
    commands = _subparsers(cli.build_parser())
    assert set(commands) == {"map", "slam", "localize", "ekf-slam", "fastslam", "optimize", "eval", "batch"}
    missing = []
    for name, parser in commands.items():
        formatter = parser._get_formatter()
        for action in parser._actions:
            if action.option_strings and action.nargs != 0:
                text = formatter._expand_help(action) if action.help else ""
                if "default" not in text.lower():
                    missing.append(f"{name} {action.option_strings[-1]}")
    assert missing == []
    optimize = commands["optimize"].format_help()
    for default in ("(default: gauss-newton)", "(default: 100)", "(default: auto)", "(default: none)"):
        assert default in " ".join(optimize.split())
    ekf = " ".join(commands["ekf-slam"].format_help().split())
    assert f"(default: {ps.datasets.mrclam.MOTION_SIGMA[0]})" in ekf
    assert f"(default: {ps.datasets.mrclam.MEASUREMENT_SIGMA[1]})" in ekf


# --- item 7: docs ---------------------------------------------------------------------------

def test_the_docs_say_to_activate_the_environment():
    for page in ("README.md", "docs/install.md", "docs/cli.md"):
        assert "source .venv/bin/activate" in " ".join((ROOT / page).read_text().split()), page


def test_one_build_time_is_stated_and_a_rebuild_is_incremental():
    """Every build or compile time in minutes in the README, install.md and setup.sh is the
    measured one of install.md's 'Build time'."""
    install = (ROOT / "docs/install.md").read_text()
    measured = " ".join(re.search(r"### Build time\n\n(.*?)\n\n", install, re.S).group(1).split())
    assert re.search(r"`setup.sh` took (\d+(?:\.\d+)?) min, (\d+(?:\.\d+)?) of them compiling", measured)
    figures = set(re.findall(r"\d+(?:\.\d+)?", measured))
    for page in ("README.md", "docs/install.md", "scripts/setup.sh"):
        text = " ".join((ROOT / page).read_text().split())
        for sentence in re.split(r"(?<=[.;:])\s", text):
            if re.search(r"build|compil", sentence, re.I):
                for figure in re.findall(r"(\d+(?:\.\d+)?(?:-\d+)?) min", sentence):
                    assert figure in figures, (page, sentence)
    setup = (ROOT / "scripts/setup.sh").read_text()
    assert re.search(r'build_kind="a rebuild: incremental', setup)
    assert "about 15 minutes" not in setup


@pytest.mark.slow  # a whole-file FastSLAM run: about 20 s under the sanitizers
def test_landmark_fastslam_doc_states_the_picture_and_the_count_measured(tmp_path, capsys, shared_data):
    victoria_park = str(shared_data / "landmark_slam/victoria_park/victoriaPark.txt")
    doc = " ".join((ROOT / "docs/landmark_fastslam.md").read_text().split())
    assert "2-sigma" not in doc and ellipse_label(ELLIPSE_CONFIDENCE).split(" (")[0] in doc
    stated = re.search(r"`probslam fastslam \S+victoriaPark.txt --unknown --variant 2` keeps (\d+) landmarks", doc)
    assert cli.main(["fastslam", victoria_park, "--unknown", "--variant", "2", "--no-plot", "--no-progress",
                     "-o", str(tmp_path / "f")]) == 0
    measured = re.search(r"landmarks:\s+(\d+) in the best particle's map", capsys.readouterr().out).group(1)
    assert stated.group(1) == measured
