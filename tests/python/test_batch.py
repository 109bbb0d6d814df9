"""probslam batch: sweeps on Dask distributed. On a LocalCluster of two worker processes: a sweep
gives the rows its runs give alone; a run that raises, one past its time limit and one whose
worker is killed (SIGKILL, by a test-only run kind) each leave one row and the sweep goes on; a
sweep stopped by Ctrl-C leaves its table complete and, started again, makes only what is missing;
a sweep with an unknown key or option is refused in one line before anything runs."""

import _thread
import dataclasses
import json
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

if os.environ.get("PROBSLAM_SANITIZED"):  # before dask is imported: worker processes are not what that run tests
    pytest.skip("the sanitized run (scripts/sanitize.sh) leaves sweeps out", allow_module_level=True)
distributed = pytest.importorskip("distributed")
pytest.importorskip("pyarrow")
cloudpickle = pytest.importorskip("cloudpickle")

from probslam import batch, cli  # noqa: E402
from probslam.batch import table  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "sweep_demo.toml"
PROBSLAM = [sys.executable, "-m", "probslam"]
#: The metrics of a run made twice (alone and on a worker) are the same computation: equal bit for
#: bit; only the cost columns, the worker and a localize run's own timing of its filter differ.
COST = set(table.COST_COLUMNS) | {"worker", "seconds", "real_time_factor"}


@dataclasses.dataclass
class ProbeOptions:
    """The options of the test-only kind: what it does."""

    action: str = "ok"  # ok, raise, sleep, kill-once (SIGKILL its own worker the first time), kill
    value: int = 0

    def replace(self, **fields):
        out = dataclasses.replace(self, **fields)
        if out.action not in ("ok", "raise", "sleep", "kill-once", "kill"):
            raise ValueError(f"action must be ok, raise, sleep, kill-once or kill, got {out.action!r}")
        return out


def probe(dataset, values, inputs):
    options = batch.set_options(ProbeOptions(), values)
    if options.action == "raise":
        raise RuntimeError(f"probe {options.value} raised")
    if options.action == "sleep":
        time.sleep(60)
    if options.action == "kill-once":
        marker = pathlib.Path(inputs["folder"]) / f"killed-{options.value}"
        if not marker.exists():
            marker.write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGKILL)  # the worker process dies mid-run
    if options.action == "kill":  # a crash, every time
        os.kill(os.getpid(), signal.SIGKILL)
    return batch.Outcome({"value": options.value * 2, "pid": os.getpid()})


PROBE = batch.RunKind("probe", ProbeOptions, probe, ("value", "pid"), inputs={"folder": True})


@pytest.fixture(scope="module")
def client():
    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import this file
    batch.register(PROBE)
    c = batch.start_client(workers=2, memory_limit="2GB")
    yield c
    c.close()
    del batch.KINDS["probe"]


def _metrics(row):
    return {k: v for k, v in row.items() if k not in COST}


def _given(row):
    """A row without the columns it does not have (the table fills them with None)."""
    return {k: v for k, v in row.items() if v is not None}


def test_a_sweep_gives_the_rows_its_runs_give_alone(client, tmp_path):
    sweep = batch.Sweep([
        batch.RunGroup("optimize", ["bundled:*_400.g2o"], {"algorithm": ["gauss-newton", "levenberg-marquardt"]}),
        batch.RunGroup("localize", ["bundled:intel_raw_loop.log.gz"], {"max_particles": [1000, 3000]}, seeds=[0, 1],
                       inputs={"map": "bundled:intel_raw_loop_map.yaml"}, reference="bundled:intel_excerpt.log.gz")])
    runs = sweep.expand()
    assert len(runs) == 8 and len({r.run_id for r in runs}) == 8
    rows = batch.run(sweep, client, str(tmp_path), trajectories=True)
    assert [row["run_id"] for row in rows] == [r.run_id for r in runs]
    assert all(row["status"] == "ok" for row in rows), [row["error"] for row in rows]
    assert {row["worker"] for row in rows} <= set(client.scheduler_info()["workers"])
    for run, row in zip(runs, rows):
        assert _metrics(batch.run_one(run)) == {k: v for k, v in _metrics(row).items() if k != "trajectory"}
    # The trajectories kept are the ones scored: scored again, the same figure.
    from probslam.pipelines import EvaluationOptions, evaluate_trajectory
    for row in rows:
        kept = tmp_path / batch.TRAJECTORIES / row["trajectory"]
        assert kept.name.startswith(row["run_id"]) and kept.is_file()
        if row["kind"] == "localize":
            again = evaluate_trajectory(str(kept), row["reference"], EvaluationOptions())
            assert again.result.rmse == row["ate_rmse_m"]
    # The table on disk holds the same rows, typed (Parquet) and as text (CSV).
    back = {row["run_id"]: row for row in table.read(str(tmp_path))}  # in the order the runs finished
    assert [_given(back[row["run_id"]]) for row in rows] == [_given(row) for row in rows]
    csv_lines = (tmp_path / batch.CSV).read_text().splitlines()
    assert len(csv_lines) == 9 and csv_lines[0].startswith("run_id,kind,dataset,seed,reference,options.")
    localize = [row for row in rows if row["kind"] == "localize"]
    assert all(row["ate_rmse_m"] > 0 and row["scans"] == 630 for row in localize)
    assert "localize (medians" in batch.summary(rows)


