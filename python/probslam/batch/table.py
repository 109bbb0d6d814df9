"""A sweep's table on disk: one row per run (its configuration, metrics, cost and status) in
``results.parquet`` with ``results.csv`` beside it, rewritten whole as rows come (each through a
temporary file and a rename, so that a stop at any moment leaves both complete up to the last
row written), read back to skip the runs done; and its summary: the medians of each group of runs that
differ only in their seed.
"""

from __future__ import annotations

import csv
import json
import math
import os
import statistics
from typing import Any, Dict, Iterable, List, Sequence, Tuple

PARQUET = "results.parquet"
CSV = "results.csv"
#: The option columns are named ``options.NAME`` (NAME a dotted path for a sub-structure's field).
OPTION_PREFIX = "options."
#: The kind's own inputs (localize's map) are named ``inputs.NAME``.
INPUT_PREFIX = "inputs."
#: Columns that describe a run's cost, not its result: their medians close each summary row.
COST_COLUMNS = ("wall_s", "cpu_s", "peak_memory_mb")
#: The columns that say what a run is and how it went, not what it measured.
IDENTITY_COLUMNS = ("run_id", "kind", "dataset", "seed", "reference", "status", "error", "warnings", "worker",
                    "trajectory")


def columns(rows: Sequence[Dict[str, Any]]) -> List[str]:
    """Every column of ``rows``: what the run is, its options, its metrics, how it went and its
    cost, each part in the order of first appearance."""
    seen: Dict[str, None] = {}
    for row in rows:
        seen.update(dict.fromkeys(row))

    def part(name: str) -> int:
        if name in IDENTITY_COLUMNS[:5]:
            return 0
        if name.startswith((INPUT_PREFIX, OPTION_PREFIX)):
            return 1
        return 3 if name in IDENTITY_COLUMNS or name in COST_COLUMNS else 2

    return sorted(seen, key=part)


def _arrow_column(values: List[Any]):
    """A pyarrow array of ``values``; a column whose rows mix types (an option that is a name in
    one group and a number in another) is kept as JSON text."""
    import pyarrow as pa

    try:
        return pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return pa.array([None if v is None else json.dumps(v) for v in values], pa.string())


def _replace(path: str, write) -> None:
    tmp = f"{path}.tmp{os.getpid()}"
    write(tmp)
    os.replace(tmp, path)


def write(directory: str, rows: Sequence[Dict[str, Any]]) -> None:
    """Writes ``rows`` to DIRECTORY/results.parquet and results.csv (each replaced whole)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    names = columns(rows)
    table = pa.table({name: _arrow_column([row.get(name) for row in rows]) for name in names})
    _replace(os.path.join(directory, PARQUET), lambda tmp: pq.write_table(table, tmp))

    def write_csv(tmp: str) -> None:
        with open(tmp, "w", newline="") as f:
            out = csv.DictWriter(f, names)
            out.writeheader()
            out.writerows(rows)

    _replace(os.path.join(directory, CSV), write_csv)


def read(directory: str) -> List[Dict[str, Any]]:
    """The rows of DIRECTORY/results.parquet ([] when there is none yet)."""
    import pyarrow.parquet as pq

    path = os.path.join(directory, PARQUET)
    if not os.path.exists(path):
        return []
    return pq.read_table(path).to_pylist()


def is_metric(value: Any) -> bool:
    """A finite number (not a bool): what a median and a plot take."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def kind_columns(rows: Sequence[Dict[str, Any]]) -> Tuple[List[str], List[str]]:
    """The option and input columns of one kind's ``rows``, and its metric columns (the kind's
    own that some run has, e.g. a landmark run's MRCLAM scores only on MRCLAM, then the cost columns)."""
    names = columns(rows)
    options = [n for n in names if n.startswith((INPUT_PREFIX, OPTION_PREFIX))]
    metrics = [n for n in names if n not in IDENTITY_COLUMNS and n not in options and n not in COST_COLUMNS
               and any(_given(r.get(n)) for r in rows)]
    return options, metrics + list(COST_COLUMNS)


def groups(rows: Sequence[Dict[str, Any]], options: Sequence[str]) -> Dict[Tuple[str, str], List[Dict[str, Any]]]:
    """One kind's ``rows`` grouped by dataset and options: the runs that differ only in their
    seed, keyed by (the dataset's name, "name=value, ..." or "(defaults)")."""
    out: Dict[Tuple[str, str], List[Dict[str, Any]]] = {}
    for row in rows:
        key = (os.path.basename(str(row["dataset"]).rstrip(os.sep)),
               ", ".join(f"{_name(n)}={_value(row[n])}" for n in options if row.get(n) is not None) or "(defaults)")
        out.setdefault(key, []).append(row)
    return out


def by_kind(rows: Sequence[Dict[str, Any]]) -> Dict[str, List[Dict[str, Any]]]:
    """``rows`` split by their kind, in the order the kinds first appear."""
    out: Dict[str, List[Dict[str, Any]]] = {}
    for row in rows:
        out.setdefault(row["kind"], []).append(row)
    return out


def measured(rows: Iterable[Dict[str, Any]], metric: str) -> List[float]:
    """The values of ``metric`` in the runs of ``rows`` that ended well and measured it (a finite number)."""
    return [float(r[metric]) for r in rows if r["status"] == "ok" and is_metric(r.get(metric))]


def summary(rows: Sequence[Dict[str, Any]]) -> str:
    """The medians over seeds of each kind's metrics, one line per dataset and options (as
    benchmarks/RESULTS.md shows them), with how many runs were ok and the cost of a run."""
    out = []
    for kind, mine in by_kind(rows).items():
        options, metrics = kind_columns(mine)
        header = ["dataset", "options", "ok"] + metrics
        lines = [header]
        for (dataset, opts), group in groups(mine, options).items():
            ok = [r for r in group if r["status"] == "ok"]
            lines.append([dataset, opts, f"{len(ok)}/{len(group)}"] + [_median(r.get(m) for r in ok) for m in metrics])
        widths = [max(len(line[k]) for line in lines) for k in range(len(header))]
        out.append(f"{kind} (medians over each line's seeds; ok: the runs that ended well):")
        out += ["  " + "  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines]
    return "\n".join(out)


def _given(value: Any) -> bool:
    """A value a run gave: not None, nor the NaN a table read back holds where a row had None."""
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def _name(column: str) -> str:
    return column.split(".", 1)[1]


def _value(value: Any) -> str:
    """An option or input as the summary shows it (a file by its name)."""
    return os.path.basename(value) if isinstance(value, str) and os.sep in value else str(value)


def _median(values: Iterable[Any]) -> str:
    values = list(values)
    if values and all(isinstance(v, bool) for v in values):
        return f"{sum(values)}/{len(values)}"
    numbers = [float(v) for v in values if is_metric(v)]
    return f"{statistics.median(numbers):.6g}" if numbers else "-"


__all__ = ["CSV", "PARQUET", "by_kind", "columns", "groups", "is_metric", "kind_columns", "measured", "read", "summary", "write"]
