"""Issue 48: a state file's counts are bounded by its bytes and agree with each other before
anything is used (edited payloads with their checksums recomputed, as the fuzz harness's
state_file target makes them); an interrupted ``slam --save`` leaves a file that resumes; a run
file's destination and metadata are user errors, not bugs."""

import gzip
import json
import os
import pathlib
import shlex
import signal
import struct
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from probslam import cli
from probslam.slam import RUN_FORMAT_VERSION, RUN_MAGIC, load_run
from probslam.data import path as data_path

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "fuzz"))
import make_seeds  # noqa: E402
import targets  # noqa: E402

# A load that loops over a claimed count instead of refusing it never ends: bounded here.
LOAD_TIMEOUT_S = 120


@pytest.fixture(scope="module")
def states():
    return make_seeds.small_states()


def payload_of(obj) -> bytes:
    return targets.state_payload(make_seeds.state_bytes(obj))[1]


def load_in_subprocess(tmp_path, tag, payload):
    """What loading the framed payload prints, in a process of its own (a reader that loops over
    a claimed count hangs rather than refuses: the timeout makes that a failure)."""
    path = tmp_path / "edited.psl"
    path.write_bytes(targets.frame_state(tag, payload))
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(pathlib.Path(targets.__file__).parent)!r})
        import targets
        try:
            targets.state_class({tag!r}).load({str(path)!r})
            print("loaded")
        except ValueError as e:
            print("ValueError:", e)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=LOAD_TIMEOUT_S)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def matrix_at(payload: bytes, offset: int, rows: int, cols: int, skip: int) -> bytes:
    """payload with the matrix header at offset claiming rows x cols and its `skip` entries gone."""
    return payload[:offset] + struct.pack("<qq", rows, cols) + payload[offset + 16 + 8 * skip:]


# (class, payload offset of a matrix with both dimensions dynamic, its entries as saved):
# FastSlam's motion noise after its options (FastSlamOptions::describe(): 5 int32, 11 doubles, a
# uint64, 4 flags); EkfSlam's Q after the control flag, the 3 x 3 pose noise and the 2 x 2 control noise.
DYNAMIC_MATRICES = [("FastSlam", 5 * 4 + 11 * 8 + 8 + 4, 9), ("EkfSlam", 1 + 88 + 48, 4)]


@pytest.mark.parametrize("tag,offset,entries", DYNAMIC_MATRICES)
@pytest.mark.parametrize("rows,cols", [(0, 1 << 62), (1 << 62, 0), (1 << 33, 1 << 33), (3, 1 << 61)])
def test_matrix_dimensions_are_bounded_by_the_bytes_left(states, tmp_path, tag, offset, entries, rows, cols):
    payload = payload_of(states[tag])
    assert struct.unpack_from("<qq", payload, offset)[0] * struct.unpack_from("<qq", payload, offset)[1] == entries
    out = load_in_subprocess(tmp_path, tag, matrix_at(payload, offset, rows, cols, entries))
    assert out.startswith("ValueError:") and "bytes left" in out, out


def test_submap_slam_without_offset_covariances_is_refused(states):
    """The loop-closure search reads a scan's offset covariance by its index: a file that holds
    fewer than one per scan loaded before and read past the vector on the next search."""
    slam = states["SubmapSlam2D"]
    payload = payload_of(slam)
    n = slam.num_scans
    block = struct.pack("<Qqq", n, 3, 3)  # the offset covariances' count and first header
    at = payload.index(block)
    assert payload.count(block) == 1
    matrix = 16 + 72
    for kept in (0, n - 1):
        edited = payload[:at] + struct.pack("<Q", kept) + payload[at + 8:at + 8 + kept * matrix] + \
            payload[at + 8 + n * matrix:]
        with pytest.raises(ValueError, match="offset covariances do not match"):
            type(slam).__new__(type(slam)).__setstate__(targets.frame_state("SubmapSlam2D", edited))
    # The graph's nodes: one per submap.
    nodes = slam.num_submaps
    after = at + 8 + n * matrix
    assert struct.unpack_from("<Q", payload, after)[0] == nodes
    edited = payload[:after] + struct.pack("<Q", nodes - 1) + payload[after + 8:after + 8 + (nodes - 1) * 40] + \
        payload[after + 8 + nodes * 40:]
    with pytest.raises(ValueError, match="nodes do not match"):
        type(slam).__new__(type(slam)).__setstate__(targets.frame_state("SubmapSlam2D", edited))


