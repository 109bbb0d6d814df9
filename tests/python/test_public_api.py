"""probslam's public names, as a user meets them: every one exported, documented, with a real
signature, and (for the C++ core) the same signature in the hand-written stub _core.pyi.

The names walked: ``probslam.__all__`` and the ``__all__`` of the subpackages below. Each is
checked for
  - exported: the module has ``__all__``, every name in it exists, and every public function or
    class the module defines itself is in it; every public name of ``probslam._core`` is exported
    from ``probslam`` or a subpackage (or listed in CORE_INTERNAL with the reason);
  - documented: a docstring beyond the signature, for functions, classes and each public method
    and property a class defines;
  - a real signature: no ``*args``, and no ``**kwargs`` but a documented forwarder (a ``**options``
    whose docstring says where the options go: run_slam's go to SubmapSlam2D / GridFastSlam,
    whose own signatures are checked here). ``inspect.signature`` fails on pybind11 3.x builtins,
    so a C++ function's signature is read from the first line(s) of its docstring, which pybind11
    writes as ``name(arg: type = default, ...) -> ret`` (one numbered line per overload);
  - for objects of ``probslam._core``: the stub declares each function, constructor and method
    with the same parameter names, order, kinds (keyword-only after ``*``) and defaults.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import math
import pathlib
import pkgutil
import re
import types

import pytest

import probslam
from probslam import _core

STUB = pathlib.Path(__file__).resolve().parents[2] / "python" / "probslam" / "_core.pyi"

#: Subpackages whose ``__all__`` is public API (``datasets`` once it exists).
SUBPACKAGES = ("io", "eval", "slam", "sim", "sim_laser", "inverse_learning", "data", "datasets", "geometry", "certificate", "pipelines", "graph")

#: Public names of probslam._core that are deliberately not exported, with the reason.
CORE_INTERNAL = {
    "MAX_COORDINATE": "a limit the CLI checks its options against; users meet it in error messages",
    "MAX_BAD_ROW_FRACTION": "read_pose_graph's rows='skip' limit, exported as probslam.graph.MAX_BAD_ROW_FRACTION",
    "POSE_GRAPH_MAX_REPORTED_LINES": "how many skipped lines PoseGraphReadReport lists",
    "INFORMATION_EIGENVALUE_FLOOR": "the pose-graph readers' information-repair floor, exported as "
                                    "probslam.graph.INFORMATION_EIGENVALUE_FLOOR",
    "CARMEN_MAX_REPORTED_LINES": "how many skipped lines a CARMEN read lists (probslam.io.carmen.MAX_REPORTED_LINES)",
    "parse_carmen_log": "the parser under probslam.io.read_carmen_log, which reads compressed logs too",
}

#: A parameter ``**options`` is allowed in a function whose docstring mentions "options" (it
#: forwards them to a class whose own signature this test checks); ``**kwargs`` never.
FORWARDED_KEYWORDS = "options"


# --- the names ----------------------------------------------------------------------------------

def modules():
    out = [probslam]
    for name in SUBPACKAGES:  # probslam.certificate is imported on demand (scipy.sparse)
        out.append(importlib.import_module(f"probslam.{name}"))
    return out


def test_no_module_is_hidden_by_a_name_of_its_package():
    """A package's attribute of a submodule's name is that module: ``from .slam_log import
    slam_log`` made ``probslam.pipelines.slam_log`` the function, its module out of reach."""
    hidden, packages = [], [probslam]
    while packages:
        package = packages.pop()
        for info in pkgutil.iter_modules(package.__path__):
            if info.name == "__main__":  # importing it runs the command line
                continue
            module = importlib.import_module(f"{package.__name__}.{info.name}")
            packages += [module] if info.ispkg else []
            attribute = getattr(package, info.name)
            if attribute is not module:
                hidden.append(f"{module.__name__} (the package's {info.name} is a {type(attribute).__name__})")
    assert not hidden, hidden


def public_objects():
    """(qualified name, object) of every public name of every module, modules themselves aside,
    and of every public name of probslam._core (a Python wrapper of the same name does not
    exempt the binding from the stub) and the private classes the stub declares (the Python
    classes' engines, _EkfSlam)."""
    seen = {}
    for module in modules():
        for name in getattr(module, "__all__", []):
            obj = getattr(module, name, None)
            if obj is None or isinstance(obj, types.ModuleType):
                continue
            seen.setdefault(id(obj), (f"{module.__name__}.{name}", obj))
    stub = stub_signatures()
    for name in dir(_core):
        obj = getattr(_core, name)
        if (not name.startswith("_") or (isinstance(obj, type) and name in stub)) and not name.startswith("__"):
            seen.setdefault(id(obj), (f"probslam._core.{name}", obj))
    return sorted(seen.values(), key=lambda item: item[0])


def is_core(obj) -> bool:
    return getattr(obj, "__module__", None) == "probslam._core"


def is_static_property(raw) -> bool:
    """pybind11's static property (OccupancyGrid2D.max_cells): it drops the docstring."""
    return type(raw).__name__ == "pybind11_static_property"


def class_members(cls):
    """(name, raw attribute) of the public methods and properties a class defines itself, and its
    constructor when it defines one (a pybind11 class without py::init has none of its own)."""
    out = []
    for name, raw in vars(cls).items():
        if name.startswith("_") and name != "__init__":
            continue
        if hasattr(cls, "__members__") and name in ("name", "value"):
            continue  # pybind11's own enum properties; the class docstring lists the values
        if name == "__init__" and is_core(cls) and not (raw.__doc__ or "").startswith("__init__("):
            continue
        if isinstance(raw, (staticmethod, classmethod)):
            raw = raw.__func__
        if isinstance(raw, property) or is_static_property(raw) or callable(raw):
            out.append((name, raw))
    return out


# --- signatures from pybind11 docstrings --------------------------------------------------------

def _outside_quotes(text: str):
    """(index, character, bracket depth) of each character of text outside quotes; a bracket
    stands at the depth it opens from or closes to."""
    depth, quote = 0, None
    for i, c in enumerate(text):
        if quote:
            quote = None if c == quote else quote
            continue
        if c in "'\"":
            quote = c
            continue
        depth -= c in ")]}"
        yield i, c, depth
        depth += c in "([{"


def _split_top(text: str):
    """text split at the commas outside brackets and quotes."""
    cuts = [i for i, c, depth in _outside_quotes(text) if c == "," and depth == 0]
    return [p.strip() for p in (text[a + 1:b] for a, b in zip([-1] + cuts, cuts + [len(text)])) if p.strip()]


def _params_text(line: str, name: str):
    """The text between the parentheses of `name(...) -> ...`, or None."""
    if not line.startswith(name + "("):
        return None
    ends = [i for i, c, depth in _outside_quotes(line) if c == ")" and depth == 0 and i > len(name)]
    return line[len(name) + 1:ends[0]] if ends else None


def _parse_param(text: str, keyword_only: bool):
    """(name, kind, default text or None) of one pybind11 parameter `name: type = default`."""
    if text.startswith("**"):
        return (text[2:].split(":")[0].strip(), "var_keyword", None)
    if text.startswith("*"):
        return (text[1:].split(":")[0].strip(), "var_positional", None)
    head, _, rest = text.partition(":")
    equals = [i for i, _, depth in _outside_quotes(rest) if depth == 0 and rest.startswith(" = ", i)]
    default = rest[equals[0] + 3:].strip() if equals else None
    return (head.strip(), "keyword_only" if keyword_only else "positional", default)


def binding_signatures(obj, name: str):
    """Every overload of a pybind11 function as a list of (name, kind, default text), `self`
    dropped; [] when the docstring shows no signature."""
    doc = obj.__doc__ or ""
    lines = [line.strip() for line in doc.splitlines()]
    overloads = [re.sub(r"^\d+\. ", "", line) for line in lines if re.match(r"^\d+\. " + re.escape(name) + r"\(", line)]
    candidates = overloads or [line for line in lines[:1]]
    out = []
    for line in candidates:
        inner = _params_text(line, name)
        if inner is None:
            continue
        params, keyword_only = [], False
        for part in _split_top(inner):
            if part == "*":
                keyword_only = True
                continue
            if part == "/":
                continue
            params.append(_parse_param(part, keyword_only))
        out.append([p for p in params if p[0] != "self"])
    return out


# --- signatures from the stub -------------------------------------------------------------------

def _stub_function_params(node: ast.FunctionDef, is_method: bool):
    a = node.args
    static = any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in node.decorator_list)
    positional = a.posonlyargs + a.args
    defaults = [None] * (len(positional) - len(a.defaults)) + list(a.defaults)
    params = [(arg.arg, "positional", None if d is None else ast.unparse(d)) for arg, d in zip(positional, defaults)]
    if is_method and not static and params:
        params = params[1:]  # self
    if a.vararg:
        params.append((a.vararg.arg, "var_positional", None))
    params += [(arg.arg, "keyword_only", None if d is None else ast.unparse(d))
               for arg, d in zip(a.kwonlyargs, a.kw_defaults)]
    if a.kwarg:
        params.append((a.kwarg.arg, "var_keyword", None))
    return params