def test_a_run_that_raises_times_out_or_kills_its_worker_is_one_row_each(client, tmp_path):
    data = tmp_path / "data.txt"
    data.write_text("")
    sweep = batch.Sweep([
        batch.RunGroup("probe", [str(data)], {"action": "ok", "value": [1, 2, 3]}, inputs={"folder": str(tmp_path)}),
        batch.RunGroup("probe", [str(data)], {"action": "raise", "value": 4}, inputs={"folder": str(tmp_path)}),
        batch.RunGroup("probe", [str(data)], {"action": "kill-once", "value": 5}, inputs={"folder": str(tmp_path)}),
        batch.RunGroup("probe", [str(data)], {"action": "sleep", "value": 6}, inputs={"folder": str(tmp_path)}),
    ], time_limit=1.5)
    out = tmp_path / "out"
    out.mkdir()
    rows = batch.run(sweep, client, str(out))
    assert len(rows) == 6 and len({row["run_id"] for row in rows}) == 6
    status = {row["options.value"]: (row["status"], row["error"]) for row in rows}
    assert [status[v][0] for v in (1, 2, 3)] == ["ok"] * 3
    assert status[4] == ("error", "RuntimeError: probe 4 raised")
    killed = next(row for row in rows if row["options.value"] == 5)
    first_pid = int((tmp_path / "killed-5").read_text())
    assert killed["status"] == "ok" and killed["value"] == 10 and killed["pid"] != first_pid  # retried elsewhere
    assert status[6][0] == "timeout" and "1.5 s" in status[6][1]
    assert len(table.read(str(out))) == 6


@pytest.mark.slow  # three worker processes started again: 5-15 s
def test_a_run_that_kills_every_worker_it_is_given_is_recorded_killed_and_the_others_are_not(client, tmp_path):
    data = tmp_path / "data.txt"
    data.write_text("")
    sweep = batch.Sweep([
        batch.RunGroup("probe", [str(data)], {"action": "kill", "value": 7}, inputs={"folder": str(tmp_path)}),
        batch.RunGroup("probe", [str(data)], {"action": "ok", "value": [8, 9, 10, 11]}, inputs={"folder": str(tmp_path)}),
    ])
    rows = batch.run(sweep, client)
    assert len(rows) == 5 and len({row["run_id"] for row in rows}) == 5
    status = {row["options.value"]: (row["status"], row["error"]) for row in rows}
    assert status[7][0] == "killed" and f"died {batch.ALLOWED_FAILURES + 1} times" in status[7][1]
    assert [status[v] for v in (8, 9, 10, 11)] == [("ok", None)] * 4