def test_every_state_seed_loads_through_the_fuzz_target(states, tmp_path):
    """The state_file target frames a payload with a valid checksum: the seeds (every class's
    payload as saved) load to the saved state, and a flipped payload byte reaches the reader
    (ValueError or a loaded object; nothing else)."""
    ws = targets.Workspace(tmp_path)
    assert targets.STATE_CLASSES == tuple(states)
    for index, (tag, obj) in enumerate(states.items()):
        framed = make_seeds.state_bytes(obj)
        assert targets.frame_state(tag, payload_of(obj)) == framed
        targets.check(targets.TARGETS["state_file"], ws, bytes([index]) + payload_of(obj))
        loaded = targets.state_class(tag).load(tmp_path / "state.psl")
        assert loaded.__getstate__() == framed
        rng = np.random.default_rng(index)
        payload = bytearray(payload_of(obj))
        for k in rng.integers(0, len(payload), 20):
            edited = bytearray(payload)
            edited[k] ^= 1 << int(rng.integers(8))
            targets.check(targets.TARGETS["state_file"], ws, bytes([index]) + bytes(edited))


# ---- run files: slam --save / --resume ----

def part_log(tmp_path, scans):
    """The bundled raw log's first `scans` laser scans, as a CARMEN file."""
    lines = gzip.decompress(open(data_path(cli.BUNDLED_RAW_LOG), "rb").read()).decode().splitlines(True)
    lasers = [s for s in lines if s.startswith("FLASER")]
    path = tmp_path / "part.log"
    path.write_text("".join([s for s in lines if not s.startswith("FLASER")] + lasers[:scans]))
    return str(path)


# Runs the CLI with run_slam's chunks made small; as each add_scans runs (its C++ work holds no
# GIL), a thread prints a line, so that the test can send SIGINT while the call is under way.
SLAM_SCRIPT = """
import signal, sys, threading, time
from probslam import _core, cli, slam

slam.run_slam.__kwdefaults__["chunk"] = CHUNK
# Ctrl-C as from a terminal: a test runner's worker process may ignore SIGINT, and a child
# inherits that (Python then installs no KeyboardInterrupt handler).
signal.signal(signal.SIGINT, signal.default_int_handler)

def announced(cls):
    class Announced(cls):
        def add_scans(self, *args):
            def announce():
                time.sleep(0.01)  # the main thread is inside add_scans by then (a chunk takes > 0.07 s)
                print("in add_scans", flush=True)
            threading.Thread(target=announce, daemon=True).start()
            super().add_scans(*args)
    Announced.__name__ = cls.__name__
    return Announced

_core.SubmapSlam2D = announced(_core.SubmapSlam2D)
_core.GridFastSlam = announced(_core.GridFastSlam)
sys.exit(cli.main(sys.argv[1:]))
"""
CHUNK = 60


