"""A sweep's runs on Dask distributed: each run a task (``run_one``, a pure function of the run)
on a worker process of one thread, its row written to the table as it comes back.

Without a client, a ``LocalCluster`` of process workers (one per core, one thread each, a memory
limit per worker) is started for the sweep, unless ``scheduler`` or DASK_SCHEDULER_ADDRESS names
the scheduler of a running cluster. What goes wrong is a row, not the end of the sweep: a run that
raises is recorded with its error; one past its time limit is recorded as ``timeout`` and its
worker restarted (the thread cannot be stopped otherwise); a worker process that dies (a crash,
the memory limit) has its runs retried elsewhere by the scheduler, and a run that has killed
ALLOWED_FAILURES + 1 workers is recorded as ``killed``. Each run's row is written once.
"""

from __future__ import annotations

import logging
import math
import os
import resource
import tempfile
import threading
import time
import warnings
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

from .._args import positive_real
from ..eval import CorrectedLogError
from ..pipelines import EvaluationOptions, evaluate_trajectory, reference_kind
from .kinds import KINDS, Outcome, RunKind
from .sweep import Run, Sweep, load
from . import table

#: How many times a run's worker may die before the run is recorded as ``killed`` (Dask's
#: ``distributed.scheduler.allowed-failures``, 3 by default, set for the clusters the sweep
#: starts): a worker lost by chance, or a run that only waited on a worker another run killed,
#: is retried; a run that kills every worker it is given costs three worker starts, not four.
ALLOWED_FAILURES = 2
#: Runs sent to a worker at a time per thread (Dask's ``distributed.scheduler.worker-saturation``,
#: 1.1 by default): one, so that a worker that dies takes only the run that killed it, not a run
#: queued behind it (which would count a death against it too), and a free worker takes the next.
WORKER_SATURATION = 1.0
#: Where Linux keeps a process's peak resident memory (VmHWM), and how it is reset before a run
#: (proc(5): writing 5 to clear_refs resets the peak), so that each row has its own run's peak.
PROC_STATUS = "/proc/self/status"
#: The table is written whole (Parquet and CSV), so at most once in this many seconds while rows
#: come (and at the end, or when stopped): a row a run apart would cost O(runs^2) on long sweeps.
WRITE_INTERVAL = 1.0
PROC_CLEAR_REFS = "/proc/self/clear_refs"
#: The folder of a sweep's directory that keeps the runs' trajectories (run(..., trajectories=True)),
#: and the row's column naming a run's file there.
TRAJECTORIES = "trajectories"
TRAJECTORY_COLUMN = "trajectory"
MISSING = ("probslam batch needs dask, distributed and pyarrow: pip install 'probslam[batch]' "
           "(scripts/setup.sh installs them)")


def require_dask() -> None:
    """ImportError saying how to install the batch extra when dask, distributed or pyarrow is missing."""
    try:
        import dask  # noqa: F401
        import distributed  # noqa: F401
        import pyarrow  # noqa: F401
    except ImportError as exc:
        raise ImportError(f"{MISSING}; {exc}") from None


def describe(run: Run) -> Dict[str, Any]:
    """The columns that say what ``run`` is: its id, kind, dataset, seed, reference, the kind's
    inputs and the options."""
    row = {"run_id": run.run_id, "kind": run.kind, "dataset": run.dataset, "seed": run.seed,
           "reference": run.reference}
    row.update({table.INPUT_PREFIX + name: value for name, value in run.inputs})
    row.update({table.OPTION_PREFIX + name: value for name, value in run.options})
    return row


def _reset_peak_memory() -> None:
    try:
        with open(PROC_CLEAR_REFS, "w") as f:
            f.write("5")
    except OSError:
        pass  # not Linux, or not allowed: the peak is then the process's own since it started