def stub_signatures(text: str | None = None):
    """{"name" or "Class.method": [params of each overload]} of the stub."""
    tree = ast.parse(STUB.read_text() if text is None else text)
    out = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            out.setdefault(node.name, []).append(_stub_function_params(node, False))
        elif isinstance(node, ast.ClassDef):
            out.setdefault(node.name, [])
            for member in node.body:
                if isinstance(member, ast.FunctionDef):
                    out.setdefault(f"{node.name}.{member.name}", []).append(_stub_function_params(member, True))
    return out


# --- defaults compared by value -----------------------------------------------------------------

_NAMESPACE = {"math": math, "inf": math.inf, "nan": math.nan, **{n: getattr(_core, n) for n in dir(_core)}}


def _default_value(text):
    """A default as a value: pybind11 writes repr (enum values as <Association.X: 0>), the stub
    an expression (math.inf, Association.X); text it cannot evaluate compares as text."""
    if text is None:
        return None
    text = re.sub(r"<(\w+)\.(\w+): -?\d+>", r"\1.\2", text)
    try:
        return ("value", eval(text, dict(_NAMESPACE)))  # noqa: S307 (our own stub and docstrings)
    except Exception:  # noqa: BLE001
        return ("text", text)


def _same_default(a, b) -> bool:
    x, y = _default_value(a), _default_value(b)
    if x is None or y is None:
        return x is y
    if x[0] != y[0]:
        return False
    u, v = x[1], y[1]
    if isinstance(u, bool) != isinstance(v, bool):
        return False  # True == 1, but a flag's default is not a count's
    if isinstance(u, float) and isinstance(v, float) and math.isnan(u) and math.isnan(v):
        return True
    try:
        return bool(u == v)
    except Exception:  # noqa: BLE001
        return False


