"""A sweep: which runs to make, as a TOML file or the same as a Python object, and its expansion
into runs, each identified by a hash of its inputs.

A sweep holds groups of runs (``[[runs]]`` tables in the file; ``RunGroup`` in Python). Each group
names a command (a run kind: ``kinds.KINDS``), its datasets (paths and globs; ``bundled:NAME``
for the package's demo data, ``probslam.data``), the kind's own inputs (localize's ``map``), an
option grid (each option a value or a list of values; every combination is a run), seeds, and a
reference to score against with its evaluation options. Every key and every option is checked
when the sweep is read and expanded, so that a misspelling is refused, naming it, before
anything runs.
"""

from __future__ import annotations

import dataclasses
import glob
import hashlib
import itertools
import json
import os
import re
import string
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

from .. import data as bundled_data
from ..pipelines import EvaluationOptions
from .kinds import KINDS, RunKind, set_options

PathLike = Union[str, "os.PathLike[str]"]

#: A dataset, map or reference written ``bundled:NAME`` is ``probslam.data.path(NAME)`` (NAME may
#: be a glob over the bundled files): a sweep over the demo data reads the same on any install.
BUNDLED = "bundled:"
#: The keys a sweep file may have at its top level, and in each ``[[runs]]`` table besides the
#: kind's own inputs.
SWEEP_KEYS = ("runs", "time_limit")
GROUP_KEYS = ("command", "datasets", "options", "seeds", "reference", "evaluation")
#: The fields of a reference path template (``reference = "{dir}/{stem}.tum"``): the dataset's
#: path, folder, file name, and file name without its suffixes.
REFERENCE_FIELDS = ("dataset", "dir", "name", "stem")
#: How many hex digits of a run's SHA-256 name it: 64 bits, no collision in any sweep a table holds.
RUN_ID_DIGITS = 16


@dataclass
class RunGroup:
    """Runs of one command: every dataset with every combination of the option grid and every
    seed. ``options``: option name (a dotted path into a sub-structure, ``odometry.alpha1``) ->
    a value, or a list of values to sweep; ``inputs``: the kind's own inputs (localize: ``map``,
    ``initial_pose``); ``reference``: a path or a template of REFERENCE_FIELDS (None: not
    scored); ``evaluation``: ``EvaluationOptions`` fields for the score."""

    command: str
    datasets: Sequence[str]
    options: Mapping[str, Any] = field(default_factory=dict)
    seeds: Sequence[int] = ()
    reference: Optional[str] = None
    evaluation: Mapping[str, Any] = field(default_factory=dict)
    inputs: Mapping[str, Any] = field(default_factory=dict)


@dataclass
class Sweep:
    """Groups of runs; ``base``: the folder relative paths are read from (a sweep file's own);
    ``time_limit``: seconds a run may take (None: no limit); ``source``: what messages call it."""

    runs: Sequence[RunGroup]
    base: str = "."
    time_limit: Optional[float] = None
    source: str = "sweep"  # how messages name it: its file

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any], base: PathLike = ".", where: str = "sweep") -> "Sweep":
        """A sweep from its description as a dict (a TOML file as read). ValueError naming the
        first unknown key (and where it is) or value of the wrong kind."""
        _require(isinstance(spec, Mapping), f"{where}: expected a table of {', '.join(SWEEP_KEYS)}")
        _known_keys(spec, SWEEP_KEYS, where)
        groups = spec.get("runs")
        _require(isinstance(groups, list) and groups, f"{where}: no [[runs]] table: nothing to run")
        runs = [_group(g, f"{where}: runs[{k}]") for k, g in enumerate(groups)]
        time_limit = spec.get("time_limit")
        if time_limit is not None:
            _require(_is_number(time_limit) and time_limit > 0, f"{where}: time_limit must be a number of seconds > 0, "
                                                                f"got {time_limit!r}")
        return cls(runs, os.fspath(base), time_limit, where)

    def expand(self) -> List["Run"]:
        """Every run of the sweep in order (each distinct run once). ValueError naming the group
        and the dataset, input, option or seed that is refused, before anything runs."""
        runs: Dict[str, Run] = {}
        for k, group in enumerate(self.runs):
            for run in _expand_group(group, self.base, f"{self.source}: runs[{k}]"):
                runs.setdefault(run.run_id, run)
        return list(runs.values())