def _peak_memory_mb() -> float:
    try:
        with open(PROC_STATUS) as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def score(outcome: Outcome, run: Run, path: Optional[str] = None) -> Dict[str, Any]:
    """The run's trajectory (written at ``path`` already, or None: written here to a temporary
    file) against its reference (``pipelines.evaluate_trajectory``): ATE or RPE against a
    trajectory, the relations error, the RMS against positions, or the errors scan for scan
    against a corrected log; then the run's other trajectories (``Outcome.also_scored``), their
    metrics named ``NAME_METRIC``. The evaluation's ``raw_log`` is the run's (``Outcome.raw_log``)
    for a relations file or a corrected log, unless the sweep names one."""
    if outcome.write_trajectory is None:
        raise ValueError(f"reference: a {run.kind} run makes no trajectory to score")
    options = EvaluationOptions(**dict(run.evaluation))
    if (options.raw_log is None and outcome.raw_log is not None
            and reference_kind(run.reference, options.reference_format) in ("relations", "carmen")):
        options = options.replace(raw_log=outcome.raw_log)
    metrics = _score(outcome.write_trajectory, run, options, path, f"the {run.kind} run's trajectory")
    for name, write in outcome.also_scored.items():
        scored = _score(write, run, options, None, f"the {run.kind} run's {name} trajectory")
        metrics.update({f"{name}_{metric}": value for metric, value in scored.items()})
    return metrics


def _score(write, run: Run, options: EvaluationOptions, path: Optional[str], trajectory: str) -> Dict[str, Any]:
    """One trajectory's metrics against the run's reference (``trajectory``: what messages call
    it, not a temporary file)."""
    with tempfile.TemporaryDirectory(prefix="probslam-batch-") as folder:
        path = path or write(os.path.join(folder, "run"))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                evaluation = evaluate_trajectory(path, run.reference, options)
            except ValueError as exc:
                raise ValueError(str(exc).replace(path, trajectory)) from None
    for w in caught:
        warnings.warn(str(w.message).replace(path, trajectory), w.category)
    r = evaluation.result
    if evaluation.kind == "relations":
        return {"relations_mean_m": r.trans_mean, "relations_std_m": r.trans_std,
                "relations_rotation_mean_deg": r.rot_mean_deg, "relations_rotation_std_deg": r.rot_std_deg,
                "relations_used": len(r.used)}
    if evaluation.kind == "positions":
        return {"position_rmse_m": float(r.rmse), "position_rmse_aligned_m": float(r.rmse_aligned)}
    if isinstance(r, CorrectedLogError):
        position, heading = r.statistics, r.heading_statistics_deg
        return {"position_mean_m": position["mean"], "position_median_m": position["median"],
                "position_max_m": position["max"], "heading_mean_deg": heading["mean"],
                "heading_median_deg": heading["median"], "heading_max_deg": heading["max"], "pairs": r.matched}
    return {("rpe" if evaluation.options.rpe else "ate") + "_rmse_m": float(r.rmse), "pairs": int(r.count)}


def _metrics(run: Run, kind: RunKind, trajectories: Optional[str]) -> Dict[str, Any]:
    values = dict(run.options)
    if run.seed is not None:
        values[kind.seed_option] = run.seed
    inputs = dict(run.inputs)
    if kind.reads_reference:
        inputs.update(reference=run.reference, evaluation=dict(run.evaluation))
    outcome = kind.run(run.dataset, values, inputs)
    metrics = dict(outcome.metrics)
    path = None
    if trajectories is not None and outcome.write_trajectory is not None:
        path = outcome.write_trajectory(os.path.join(trajectories, run.run_id))
        metrics[TRAJECTORY_COLUMN] = os.path.basename(path)
    if run.reference is not None:
        metrics.update(score(outcome, run, path))
    return metrics