def _same_params(p, q) -> bool:
    return len(p) == len(q) and all(a[0] == b[0] and a[1] == b[1] and _same_default(a[2], b[2]) for a, b in zip(p, q))


def _show(params) -> str:
    kinds = {"positional": "", "keyword_only": "*", "var_positional": "*", "var_keyword": "**"}
    return "(" + ", ".join(kinds[k] + n + ("" if d is None else "=" + d) for n, k, d in params) + ")"


# --- documentation ------------------------------------------------------------------------------

def doc_text(obj, name: str) -> str:
    """obj's docstring without the signature lines pybind11 writes into it."""
    doc = inspect.getdoc(obj) or ""
    keep = [line for line in doc.splitlines()
            if not (line.strip() == "Overloaded function." or line.strip().startswith(name + "(")
                    or re.match(r"\d+\. " + re.escape(name) + r"\(", line.strip()))]
    return "\n".join(keep).strip()


def documented(obj, name: str) -> bool:
    if isinstance(obj, type):
        doc = obj.__doc__ or ""
        return bool(doc.strip()) and not doc.startswith(name + "(")  # not a dataclass's own signature
    return bool(doc_text(obj, name))


# --- the checks ---------------------------------------------------------------------------------

def export_problems():
    problems = []
    for module in modules():
        names = getattr(module, "__all__", None)
        if names is None:
            problems.append(f"{module.__name__} has no __all__")
            continue
        problems += [f"{module.__name__}.__all__ names {n!r}, which does not exist" for n in names
                     if not hasattr(module, n)]
        for n, obj in vars(module).items():
            defined_here = getattr(obj, "__module__", None) == module.__name__
            if not n.startswith("_") and defined_here and (inspect.isfunction(obj) or inspect.isclass(obj)) \
                    and n not in names:
                problems.append(f"{module.__name__}.{n} is public but not in __all__")
    # By name: a Python function of the same name (read_pose_graph) is the export.
    exported = {n for module in modules() for n in getattr(module, "__all__", [])}
    problems += [f"_core.{n} is exported neither from probslam nor from a subpackage" for n in dir(_core)
                 if not n.startswith("_") and n not in CORE_INTERNAL and n not in exported]
    return problems