@pytest.mark.parametrize("method", ["graph", "rbpf"])
def test_ctrl_c_during_add_scans_leaves_a_run_file_that_resumes(tmp_path, capsys, method):
    log = part_log(tmp_path, 3 * CHUNK)
    run = str(tmp_path / "run.psl")
    opts = ["--no-plot", "--no-progress"]
    method_opts = ["--method", method] + (["--particles", "3"] if method == "rbpf" else [])
    script = tmp_path / "slam_script.py"
    script.write_text(SLAM_SCRIPT.replace("CHUNK", str(CHUNK), 1))
    proc = subprocess.Popen([sys.executable, str(script), "slam", log, "--save", run, "-o", str(tmp_path / "cut")]
                            + method_opts + opts, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # SIGINT while the second chunk's add_scans runs: the first chunk is complete, the second
    # completes in C++ and Python sees the signal as the call returns.
    for _ in range(2):
        assert proc.stdout.readline().strip() == "in add_scans"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == cli.EXIT_INTERRUPTED, err
    saved = load_run(run)  # metadata and object agree
    assert saved.scans_done == 2 * CHUNK and saved.mapper.num_scans == saved.scans_done
    assert not os.path.exists(run + ".tmp")
    assert "run file" in err and "written" in err and "Traceback" not in err
    command = shlex.split(err.split("to continue: ", 1)[1].strip())
    assert command[:2] == ["probslam", "slam"] and "--resume" in command
    # The command printed continues the run; the result is that of a run that never stopped.
    assert cli.main(command[1:] + ["--no-progress"]) == 0
    assert "resumed:" in capsys.readouterr().out
    assert cli.main(["slam", log, "-o", str(tmp_path / "one")] + method_opts + opts) == 0
    assert (tmp_path / "cut_trajectory.tum").read_bytes() == (tmp_path / "one_trajectory.tum").read_bytes()
    assert (tmp_path / "cut.pgm").read_bytes() == (tmp_path / "one.pgm").read_bytes()


def test_save_destination_is_checked_before_the_run(tmp_path, capsys):
    log = part_log(tmp_path, 30)
    folder = tmp_path / "runs"
    folder.mkdir()
    for bad, what in [(folder, "is a directory"), (tmp_path / "missing" / "run.psl", "does not exist")]:
        assert cli.main(["slam", log, "--save", str(bad), "-o", str(tmp_path / "x"), "--no-plot",
                         "--no-progress"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("probslam: error: --save") and what in err and ".tmp" not in err
        assert "\n" not in err
        assert not os.path.exists(str(bad) + ".tmp")
        assert not (tmp_path / "x.yaml").exists()  # refused before the run


def run_file(meta: bytes) -> bytes:
    return RUN_MAGIC + struct.pack("<II", RUN_FORMAT_VERSION, len(meta)) + meta


@pytest.mark.parametrize("meta", [b"[" * 100_000 + b"]" * 100_000,
                                  json.dumps({"method": ["graph"], "scans_done": 1, "first_timestamp": 0,
                                              "last_timestamp": 0, "log_scans": 1}).encode(),
                                  json.dumps({"method": "graph", "scans_done": 1, "first_timestamp": 10 ** 400,
                                              "last_timestamp": 0, "log_scans": 1}).encode()])
def test_damaged_run_metadata_is_a_user_error(tmp_path, capsys, meta):
    path = tmp_path / "run.psl"
    path.write_bytes(run_file(meta))
    with pytest.raises(ValueError, match="corrupt run metadata") as e:
        load_run(path)
    assert str(e.value).startswith(str(path))
    log = part_log(tmp_path, 30)
    assert cli.main(["slam", log, "--resume", str(path), "-o", str(tmp_path / "x"), "--no-plot"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("probslam: error:") and "corrupt run metadata" in err and "\n" not in err


def test_every_class_the_format_names_saves_loads_and_pickles():
    """docs/file_format.md names the classes with a state file: each has save, load and pickle
    (PoseGraph3D and MonteCarloLocalization had none), and the fuzz target reads them all."""
    import re

    text = (pathlib.Path(__file__).resolve().parents[2] / "docs" / "file_format.md").read_text()
    first = text.split("\n\n")[1]
    named = set(re.findall(r"`([A-Z][A-Za-z0-9]+)`", first.split(", in C++")[0]))
    assert named == set(targets.STATE_CLASSES)
    for tag in named:
        cls = targets.state_class(tag)
        assert callable(cls.save) and callable(cls.load) and "__setstate__" in dir(cls), tag