def run_one(run: Run, kind: Optional[RunKind] = None, time_limit: Optional[float] = None,
            trajectories: Optional[str] = None) -> Dict[str, Any]:
    """Makes ``run`` (with ``kind``; None: KINDS[run.kind]) and returns its row: what it is, its
    metrics, its status (ok, error, timeout), error text and warnings, wall and CPU seconds and the
    process's peak memory during it. Past ``time_limit`` seconds the row says timeout and the run's
    thread is left running (the caller restarts the process). On a worker or alone: the same row.
    ``trajectories``: a folder (existing; on a cluster, on storage the workers share) where a run
    that makes a trajectory writes it as RUN_ID_trajectory.tum, named in the row's ``trajectory``."""
    kind = KINDS[run.kind] if kind is None else kind
    row = describe(run)
    row.update(dict.fromkeys(kind.metrics))
    outcome: Dict[str, Any] = {}

    def target() -> None:
        with warnings.catch_warnings(record=True) as caught:  # a reader's notes go in the row, not on a console
            warnings.simplefilter("always")
            try:
                outcome["metrics"] = _metrics(run, kind, trajectories)
            except Exception as exc:  # noqa: BLE001 - any failure of the run is its row's error
                outcome["error"] = f"{type(exc).__name__}: {exc}"
        outcome["warnings"] = "; ".join(dict.fromkeys(str(w.message) for w in caught)) or None

    _reset_peak_memory()
    cpu, wall = time.process_time(), time.perf_counter()
    if time_limit is None:
        target()
    else:
        thread = threading.Thread(target=target, name=f"probslam-run-{run.run_id}", daemon=True)
        thread.start()
        thread.join(time_limit)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    if "metrics" in outcome:
        row.update(outcome["metrics"])
        status, error = "ok", None
    elif "error" in outcome:
        status, error = "error", outcome["error"]
    else:
        status, error = "timeout", f"still running after the time limit of {time_limit:g} s"
    row.update(status=status, error=error, warnings=outcome.get("warnings"), wall_s=wall, cpu_s=cpu,
               peak_memory_mb=_peak_memory_mb())
    return row


def _on_worker(run: Run, kind: RunKind, time_limit: Optional[float], trajectories: Optional[str]) -> Dict[str, Any]:
    from distributed import get_worker

    row = run_one(run, kind, time_limit, trajectories)
    row["worker"] = get_worker().address
    return row


def _lost(run: Run, kind: RunKind, status: str, error: str) -> Dict[str, Any]:
    """The row of a run that gave no row of its own (its workers died, or it could not be sent)."""
    row = describe(run)
    row.update(dict.fromkeys(kind.metrics))
    row.update(status=status, error=error, warnings=None, wall_s=None, cpu_s=None, peak_memory_mb=None, worker=None)
    return row


def start_client(scheduler: Optional[str] = None, workers: Optional[int] = None,
                 memory_limit: Union[str, float, None] = "auto"):
    """A client of the scheduler at ``scheduler`` (None: DASK_SCHEDULER_ADDRESS), or of a new
    ``LocalCluster``: ``workers`` processes (None: one per core) of one thread each, each with
    ``memory_limit`` (bytes or a size such as "2GB"; "auto": the memory shared out; None: no
    limit). Close it when done (``client.close()``; the local cluster closes with it)."""
    require_dask()
    import dask
    from distributed import Client

    scheduler = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")
    if scheduler:
        for name, value, default in (("workers", workers, None), ("memory_limit", memory_limit, "auto")):
            if value != default:
                raise ValueError(f"{name} applies to a local cluster; the scheduler at {scheduler} has its workers")
        return Client(scheduler)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    with dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
                          "distributed.scheduler.worker-saturation": WORKER_SATURATION}):
        # The client starts its own LocalCluster, and closes it with itself.
        return Client(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                      memory_limit=memory_limit or 0, dashboard_address=None, silence_logs=logging.CRITICAL)


def _as_sweep(sweep: Union[Sweep, Mapping[str, Any], str, "os.PathLike[str]"]) -> Sweep:
    if isinstance(sweep, Sweep):
        return sweep
    if isinstance(sweep, Mapping):
        return Sweep.from_dict(sweep)
    if isinstance(sweep, (str, os.PathLike)):
        return load(sweep)
    raise TypeError(f"sweep: expected a Sweep, a dict or a TOML file's path, got {type(sweep).__name__}")