def _signature_problem(qualname, obj, name, params_list):
    for params in params_list:
        for pname, kind, _ in params:
            if kind == "var_positional":
                return f"{qualname}: *{pname} (no real signature)"
            # **options forwarded (and said so), or **fields beside a typed options= whose fields they set.
            sugar = pname == "fields" and any(p[0] == "options" for p in params)
            if kind == "var_keyword" and not sugar and not (pname == FORWARDED_KEYWORDS and "options" in (obj.__doc__ or "")):
                return f"{qualname}: bare **{pname} (no real signature)"
    return None


def python_params(obj):
    sig = inspect.signature(obj)
    kinds = {inspect.Parameter.VAR_POSITIONAL: "var_positional", inspect.Parameter.VAR_KEYWORD: "var_keyword",
             inspect.Parameter.KEYWORD_ONLY: "keyword_only"}
    return [(p.name, kinds.get(p.kind, "positional"), None) for p in sig.parameters.values()]


def object_problems(stub=None):
    """Docs, signatures and stub agreement of every public object (and of its classes' members)."""
    stub = stub_signatures() if stub is None else stub
    problems = []
    for qualname, obj in public_objects():
        short = qualname.rsplit(".", 1)[1]
        if not (callable(obj) or isinstance(obj, type)):
            continue  # a constant
        if not documented(obj, getattr(obj, "__name__", short)):
            problems.append(f"{qualname}: no docstring")
        core = is_core(obj)
        core_name = getattr(obj, "__name__", short)
        if core and core_name not in stub:
            problems.append(f"{qualname}: not in {STUB.name}")
        members = class_members(obj) if isinstance(obj, type) else [(None, obj)]
        for member, raw in members:
            label = qualname if member is None else f"{qualname}.{member}"
            fname = core_name if member is None else member
            if is_static_property(raw):
                if member not in (obj.__doc__ or ""):
                    problems.append(f"{label}: a static property the class docstring does not name")
                continue
            if member is not None and member != "__init__" and not documented(raw, member):
                problems.append(f"{label}: no docstring")
            if isinstance(raw, property):
                continue
            if core:
                params_list = binding_signatures(raw, fname)
                if not params_list:
                    problems.append(f"{label}: no signature in its docstring")
                    continue
                key = core_name if member is None else f"{core_name}.{member}"
                if key not in stub:
                    problems.append(f"{label}: not in {STUB.name}")
                else:
                    want = stub[key]
                    for params in params_list:
                        if not any(_same_params(params, s) for s in want):
                            problems.append(f"{label}: binding {_show(params)} but stub "
                                            + " | ".join(_show(s) for s in want))
                    for s in want:
                        if not any(_same_params(p, s) for p in params_list):
                            problems.append(f"{label}: stub {_show(s)} matches no binding overload")
            else:
                try:
                    params_list = [python_params(raw)]
                except (TypeError, ValueError):
                    problems.append(f"{label}: inspect.signature fails")
                    continue
            problem = _signature_problem(label, raw, fname, params_list)
            if problem:
                problems.append(problem)
    return problems


