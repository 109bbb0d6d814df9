"""Sweeps of runs over logs, commands, option grids and seeds, executed on Dask distributed
(``probslam batch``): from a ``LocalCluster`` on one machine to a cluster's scheduler.

``sweep``: the description (a TOML file or ``Sweep``) and its expansion into runs; ``kinds``: what
each command's run is, on the library's pipelines (a registry); ``execute``: the runs on Dask;
``table``: the rows on disk and their summary; ``figures``: a plot per metric. Dask, distributed and pyarrow are the
``probslam[batch]`` extra: this package imports without them, and says how to install them when a
sweep is run.
"""

from .execute import ALLOWED_FAILURES, TRAJECTORIES, require_dask, run, run_one, start_client
from .figures import FIGURES, plot
from .kinds import KINDS, Outcome, RunKind, register, set_options
from .sweep import BUNDLED, Run, RunGroup, Sweep, load
from .table import CSV, PARQUET, summary

__all__ = ["ALLOWED_FAILURES", "BUNDLED", "CSV", "FIGURES", "KINDS", "Outcome", "PARQUET", "Run", "RunGroup", "RunKind",
           "Sweep", "TRAJECTORIES", "load", "plot", "register", "require_dask", "run", "run_one", "set_options",
           "start_client", "summary"]