def test_a_sweep_stopped_by_ctrl_c_makes_only_what_is_missing_when_started_again(client, tmp_path, capsys):
    """The demo sweep through the command line, on the module's cluster (--scheduler), stopped by
    Ctrl-C (a KeyboardInterrupt in the main thread, as a terminal's SIGINT gives) after its first
    row, then started again."""
    out = tmp_path / "out"
    cmd = ["batch", str(DEMO), "-o", str(out), "--scheduler", client.scheduler.address, "--no-progress"]

    def press_ctrl_c():
        deadline = time.monotonic() + 60
        while not (out / batch.PARQUET).exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        _thread.interrupt_main()

    # interrupt_main does nothing where SIGINT is ignored, as a runner started in the background
    # (a non-interactive shell's `&`) passes it to pytest and its workers: the terminal's handler here.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Thread(target=press_ctrl_c, daemon=True).start()
        assert cli.main(cmd) == 130
    finally:
        signal.signal(signal.SIGINT, previous)
    assert "holds every run that finished" in capsys.readouterr().err
    done = table.read(str(out))
    assert 0 < len(done) < 12
    assert cli.main(cmd) == 0
    printed = capsys.readouterr().out
    assert "12 runs, 0 failed" in printed and "localize (medians" in printed and "optimize (medians" in printed
    rows = table.read(str(out))
    assert len(rows) == 12 and len({row["run_id"] for row in rows}) == 12
    assert [_given(row) for row in rows[:len(done)]] == [_given(row) for row in done]  # kept, not made again
    assert {row["run_id"] for row in rows} == {r.run_id for r in batch.load(DEMO).expand()}
    assert (out / batch.CSV).read_text().count("\n") == 13
    figures = {p.name for p in (out / batch.FIGURES).glob("*.png")}
    assert f"figures: {len(figures)} in" in printed
    assert {"optimize_chi2.png", "localize_ate_rmse_m.png", "localize_cpu_s.png"} <= figures


def test_a_figure_per_measured_metric_with_each_group_of_seeds_on_its_line(tmp_path):
    """Synthetic rows of two option values x three seeds: one figure per metric some ok run
    measured (none for a metric only failed runs have), each group's runs on their line."""
    pytest.importorskip("matplotlib")
    rows = [{"run_id": f"{k}{s}", "kind": "localize", "dataset": "/data/a.log", "seed": s, "status": "ok",
             "error": None, "options.max_particles": k, "ate_rmse_m": 0.1 * (s + 1) * k, "wall_s": 1.0,
             "cpu_s": 1.0, "peak_memory_mb": 10.0, "never_ok": None} for k in (1, 2) for s in range(3)]
    rows.append(dict(rows[0], run_id="x", status="error", never_ok=5.0))
    options, _ = table.kind_columns(rows)
    groups = table.groups(rows, options)
    assert list(groups) == [("a.log", "max_particles=1"), ("a.log", "max_particles=2")]
    assert [len(g) for g in groups.values()] == [4, 3]
    paths = batch.plot(rows, str(tmp_path))
    assert sorted(os.path.basename(p) for p in paths) == ["localize_ate_rmse_m.png", "localize_cpu_s.png",
                                                          "localize_peak_memory_mb.png", "localize_wall_s.png"]
    assert all(open(p, "rb").read(8) == b"\x89PNG\r\n\x1a\n" for p in paths)