def run(sweep, client=None, directory: Optional[str] = None, *, time_limit: Optional[float] = None,
        scheduler: Optional[str] = None, workers: Optional[int] = None,
        memory_limit: Union[str, float, None] = "auto", progress: Optional[bool] = None,
        trajectories: bool = False) -> List[Dict[str, Any]]:
    """Runs ``sweep`` (a ``Sweep``, its dict, or a TOML file's path) on ``client`` (None: one of
    ``start_client(scheduler, workers, memory_limit)``, closed at the end) and returns its rows in
    the sweep's order (dicts; ``pandas.DataFrame(rows)`` makes a frame). With ``directory`` (made
    if missing), the rows are written there as they come (``table``; at most once in WRITE_INTERVAL, and at the end
    or when stopped) and the runs whose rows are there already are
    not made again. ``time_limit`` (s; None: the sweep's own) bounds each run. ``trajectories``
    (with ``directory``): each run's trajectory kept in ``directory``/trajectories (TRAJECTORIES),
    its file named in the row. ValueError naming what the sweep refuses before any run."""
    sweep = _as_sweep(sweep)
    runs = sweep.expand()
    time_limit = sweep.time_limit if time_limit is None else positive_real(time_limit, "time_limit")
    require_dask()
    if trajectories and directory is None:
        raise ValueError("trajectories: kept in the sweep's directory; give one")
    if directory is not None:
        os.makedirs(directory, exist_ok=True)
    folder = None
    if trajectories:
        folder = os.path.abspath(os.path.join(directory, TRAJECTORIES))
        os.makedirs(folder, exist_ok=True)
    rows = table.read(directory) if directory is not None else []
    done = {row["run_id"] for row in rows}
    todo = [r for r in runs if r.run_id not in done]
    if not todo:
        return _in_order(runs, rows)
    own = client is None
    if own:
        client = start_client(scheduler, workers, memory_limit)
    try:
        _run_on(client, todo, time_limit, directory, rows, progress, folder)
    finally:
        if own:
            client.close()
    return _in_order(runs, rows)


def _in_order(runs: Sequence[Run], rows: Sequence[Dict[str, Any]]) -> List[Dict[str, Any]]:
    """The rows of ``runs`` (those there are), in the order of ``runs``."""
    by_id = {row["run_id"]: row for row in rows}
    return [by_id[r.run_id] for r in runs if r.run_id in by_id]


def _run_on(client, runs: Sequence[Run], time_limit: Optional[float], directory: Optional[str],
            rows: List[Dict[str, Any]], progress: Optional[bool], trajectories: Optional[str] = None) -> None:
    """Makes ``runs`` on ``client``, each row appended to ``rows`` and written to the table as it comes."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    from .._progress import progress_bar

    written, pending = -math.inf, False  # the first row is written at once
    futures = {client.submit(_on_worker, r, KINDS[r.kind], time_limit, trajectories, key=f"probslam-run-{r.run_id}",
                             pure=False): r for r in runs}
    try:
        with progress_bar(len(runs), "probslam batch", "run", progress) as bar:
            for future in as_completed(futures):
                r = futures[future]
                try:
                    row = future.result()
                except KilledWorker as exc:
                    row = _lost(r, KINDS[r.kind], "killed", f"its worker died {ALLOWED_FAILURES + 1} times while "
                                f"running it (a crash, or past the memory limit): {exc}")
                except FutureCancelledError as exc:
                    row = _lost(r, KINDS[r.kind], "error", f"cancelled: {exc}")
                except Exception as exc:  # noqa: BLE001 - a task that could not run (e.g. not sent)
                    row = _lost(r, KINDS[r.kind], "error", f"{type(exc).__name__}: {exc}")
                future.release()
                if row["status"] == "timeout":
                    # Its thread still runs on that worker: a new process frees the core.
                    client.restart_workers([row["worker"]], raise_for_error=False)
                rows.append(row)
                pending = directory is not None
                if pending and time.monotonic() - written >= WRITE_INTERVAL:
                    table.write(directory, rows)
                    written, pending = time.monotonic(), False
                bar.update(1)
    finally:
        if pending:  # the last rows, also when stopped (Ctrl-C)
            table.write(directory, rows)
        client.cancel([f for f in futures if not f.done()])


__all__ = ["ALLOWED_FAILURES", "TRAJECTORIES", "describe", "require_dask", "run", "run_one", "score", "start_client"]
