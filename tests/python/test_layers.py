"""The package's imports point downward: cli -> batch -> pipelines -> datasets -> algorithms -> eval
-> io -> geometry -> _core (and the private helpers beside it). A module may import its own layer and
any layer below; an import upward (io reading eval, an algorithm reading a dataset) is a cycle
waiting to happen and a sign that a kernel lives in the wrong place."""

import ast
import pathlib

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "python" / "probslam"

#: Each top-level module or subpackage of probslam, by layer (0 is the top).
LAYERS = [
    {"cli", "__main__", "__init__"},
    {"batch"},
    {"pipelines"},
    {"datasets"},
    {"slam", "localization", "fastslam", "ekf", "graph", "graphslam", "landmark_refine", "landmark_slam", "mapping",
     "map_occupancy", "inverse_learning", "sim", "sim_laser", "plot", "certificate"},
    {"eval"},
    {"io"},
    {"geometry"},
    {"_core", "_args", "_progress", "data"},
]
LEVEL = {name: k for k, names in enumerate(LAYERS) for name in names}

#: Upward imports still in the tree, each with what removes it (issue 52): the list only shrinks.
KNOWN_UPWARD: set = set()


def imports():
    """(importing top-level name, imported top-level name, file:line) of every relative import."""
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).with_suffix("")
        package = list(rel.parts[:-1])
        me = rel.parts[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if not (isinstance(node, ast.ImportFrom) and node.level):
                continue
            base = package[:len(package) - (node.level - 1)]
            names = [node.module] if node.module else [a.name for a in node.names]
            for name in names:
                target = (base + name.split("."))[0] if base or name else name
                yield me, target, f"{'/'.join(rel.parts)}.py:{node.lineno}"


def test_every_module_has_a_layer():
    unknown = sorted({f"{me} ({where})" for me, target, where in imports() for name in (me, target)
                      if name not in LEVEL and name != "__version__"})
    assert not unknown, unknown


def test_imports_point_downward():
    upward = sorted(f"{where}: {me} imports {target}" for me, target, where in imports()
                    if target in LEVEL and me in LEVEL and LEVEL[target] < LEVEL[me]
                    and (me, target) not in KNOWN_UPWARD)
    assert not upward, "\n".join(upward)


def test_the_known_exceptions_still_exist():
    """An exception removed from the code leaves the list too (so the list only shrinks)."""
    seen = {(me, target) for me, target, _ in imports()}
    assert KNOWN_UPWARD <= seen, KNOWN_UPWARD - seen


def test_the_cpp_core_includes_only_the_core():
    """core/ is below every C++ family (io, grid, graph, filters): its headers and sources
    include nothing of theirs."""
    root = PACKAGE.parents[1]
    outside = []
    for path in sorted([*(root / "include" / "probslam" / "core").glob("*"), *(root / "src" / "core").glob("*")]):
        for k, line in enumerate(path.read_text().splitlines(), 1):
            if line.startswith('#include "') and not (line.startswith('#include "probslam/core/')
                                                      or "/" not in line.split('"')[1]):
                outside.append(f"{path.relative_to(root)}:{k}: {line}")
    assert not outside, "\n".join(outside)
