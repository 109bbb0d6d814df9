"""What ``probslam batch`` costs per run, and what a second worker gives: a sweep of a trivial run
kind (it does nothing) on a LocalCluster already started, with and without the table written
after each row, so that the difference of the wall times over the runs is the executor's and
the table's own cost; then (--throughput) a sweep of 20 localize runs on the bundled raw Intel
loop on one worker and on two. Cluster start-up is timed apart. Prints a table; --record writes
it into RESULTS.md (run it on a quiet machine: the second worker's gain is the point).

    .venv/bin/python benchmarks/bench_batch.py [--runs N] [--throughput] [--record]
"""

import argparse
import os
import tempfile
import time

from probslam import batch
from common import commit, heading, report


def nothing(dataset, values, inputs):
    return batch.Outcome({"value": values.get("value", 0)})


class NoOptions:
    """The trivial kind's options: a ``value`` that only tells runs apart."""

    def __init__(self, value=0):
        self.value = value

    def as_dict(self):
        return {"value": self.value}

    def replace(self, **fields):
        return NoOptions(**{**self.as_dict(), **fields})


def trivial_sweep(n: int) -> batch.Sweep:
    batch.register(batch.RunKind("nothing", NoOptions, nothing, ("value",)))
    return batch.Sweep([batch.RunGroup("nothing", [__file__], {"value": list(range(n))})])


def localize_sweep(n: int) -> batch.Sweep:
    return batch.Sweep([batch.RunGroup("localize", ["bundled:intel_raw_loop.log.gz"], {"max_particles": 2000},
                                       seeds=list(range(n)), inputs={"map": "bundled:intel_raw_loop_map.yaml"})])


def timed_sweep(sweep: batch.Sweep, workers: int, table: bool):
    """(start-up s, sweep s, rows) of ``sweep`` on a new LocalCluster of ``workers``."""
    t = time.perf_counter()
    client = batch.start_client(workers=workers)
    client.submit(os.getpid).result()  # a worker up and answering
    started = time.perf_counter() - t
    try:
        with tempfile.TemporaryDirectory() as folder:
            t = time.perf_counter()
            rows = batch.run(sweep, client, folder if table else None, progress=False)
            return started, time.perf_counter() - t, rows
    finally:
        client.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200, help="trivial runs per sweep (default 200)")
    parser.add_argument("--throughput", action="store_true", help="also 20 localize runs on 1 and 2 workers")
    parser.add_argument("--record", action="store_true", help="write the table into benchmarks/RESULTS.md")
    args = parser.parse_args()
    lines = heading("probslam batch: cost per run and a second worker's throughput",
                    f"Commit {commit()}. A LocalCluster per row (process workers, one thread each); "
                    "per run = sweep s / runs; the localize runs are 2,000-particle MCL on the bundled "
                    "raw Intel loop, seeds 0-19.",
                    ["sweep", "workers", "table", "runs", "start-up s", "sweep s", "per run ms",
                     "run's own wall ms (median)"])
    cases = [(trivial_sweep(args.runs), w, table) for w in (1, 2) for table in (False, True)]
    if args.throughput:
        cases += [(localize_sweep(20), w, True) for w in (1, 2)]
    for sweep, workers, table in cases:
        started, seconds, rows = timed_sweep(sweep, workers, table)
        own = sorted(row["wall_s"] for row in rows)[len(rows) // 2]
        lines.append(f"| {rows[0]['kind']} | {workers} | {'yes' if table else 'no'} | {len(rows)} | {started:.2f} | "
                     f"{seconds:.2f} | {1e3 * seconds / len(rows):.1f} | {1e3 * own:.2f} |")
    if args.throughput:
        one, two = (float(line.split("|")[6]) for line in lines[-2:])
        lines += ["", f"Two workers give {one / two:.2f}x the throughput of one on the localize sweep."]
    report(lines, record=args.record)


if __name__ == "__main__":
    main()
