"""A sweep's figures: one per kind and metric, each group of runs that differ only in their seed
on its own line (the summary's lines), every run a dot and the group's median a bar, so that the
spread over seeds is seen beside the median the summary prints. matplotlib is the ``plot`` extra:
without it the sweep's table is complete and the figures are left out with a note.
"""

from __future__ import annotations

import os
import re
import statistics
from typing import Any, Dict, List, Sequence

from . import table

#: The folder of a sweep's output directory that holds its figures.
FIGURES = "figures"

#: Inches per group line of a figure (the label's text height and the dots' spread), and the
#: least height, so that one-group figures keep room for their axis.
INCHES_PER_GROUP = 0.35
MIN_HEIGHT_INCHES = 2.0


def _file_name(kind: str, metric: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{kind}_{metric}") + ".png"


def _draw(plt, kind: str, metric: str, groups: Dict[tuple, List[Dict[str, Any]]], path: str) -> None:
    labels, values = [], []
    for (dataset, options), group in groups.items():
        labels.append(f"{dataset}  {options}")
        values.append(table.measured(group, metric))
    fig, ax = plt.subplots(figsize=(8.0, max(MIN_HEIGHT_INCHES, 1.0 + INCHES_PER_GROUP * len(labels))))
    try:
        for line, vals in enumerate(values):
            ax.plot(vals, [line] * len(vals), "o", color="tab:blue", alpha=0.6, markersize=5)
            if vals:
                median = statistics.median(vals)
                ax.plot([median, median], [line - 0.3, line + 0.3], "-", color="tab:red", linewidth=2)
        ax.set_yticks(range(len(labels)))
        ax.set_yticklabels(labels, fontsize=8)
        ax.invert_yaxis()
        ax.set_xlabel(metric)
        ax.set_title(f"{kind}: {metric} (dots: runs; bar: median over seeds)", fontsize=10)
        ax.grid(axis="x", alpha=0.3)
        fig.tight_layout()
        fig.savefig(path, dpi=100)
    finally:
        plt.close(fig)


def plot(rows: Sequence[Dict[str, Any]], directory: str) -> List[str]:
    """Writes one PNG per kind and metric of ``rows`` (the metrics that have a number in some
    ok run) into ``directory``/figures and returns their paths; ImportError with the install hint
    when matplotlib is missing."""
    from ..plot import require_matplotlib

    plt = require_matplotlib()
    folder = os.path.join(directory, FIGURES)
    os.makedirs(folder, exist_ok=True)
    paths = []
    for kind, mine in table.by_kind(rows).items():
        options, metrics = table.kind_columns(mine)
        grouped = table.groups(mine, options)
        for metric in metrics:
            if not table.measured(mine, metric):
                continue  # a metric no run measured (e.g. a score without a reference)
            path = os.path.join(folder, _file_name(kind, metric))
            _draw(plt, kind, metric, grouped, path)
            paths.append(path)
    return paths


__all__ = ["FIGURES", "plot"]