def test_every_public_name_is_exported():
    problems = export_problems()
    assert not problems, "\n".join(problems)


def test_every_module_is_documented():
    missing = [m.__name__ for m in modules() if not (m.__doc__ or "").strip()]
    assert not missing, missing


def test_every_public_object_is_documented_with_a_real_signature_that_the_stub_matches():
    problems = object_problems()
    assert not problems, "\n".join(problems)


# --- the face of the classes (docs/api.md) -----------------------------------------------------

API_PAGE = STUB.parents[2] / "docs" / "api.md"

#: Classes with save() that are not stateful classes of the face, with the reason (docs/api.md says it too).
NOT_STATE_FILES = {
    "LearnedInverseModel": "a trained model: save/load write its weights as a NumPy .npz, not a state file",
}


def api_row(text: str, first_cell: str):
    """The names in backticks in the last cell of the docs/api.md table row that starts with
    ``first_cell`` (the classes a name applies to)."""
    for line in text.splitlines():
        cells = line.split("|")
        if len(cells) > 3 and cells[1].strip().startswith(first_cell):
            return re.findall(r"`(\w+)`", cells[-2])
    raise AssertionError(f"docs/api.md has no row starting {first_cell}")


def exported_class(name: str):
    """The class probslam exports as ``name``, or None."""
    obj = getattr(probslam, name, None)
    return obj if isinstance(obj, type) and name in probslam.__all__ else None


def face_problems(text: str):
    """What the classes do against what docs/api.md says they do: every class of the copy() row
    has copy() and is stateful, so it has save/load and pickling and is in the save row; every
    class of the save row has them; every exported class with save() is on both rows; every
    class of the options row has ``options``; every result type of the results table is exported."""
    problems = []
    copyable, saved = api_row(text, "`copy()`"), api_row(text, "`save(path)`")
    for name in copyable + saved:
        cls = exported_class(name)
        if cls is None:
            problems.append(f"{name}: on the api page but not a class probslam exports")
            continue
        for attribute in ("copy", "save", "load", "__getstate__", "__setstate__"):
            if not callable(getattr(cls, attribute, None)):
                problems.append(f"{name}: no {attribute} (docs/api.md: every stateful class has copy, save/load, pickle)")
    problems += [f"{name}: in the copy() row but not in the save row" for name in copyable if name not in saved]
    with_options = api_row(text, "`options`")
    for name in probslam.__all__:
        cls = exported_class(name)
        if cls is None or hasattr(cls, "validate") or hasattr(cls, "replace") or name in NOT_STATE_FILES:
            continue  # not a class, an options class (copy() and pickling by fields, no file), or a model
        if callable(getattr(cls, "save", None)):
            problems += [f"{name}: has save() but is not in the {row} row of docs/api.md"
                         for row, names in (("copy()", copyable), ("save", saved)) if name not in names]
        if callable(getattr(cls, "copy", None)) and name not in copyable:
            problems.append(f"{name}: has copy() but is not in the copy() row of docs/api.md")
        if isinstance(getattr(cls, "options", None), property) and name not in with_options:
            problems.append(f"{name}: has options but is not in the options row of docs/api.md")
    for name in with_options:
        cls = exported_class(name)
        if cls is None or not isinstance(getattr(cls, "options", None), property):
            problems.append(f"{name}: in the options row but has no options property")
    results = text.split("## Results", 1)[1].split("\n## ", 1)[0]
    for line in results.splitlines():
        cells = line.split("|")
        if len(cells) > 3 and cells[2].strip().startswith("`"):
            for name in re.findall(r"`(\w+)`", cells[2]):
                if not any(hasattr(m, name) for m in modules()):
                    problems.append(f"{name}: a result type on the api page that no module exports")
    return problems


def test_the_classes_have_the_face_the_api_page_describes():
    problems = face_problems(API_PAGE.read_text())
    assert not problems, "\n".join(problems)