@pytest.mark.parametrize("text, message", [
    ('runz = []', "unknown key 'runz' (the keys: runs, time_limit)"),
    ('[[runs]]\ncommand = "optimize"\ndatasets = ["bundled:intel_400.g2o"]\nseed = [1]',
     "runs[0]: unknown key 'seed'"),
    ('[[runs]]\ncommand = "optimize"\ndatasets = ["bundled:intel_400.g2o"]\noptions = { kernal = "huber" }',
     "runs[0]: options: unknown option 'kernal' (the options here: format, noise"),
    ('[[runs]]\ncommand = "optimize"\ndatasets = ["bundled:intel_400.g2o"]\noptions = { kernel = ["none", "tukey"] }',
     "runs[0]: options: kernel must be one of none, huber, cauchy, got 'tukey'"),
    ('[[runs]]\ncommand = "localize"\ndatasets = ["bundled:intel_raw_loop.log.gz"]\nmap = "bundled:intel_raw_loop_map.yaml"'
     '\n[runs.options.odometry]\nalpha9 = 0.1', "runs[0]: options: unknown option 'odometry.alpha9'"),
    ('[[runs]]\ncommand = "optimize"\ndatasets = ["bundled:intel_400.g2o"]\nseeds = [0, 1]',
     "runs[0]: seeds: optimize has no randomness"),
    ('[[runs]]\ncommand = "localize"\ndatasets = ["bundled:intel_raw_loop.log.gz"]', "runs[0]: map: a localize run "
                                                                                      "needs one"),
    ('[[runs]]\ncommand = "optimise"\ndatasets = ["a.g2o"]', "runs[0]: command must be one of optimize, localize"),
    ('[[runs]]\ncommand = "optimize"\ndatasets = ["graphs/*.g2o"]', "runs[0]: datasets: 'graphs/*.g2o' matches no file"),
    ('[[runs]]\ncommand = "optimize"\ndatasets = ["$PROBSLAM_UNSET_FOR_TEST/a.g2o"]',
     "runs[0]: datasets: '$PROBSLAM_UNSET_FOR_TEST/a.g2o': the environment variable PROBSLAM_UNSET_FOR_TEST is not set"),
])
def test_an_unknown_key_or_option_is_one_line_and_exit_2_before_any_run(tmp_path, capsys, text, message):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(text + "\n")
    status = cli.main(["batch", str(sweep), "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert err.startswith(f"probslam: error: {sweep}: {message}"), err
    assert not (tmp_path / "out").exists()  # refused before a worker started or a table was made


def test_a_path_takes_environment_variables(tmp_path, monkeypatch):
    """Data on a cluster's shared storage or a machine's data folder: $NAME and ${NAME}."""
    from probslam import data
    folder = os.path.dirname(data.path("intel_400.g2o"))
    monkeypatch.setenv("PROBSLAM_TEST_DATA", folder)
    for written in ("$PROBSLAM_TEST_DATA/intel_400.g2o", "${PROBSLAM_TEST_DATA}/*_400.g2o"):
        group = batch.RunGroup("optimize", [written], {})
        found = {r.dataset for r in batch.Sweep([group], base=str(tmp_path)).expand()}
        assert os.path.join(folder, "intel_400.g2o") in found


def test_the_same_run_has_the_same_id_and_another_run_another():
    group = batch.RunGroup("optimize", ["bundled:intel_400.g2o"], {"kernel": ["none", "huber"]})
    a, b = batch.Sweep([group]).expand(), batch.Sweep([group, group]).expand()
    assert [r.run_id for r in a] == [r.run_id for r in b] and a[0].run_id != a[1].run_id


@pytest.mark.slow
def test_the_demo_on_a_scheduler_and_two_workers_started_as_a_cluster_would_be(tmp_path):
    """`dask scheduler` and two `dask worker` processes on localhost, as on a cluster's nodes;
    `probslam batch --scheduler ADDRESS` sends the demo sweep to them."""
    info = tmp_path / "scheduler.json"
    dask = [sys.executable, "-m", "dask"]
    started = [subprocess.Popen(dask + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                        "--scheduler-file", str(info)], stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        started += [subprocess.Popen(dask + ["worker", "--scheduler-file", str(info), "--nthreads", "1",
                                             "--no-dashboard", "--memory-limit", "2GB"], stderr=subprocess.DEVNULL)
                    for _ in range(2)]
        address = json.loads(info.read_text())["address"]
        with distributed.Client(address) as c:
            c.wait_for_workers(2, timeout=60)
        out = tmp_path / "out"
        done = subprocess.run(PROBSLAM + ["batch", str(DEMO), "-o", str(out), "--scheduler", address,
                                          "--no-progress"], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        rows = table.read(str(out))
        assert len(rows) == 12 and all(row["status"] == "ok" for row in rows)
        assert len({row["worker"] for row in rows}) == 2  # both workers ran some
    finally:
        for p in started:
            p.terminate()
        for p in started:
            p.wait(timeout=30)


def test_the_package_imports_without_dask_and_batch_says_how_to_install_it(tmp_path):
    """A user who never batches needs none of the extra: probslam and probslam.batch import; the
    command says what to install, in one line, exit 2."""
    blocker = ("import sys\n"
               "class Block:\n"
               "    def find_spec(self, name, path=None, target=None):\n"
               "        if name.split('.')[0] in ('dask', 'distributed', 'pyarrow'):\n"
               "            raise ImportError(f'No module named {name!r}')\n"
               "sys.meta_path.insert(0, Block())\n"
               "import probslam, probslam.batch\n"
               "from probslam.cli import main\n"
               f"sys.exit(main(['batch', {str(DEMO)!r}, '-o', {str(tmp_path / 'out')!r}]))\n")
    done = subprocess.run([sys.executable, "-c", blocker], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("probslam: error: probslam batch needs dask, distributed and pyarrow: pip install "
                                  "'probslam[batch]'") and done.stderr.count("\n") == 1, done.stderr


def test_a_map_run_counts_the_cells_its_map_file_has(tmp_path):
    """The map kind's counts against the map_server file the map pipeline writes (the C++
    writer's trinary PGM: 0 occupied, 254 free)."""
    from probslam.pipelines import MapOptions, map_log

    [run] = batch.Sweep([batch.RunGroup("map", ["bundled:intel_excerpt.log.gz"], {"resolution": 0.1})]).expand()
    row = batch.run_one(run)
    made = map_log(run.dataset, MapOptions(resolution=0.1), progress=False)
    made.write(str(tmp_path / "m"))
    pgm = (tmp_path / "m.pgm").read_bytes()
    fields = [line for line in pgm.split(b"\n", 4)[:4] if not line.startswith(b"#")]  # P5, [# comment,] W H, 255
    width, height = map(int, fields[1].split())
    pixels = pgm[-width * height:]
    assert row["status"] == "ok" and (row["width"], row["height"]) == (width, height)
    assert row["occupied_cells"] == pixels.count(0) and row["free_cells"] == pixels.count(254)
    assert row["scans"] == 180 and row["cells_updated"] == made.mapping.cells_updated
    with pytest.raises(ValueError, match="reference: a map run makes no trajectory to score"):
        batch.Sweep([batch.RunGroup("map", ["bundled:intel_excerpt.log.gz"], reference="bundled:intel_400.g2o")]).expand()


def test_relative_globs_and_a_reference_template_score_each_dataset_against_its_own(tmp_path):
    """Datasets are read relative to the sweep file; reference = "{dir}/{stem}_gt.tum" names each
    one's ground truth: a graph scored against its own optimum has no error (but for the file's
    digits), against the other graph's it has."""
    import shutil

    from probslam import data
    from probslam.pipelines import optimize_file

    graphs = tmp_path / "graphs"
    graphs.mkdir()
    for name in ("a", "b"):
        shutil.copy(data.path("intel_400.g2o"), graphs / f"{name}.g2o")
    optimize_file(graphs / "a.g2o").write(str(tmp_path / "a"))  # a.g2o, a_trajectory.tum
    (tmp_path / "a_trajectory.tum").rename(graphs / "a_gt.tum")
    own = graphs / "a_gt.tum"
    # b's "ground truth": a's optimum moved 1 m along x after pose 200 (an error the alignment cannot remove)
    rows = [line.split() for line in own.read_text().splitlines() if not line.startswith("#")]
    (graphs / "b_gt.tum").write_text("".join(
        " ".join([r[0], str(float(r[1]) + (1.0 if float(r[0]) >= 200 else 0.0))] + r[2:]) + "\n" for r in rows))
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('[[runs]]\ncommand = "optimize"\ndatasets = ["graphs/*.g2o"]\nreference = "{dir}/{stem}_gt.tum"\n')
    runs = batch.load(sweep).expand()
    assert [os.path.basename(r.dataset) for r in runs] == ["a.g2o", "b.g2o"]
    assert [os.path.basename(r.reference) for r in runs] == ["a_gt.tum", "b_gt.tum"]
    a, b = (batch.run_one(r) for r in runs)
    assert a["status"] == b["status"] == "ok" and a["pairs"] == b["pairs"] == 400
    assert a["ate_rmse_m"] < 1e-5 and b["ate_rmse_m"] > 0.3


@pytest.mark.parametrize("path", sorted((ROOT / "benchmarks" / "sweeps").glob("*.toml")), ids=lambda p: p.name)
def test_the_benchmarks_sweeps_are_accepted(path, shared_data, monkeypatch, tmp_path):
    """Every option of a benchmark's sweep is an option of its kind with a value it takes (the
    sweep is checked as it is read), and its datasets are where the shared data has them. The
    maps and trajectories localization.toml's header makes with `probslam slam` are stood in for
    by empty files of their names (what the sweep reads of them is checked when it runs)."""
    import re

    monkeypatch.setenv("PROBSLAM_SHARED_DATA", str(shared_data))
    monkeypatch.setenv("PROBSLAM_LOCALIZATION_MAPS", str(tmp_path))
    for name in re.findall(r"\$PROBSLAM_LOCALIZATION_MAPS/([\w.{}]+)", path.read_text()):
        for stem in ("aces", "intel", "fr079"):
            (tmp_path / name.replace("{stem}", stem)).touch()
    runs = batch.load(path).expand()
    assert runs and len({r.run_id for r in runs}) == len(runs)


def test_a_landmark_run_row_holds_its_datasets_scores_and_the_refinements():
    """An MRCLAM run refined by GraphSLAM (what benchmarks/sweeps/landmark_refine.toml runs): its row
    carries what the dataset's reference scores (the association and refinement tables' measures)
    and the refinement's figures, each the same as the eval functions compute from the filter run
    and datasets.refine_run made directly (the first 40 s of the bundled excerpt)."""
    from probslam import data, eval as ev
    from probslam.datasets import mrclam, refine_run
    from probslam.landmark_refine import UNASSIGNED

    path = data.path("mrclam7_robot1_120s")
    values = {"unknown": True, "association": "jcbb", "seconds": 40.0, "refine": "graphslam"}
    row = batch.KINDS["ekf-slam"].run(path, values, {}).metrics
    d = mrclam.load(path, seconds=40.0)
    filtered = mrclam.run_ekf(d, known=False, association="jcbb")
    refined = refine_run(filtered, d, mrclam.MOTION_NOISE, mrclam.MEASUREMENT_NOISE)
    start, r = refined.input, refined.result
    labels = ev.majority_truth(r.labels, start.truth)
    fixed = d.with_survey_swapped(mrclam.survey_label_swaps(d))
    assert (row["landmarks"], row["landmarks_associated"]) == (len(r.landmarks), len(set(r.labels[r.labels >= 0])))
    assert row["association_correct"] == ev.sighting_accuracy(r.labels, start.truth)
    assert row["map_rmse_survey_aligned_m"] == ev.score_landmarks(r.landmarks, fixed, labels).rmse_aligned
    truth = ev.truth_positions(d.groundtruth, start.times)
    for name, poses in (("path_rmse_aligned_m", r.poses), ("filter_path_rmse_aligned_m", start.poses)):
        rotation, translation = ev.align_rigid(poses[:, :2], truth)
        assert row[name] == ev.rmse(poses[:, :2] @ rotation.T + translation, truth)
    score = ev.score_mrclam(refined.as_landmark_slam_result(filtered), d, labels)
    assert (row["path_rmse_m"], row["landmark_rmse_aligned_m"]) == (score.path_rmse, score.landmark_rmse_aligned)
    assert (row["unassigned"], row["sightings"]) == (int(np.sum(r.labels == UNASSIGNED)), len(d.measurements))
    assert row["landmarks_seen"] == len(set(d.measurements[:, 1].astype(int)) & set(d.landmark_positions))
    assert (row["refine_rounds"], row["refine_merges"], row["refine_moves"], row["refine_converged"]) == (
        r.iterations, len(r.merges), len(r.splits), r.converged)
    assert row["refine_cpu_s"] > 0 and row["refine_moves"] >= 1  # the refined run is not the filter's


def test_a_landmark_sweep_sets_the_filters_options_by_dotted_path(tmp_path):
    """A sweep sets a field of LandmarkRunOptions' groups by its path (FastSLAM's options, the
    refinement's), the seeds set fastslam.seed, and the run is the driver's with those options; a
    misspelt field is refused naming its path, before any run."""
    from probslam import FastSlamOptions, data, eval as ev
    from probslam.datasets import mrclam

    kind = batch.KINDS["fastslam"]
    options = batch.set_options(kind.options(), {"fastslam.num_particles": 20, "fastslam.existence_miss": 0.0,
                                                 "refine": "graphslam", "refinement.new_landmarks": True})
    assert options.fastslam == FastSlamOptions(num_particles=20, existence_miss=0.0) and options.refinement.new_landmarks
    assert kind.options().fastslam == FastSlamOptions()
    for bad, message in (({"fastslam.num_particle": 5}, "unknown option 'fastslam.num_particle'.*'num_particles'"),
                         ({"fastslam.num_particles": 0}, "^fastslam.num_particles"),
                         ({"refinement.new_landmarks": 1}, "^refinement.new_landmarks")):
        with pytest.raises((ValueError, TypeError), match=message):
            batch.set_options(kind.options(), bad)
    sweep = tmp_path / "sweep.toml"
    text = ('[[runs]]\ncommand = "fastslam"\ndatasets = ["bundled:mrclam7_robot1_120s"]\nseeds = [3]\n'
            'options = {{ unknown = true, seconds = 30.0, "fastslam.num_particles" = 20, {} }}\n')
    sweep.write_text(text.format('"fastslam.existence_miss" = 0.0'))
    run, = batch.load(sweep).expand()
    row = batch.run_one(run)
    assert row["status"] == "ok", row["error"]
    d = mrclam.load(data.path("mrclam7_robot1_120s"), seconds=30.0)
    direct = mrclam.run_fastslam(d, known=False, num_particles=20, seed=3, existence_miss=0.0)
    assert (row["landmarks"], row["association_correct"]) == (len(direct.landmarks), ev.association_accuracy(direct))
    for given, message in (('"fastslam.particles" = 5', "runs\\[0\\]: options: unknown option 'fastslam.particles'"),
                           ('"fastslam.seed" = 1', "options: fastslam.seed: give the seeds as seeds")):
        sweep.write_text(text.format(given))
        with pytest.raises(ValueError, match=message):
            batch.load(sweep).expand()


def test_the_docs_sweeps_are_accepted(tmp_path, shared_data, monkeypatch):
    """docs/batch.md's sweep examples on the bundled and the shared data read as sweeps: their
    options are the kinds' and their values taken (the examples on a user's own files are not run)."""
    import re

    monkeypatch.setenv("PROBSLAM_SHARED_DATA", str(shared_data))
    blocks = re.findall(r"```toml\n(.*?)```", (ROOT / "docs" / "batch.md").read_text(), re.S)
    checked = 0
    for k, text in enumerate(blocks):
        datasets = re.findall(r'datasets = \[(.*?)\]', text)
        if not datasets or not all(d.strip().strip('"').startswith(("bundled:", "$PROBSLAM_SHARED_DATA"))
                                   for line in datasets for d in line.split(",")):
            continue
        path = tmp_path / f"block{k}.toml"
        path.write_text(text)
        assert batch.load(path).expand(), text
        checked += 1
    assert checked >= 5


#: Scans of the bundled raw Intel lap a slam run takes in the corrected-log test (0.2 CPU s): the
#: first 90 s, where 4 scans of the bundled corrected excerpt (from 32.9 s) have their raw twin.
LAP_SCANS = 150
def test_a_slam_run_row_holds_its_score_against_a_corrected_log(tmp_path):
    """A slam run on the start of the bundled raw Intel lap against the bundled corrected excerpt:
    the row's metrics are evaluate_trajectory's with the run's log as raw_log (the corrected scans
    paired with its scans by identical ranges), its frontend_ ones those of scan matching alone."""
    import gzip
    import warnings

    from probslam import data, eval as ev
    from probslam.batch.execute import score
    from probslam.pipelines import EvaluationOptions, evaluate_trajectory

    with gzip.open(data.path("intel_raw_lap.log.gz"), "rt") as f:
        lines = f.read().splitlines()
    lap = tmp_path / "lap.log"
    lap.write_text("\n".join(lines[:[i for i, line in enumerate(lines) if line.startswith("FLASER ")][LAP_SCANS]]))
    run = batch.Run("slam", str(lap), reference=data.path("intel_excerpt.log.gz"))
    outcome = batch.KINDS["slam"].run(run.dataset, {}, {})  # what run_one scores, made once
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the raw Intel times go back, and the trajectory's with them
        row = score(outcome, run)
        for prefix, write in (("", outcome.write_trajectory), ("frontend_", outcome.also_scored["frontend"])):
            e = evaluate_trajectory(write(str(tmp_path / "run")), run.reference,
                                    EvaluationOptions(raw_log=str(lap))).result
            assert isinstance(e, ev.CorrectedLogError) and row[prefix + "pairs"] == e.matched >= ev.MIN_PAIRS
            for name, unit, statistics in (("position", "m", e.statistics),
                                           ("heading", "deg", e.heading_statistics_deg)):
                assert [row[f"{prefix}{name}_{s}_{unit}"] for s in ("mean", "median", "max")] == \
                    [statistics[s] for s in ("mean", "median", "max")]
