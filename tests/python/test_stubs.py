"""The type stub python/probslam/_core.pyi against the built module probslam._core.

A hand-written stub drifts from the module silently; this test is the check: every public name
of the module (module level, and the public attributes of each class) must be in the stub and
every name of the stub in the module, and every public function, class, method and property of
the module must carry a runtime docstring (what help() shows), beyond the signature pybind11
generates. The comparison reads the stub with ``ast`` (no type checker needed).
"""

import ast
import inspect
import pathlib
import re
import types

import pytest

import probslam
from probslam import _core

STUB = pathlib.Path(__file__).resolve().parents[2] / "python" / "probslam" / "_core.pyi"

#: Attributes pybind11 gives every enum type itself, without a docstring of ours.
ENUM_BUILTINS = {"name", "value"}


def _stub_tree():
    return ast.parse(STUB.read_text(), filename=str(STUB))


def _names_in(body):
    """Names a stub body defines: functions, classes, annotated names. Plain assignments at module
    level are type aliases of the stub (ArrayLike, Array, Bounds), not module attributes."""
    out = set()
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            out.add(node.target.id)
    return out


def stub_module_names():
    return _names_in(_stub_tree().body)


def stub_class_members():
    """{class name: names defined in its body, including plain assignments}."""
    out = {}
    for node in _stub_tree().body:
        if isinstance(node, ast.ClassDef):
            names = _names_in(node.body)
            names |= {t.id for n in node.body if isinstance(n, ast.Assign) for t in n.targets if isinstance(t, ast.Name)}
            out[node.name] = names
    return out


def module_public_names():
    return {n for n in dir(_core) if not n.startswith("_")}


def module_classes():
    """Public classes, and the private ones the stub declares (the Python wrappers use them)."""
    stub = stub_module_names()
    return {n: getattr(_core, n) for n in dir(_core)
            if isinstance(getattr(_core, n), type) and (not n.startswith("_") or n in stub)}


def class_public_members(cls):
    return {n for n in dir(cls) if not n.startswith("_")}


def _doc_text(obj, name: str) -> str:
    """The docstring of obj without the signature lines pybind11 generates for functions."""
    doc = inspect.getdoc(obj) or ""
    keep = []
    for line in doc.splitlines():
        s = line.strip()
        if s == "Overloaded function." or s.startswith(name + "(") or re.match(r"\d+\. " + re.escape(name) + r"\(", s):
            continue
        keep.append(s)
    return "\n".join(keep).strip()


def has_doc(obj, name: str) -> bool:
    if isinstance(obj, type):
        doc = obj.__doc__ or ""
        # A dataclass or NamedTuple without a docstring gets its own signature as one.
        return bool(doc.strip()) and not doc.startswith(name + "(")
    return bool(_doc_text(obj, name))


def missing_docs():
    """Every public function, class, method and property of the module without a docstring."""
    missing = []
    for name in sorted(module_public_names()):
        obj = getattr(_core, name)
        if callable(obj) and not has_doc(obj, name):
            missing.append(name)
    for cname, cls in sorted(module_classes().items()):
        is_enum = hasattr(cls, "__members__")
        for member in sorted(class_public_members(cls)):
            if is_enum and (member in ENUM_BUILTINS or member in cls.__members__):
                continue  # enum values are documented in the class docstring ("Members:")
            raw = inspect.getattr_static(cls, member)
            if isinstance(raw, (staticmethod, classmethod)):
                raw = raw.__func__
            if type(raw).__name__ == "pybind11_static_property":
                # pybind11 drops a static property's docstring: the class docstring names it.
                if member not in (cls.__doc__ or ""):
                    missing.append(f"{cname}.{member}")
                continue
            if not has_doc(raw, member):
                missing.append(f"{cname}.{member}")
    return missing


def test_every_public_module_name_is_in_the_stub():
    missing = module_public_names() - stub_module_names()
    assert not missing, f"in probslam._core but not in {STUB.name}: {sorted(missing)}"


def test_every_stub_name_is_in_the_module():
    extra = {n for n in stub_module_names() if not hasattr(_core, n)}
    assert not extra, f"in {STUB.name} but not in probslam._core: {sorted(extra)}"


def test_every_class_attribute_matches_the_stub():
    stub = stub_class_members()
    problems = []
    for name, cls in sorted(module_classes().items()):
        if name not in stub:
            problems.append(f"class {name} missing from the stub")
            continue
        public = class_public_members(cls)
        stub_public = {n for n in stub[name] if not n.startswith("_")}
        problems += [f"{name}.{n} missing from the stub" for n in sorted(public - stub_public)]
        problems += [f"{name}.{n} in the stub but not in the module" for n in sorted(stub_public - public)]
    assert not problems, "\n".join(problems)


def test_every_public_name_has_a_runtime_docstring():
    missing = missing_docs()
    assert not missing, f"no docstring (help() shows a bare signature): {missing}"


def test_the_checks_can_fail(monkeypatch):
    """The comparison sees a name deleted from the stub, and an undocumented function."""
    text = STUB.read_text()
    cut = re.sub(r"^def write_g2o\(.*?\n(?=\S)", "", text, count=1, flags=re.S | re.M)
    assert cut != text
    monkeypatch.setattr(pathlib.Path, "read_text", lambda self, *a, **k: cut if self == STUB else text)
    assert "write_g2o" in module_public_names() - stub_module_names()
    bare = types.SimpleNamespace(__doc__="f(x: float) -> float\n")
    assert not has_doc(bare, "f")
    assert has_doc(types.SimpleNamespace(__doc__="f(x: float) -> float\n\nTwice x, metres.\n"), "f")


def test_python_level_public_names_have_docstrings():
    missing = [name for name in probslam.__all__
               if (isinstance(getattr(probslam, name), types.ModuleType) and not (getattr(probslam, name).__doc__ or "").strip())
               or (callable(getattr(probslam, name)) and not has_doc(getattr(probslam, name), name))]
    assert not missing, f"public names of probslam without a docstring: {missing}"


def _public_members(module):
    """A module's public names: its __all__, else the names it defines itself."""
    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n in dir(module) if not n.startswith("_")
                 and getattr(getattr(module, n), "__module__", None) == module.__name__]
    return names


@pytest.mark.parametrize("module", ["graph", "ekf", "fastslam", "sim", "slam", "eval", "graphslam", "mapping",
                                    "map_occupancy", "inverse_learning", "landmark_slam", "datasets",
                                    "datasets.mrclam", "datasets.victoria_park", "datasets.victoria_park_acfr",
                                    "io.laser_log", "io", "plot", "cli",
                                    "data"])
def test_python_modules_and_their_public_names_have_docstrings(module):
    import importlib
    m = importlib.import_module(f"probslam.{module}")
    missing = [] if (m.__doc__ or "").strip() else ["(module)"]
    for name in _public_members(m):
        obj = getattr(m, name)
        if callable(obj) and not has_doc(obj, name):
            missing.append(name)
        if isinstance(obj, type) and obj.__module__.startswith("probslam."):
            for attr, value in vars(obj).items():
                if not attr.startswith("_") and (inspect.isfunction(value) or isinstance(value, property)) \
                        and not (value.__doc__ or "").strip():
                    missing.append(f"{name}.{attr}")
    assert not missing, f"probslam.{module}: no docstring for {missing}"