def test_a_face_that_drifts_from_the_api_page_is_caught():
    """A class named on the save row without save(), one left off it that has save(), an options
    row naming a class without options, and a result type nobody exports each give a problem."""
    text = API_PAGE.read_text()
    cases = {
        "CorrelativeScanMatcher: no save": ("`PoseGraph3D`, `MonteCarloLocalization` |",
                                            "`PoseGraph3D`, `MonteCarloLocalization`, `CorrelativeScanMatcher` |"),
        "FastSlam: has save() but is not in the save row": ("| `EkfSlam`, `MultiHypothesisEkfSlam`, `FastSlam`, `GridFastSlam`, "
                                                            "`SubmapSlam2D`, `IncrementalScanMatcher`, `OccupancyGrid2D`, `OccupancyGrid3D`, "
                                                            "`PoseGraph2D`, `PoseGraph3D`, `MonteCarloLocalization` |",
                                                            "| `EkfSlam`, `MultiHypothesisEkfSlam`, `GridFastSlam`, "
                                                            "`SubmapSlam2D`, `IncrementalScanMatcher`, `OccupancyGrid2D`, `OccupancyGrid3D`, "
                                                            "`PoseGraph2D`, `PoseGraph3D`, `MonteCarloLocalization` |"),
        "GridFastSlam: has options but is not in the options row": (
            "| `MonteCarloLocalization`, `IncrementalScanMatcher`, `SubmapSlam2D`, `GridFastSlam`, ",
            "| `MonteCarloLocalization`, `IncrementalScanMatcher`, `SubmapSlam2D`, "),
        "EkfSlam: in the options row": ("`FastSlam`, `MultiHypothesisEkfSlam` |", "`FastSlam`, `MultiHypothesisEkfSlam`, `EkfSlam` |"),
        "NoSuchResult: a result type": ("| `UpdateResult` |", "| `NoSuchResult` |"),
    }
    for expected, (old, new) in cases.items():
        drifted = text.replace(old, new, 1)
        assert drifted != text, expected
        assert any(p.startswith(expected) for p in face_problems(drifted)), (expected, face_problems(drifted))


# --- the checks can fail ------------------------------------------------------------------------

def test_a_stub_that_drifts_is_caught():
    """A default changed, a parameter renamed, one made keyword-only and a method dropped in the
    stub each produce a problem naming the object."""
    text = STUB.read_text()
    cases = {
        "GridFastSlam.__init__": (r"(class GridFastSlam\b.*?num_particles: int = )30", r"\g<1>31"),
        "OccupancyGrid3D.__init__": (r"(class OccupancyGrid3D\b.*?def __init__\(self, )resolution", r"\1res"),
        "write_g2o": (r"def write_g2o\(path", "def write_g2o(*, path"),
        "FastSlam.landmarks": (r"(class FastSlam\b.*?)\n    def landmarks\(.*?\n(?=    def |\n)", r"\1\n"),
    }
    for name, (pattern, replacement) in cases.items():
        drifted = re.sub(pattern, replacement, text, count=1, flags=re.S)
        assert drifted != text, name
        problems = object_problems(stub_signatures(drifted))
        assert any(name.split(".")[-1] in p and name.split(".")[0] in p for p in problems), (name, problems)


def test_bare_keywords_and_missing_docs_are_caught():
    def bare(**kwargs):
        """Takes anything."""

    def forwards(x, **options):
        """x, and options that go to a class."""

    assert _signature_problem("bare", bare, "bare", [python_params(bare)])
    assert _signature_problem("forwards", forwards, "forwards", [python_params(forwards)]) is None
    assert binding_signatures(types.SimpleNamespace(__doc__="f(self: X, a: int, *, b: float = math.inf) -> None\n"),
                              "f") == [[("a", "positional", None), ("b", "keyword_only", "math.inf")]]
    assert not documented(types.SimpleNamespace(__doc__="f(x: float) -> float\n"), "f")
    assert _same_default("inf", "math.inf") and not _same_default("1", "1.5")
    assert _same_default("<Association.MAXIMUM_LIKELIHOOD: 0>", "Association.MAXIMUM_LIKELIHOOD")
    assert not _same_default("True", "1") and not _same_default("...", "0.5")