@dataclass(frozen=True)
class Run:
    """One run: a kind on a dataset with options set (name -> value, as the sweep gives them),
    a seed, its inputs and reference (absolute paths), and the evaluation's options."""

    kind: str
    dataset: str
    options: Tuple[Tuple[str, Any], ...] = ()
    seed: Optional[int] = None
    inputs: Tuple[Tuple[str, Any], ...] = ()
    reference: Optional[str] = None
    evaluation: Tuple[Tuple[str, Any], ...] = ()

    @property
    def run_id(self) -> str:
        """A hash of the run's inputs: the same run in another sweep, or the same sweep started
        again, has the same id."""
        text = json.dumps(dataclasses.asdict(self), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:RUN_ID_DIGITS]


def load(path: PathLike) -> Sweep:
    """The sweep in the TOML file at ``path`` (relative paths in it from its folder). ValueError
    naming the file and what it refuses."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11: the same parser, as a package (probslam[batch])
        import tomli as tomllib
    path = os.fspath(path)
    with open(path, "rb") as f:
        try:
            spec = tomllib.load(f)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not a TOML file: {exc}") from None
    return Sweep.from_dict(spec, os.path.dirname(os.path.abspath(path)), path)


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise ValueError(message)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _known_keys(table: Mapping[str, Any], keys: Sequence[str], where: str) -> None:
    unknown = [k for k in table if k not in keys]
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r} (the keys: {', '.join(keys)})")


def _kind(command: Any, where: str) -> RunKind:
    _require(command in KINDS, f"{where}: command must be one of {', '.join(KINDS)}, got {command!r}")
    return KINDS[command]


def _group(spec: Any, where: str) -> RunGroup:
    """A ``[[runs]]`` table as a group (its values are checked by ``_checked``)."""
    _require(isinstance(spec, Mapping), f"{where}: expected a table")
    kind = _kind(spec.get("command"), where)
    _known_keys(spec, GROUP_KEYS + tuple(kind.inputs), where)
    return RunGroup(kind.name, spec.get("datasets"), spec.get("options", {}), spec.get("seeds", []),
                    spec.get("reference"), spec.get("evaluation", {}), {k: spec[k] for k in kind.inputs if k in spec})


def _checked(group: RunGroup, where: str) -> RunGroup:
    """``group`` with its values checked (ValueError naming the first that is wrong), a lone
    dataset as a list."""
    kind = _kind(group.command, where)
    _known_keys(group.inputs, tuple(kind.inputs), where)
    datasets = [group.datasets] if isinstance(group.datasets, str) else group.datasets
    _require(isinstance(datasets, (list, tuple)) and len(datasets) > 0 and all(isinstance(d, str) for d in datasets),
             f"{where}: datasets must be a path or a list of paths and globs")
    for key in ("options", "evaluation"):
        _require(isinstance(getattr(group, key), Mapping), f"{where}: {key} must be a table")
    seeds = group.seeds
    _require(isinstance(seeds, (list, tuple)) and all(isinstance(s, int) and not isinstance(s, bool) for s in seeds),
             f"{where}: seeds must be a list of integers")
    _require(group.reference is None or isinstance(group.reference, str), f"{where}: reference must be a path")
    return dataclasses.replace(group, datasets=list(datasets))


def _flatten(options: Mapping[str, Any], prefix: str = "") -> Dict[str, Any]:
    """Nested tables as dotted paths: {"odometry": {"alpha1": 0.1}} -> {"odometry.alpha1": 0.1}."""
    out: Dict[str, Any] = {}
    for name, value in options.items():
        if isinstance(value, Mapping):
            out.update(_flatten(value, f"{prefix}{name}."))
        else:
            out[prefix + name] = value
    return out


def _paths(pattern: str, base: str, where: str) -> List[str]:
    """The files a dataset entry names: a path or a glob (relative to ``base``, or ``bundled:``)."""
    if pattern.startswith(BUNDLED):
        folder, pattern = os.path.dirname(os.path.abspath(bundled_data.__file__)), pattern[len(BUNDLED):]
        if not glob.has_magic(pattern):
            try:
                return [bundled_data.path(pattern)]
            except ValueError as exc:  # names the bundled files there are
                raise ValueError(f"{where}: {str(exc).removeprefix('name: ')}") from None
    else:
        folder = base
    full = os.path.join(folder, os.path.expanduser(_expand_variables(pattern, where)))
    if glob.has_magic(pattern):
        found = sorted(glob.glob(full, recursive=True))
        _require(bool(found), f"{where}: {pattern!r} matches no file")
        return [os.path.abspath(p) for p in found]
    _require(os.path.exists(full), f"{where}: {pattern!r}: no such file or folder ({os.path.abspath(full)})")
    return [os.path.abspath(full)]


def _expand_variables(pattern: str, where: str) -> str:
    """``$NAME`` / ``${NAME}`` from the environment (data on a cluster's shared storage, a
    machine's data folder); an unset one is refused naming it, rather than read as a file name."""
    for match in re.finditer(r"\$(\w+)|\$\{(\w+)\}", pattern):
        name = match.group(1) or match.group(2)
        _require(name in os.environ, f"{where}: {pattern!r}: the environment variable {name} is not set")
    return os.path.expandvars(pattern)


def _one_path(value: Any, base: str, where: str) -> str:
    _require(isinstance(value, str), f"{where}: expected a path, got {value!r}")
    found = _paths(value, base, where)
    _require(len(found) == 1, f"{where}: {value!r} names {len(found)} files; give one")
    return found[0]


def _reference(template: str, dataset: str, base: str, where: str) -> str:
    names = [f for _, f, _, _ in string.Formatter().parse(template) if f is not None]
    bad = [f for f in names if f not in REFERENCE_FIELDS]
    if bad:
        raise ValueError(f"{where}: reference: unknown field {{{bad[0]}}} (the fields: "
                         f"{', '.join('{' + f + '}' for f in REFERENCE_FIELDS)})")
    name = os.path.basename(dataset.rstrip(os.sep))
    path = template.format(dataset=dataset, dir=os.path.dirname(dataset), name=name, stem=name.split(".")[0])
    return _one_path(path, base, f"{where}: reference")


def _expand_group(group: RunGroup, base: str, where: str) -> List[Run]:
    group = _checked(group, where)
    kind = KINDS[group.command]
    options = _flatten(group.options)
    seed = next((name for name in ("seed", kind.seed_option) if name in options), None)
    if seed is not None:
        raise ValueError(f"{where}: options: {seed}: give the seeds as seeds = [...], not as an option")
    if group.reference is not None and not kind.scored:
        raise ValueError(f"{where}: reference: a {kind.name} run makes no trajectory to score")
    if group.seeds and not kind.seeded:
        raise ValueError(f"{where}: seeds: {kind.name} has no randomness (one run per dataset and options)")
    grid = [[(name, v) for v in (value if isinstance(value, list) else [value])] for name, value in options.items()]
    combinations = [tuple(c) for c in itertools.product(*grid)]
    for combination in combinations:  # each refused by name here, before any run
        _check_options(kind, dict(combination), where)
    evaluation = dict(group.evaluation)
    if evaluation:
        _require(group.reference is not None, f"{where}: evaluation: applies with a reference")
        try:
            set_options(EvaluationOptions(), evaluation)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{where}: evaluation: {exc}") from None
    missing = [k for k, required in kind.inputs.items() if required and k not in group.inputs]
    if missing:
        raise ValueError(f"{where}: {missing[0]}: a {kind.name} run needs one")
    inputs = tuple(sorted((k, _one_path(v, base, f"{where}: {k}") if kind.inputs_are_paths.get(k) else
                           tuple(v) if isinstance(v, list) else v) for k, v in group.inputs.items()))
    runs = []
    for pattern in group.datasets:
        for dataset in _paths(pattern, base, f"{where}: datasets"):
            reference = None if group.reference is None else _reference(group.reference, dataset, base, where)
            for combination in combinations:
                for seed in (group.seeds or [None]):
                    runs.append(Run(kind.name, dataset, combination, seed, inputs, reference,
                                    tuple(sorted(evaluation.items()))))
    return runs


def _check_options(kind: RunKind, values: Dict[str, Any], where: str) -> None:
    try:
        set_options(kind.options(), values)
    except (ValueError, TypeError, AttributeError) as exc:
        raise ValueError(f"{where}: options: {exc}") from None


__all__ = ["BUNDLED", "Run", "RunGroup", "Sweep", "load"]
