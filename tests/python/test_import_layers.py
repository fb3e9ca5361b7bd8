"""The Python package's imports are layered and acyclic (issue 27, item 3).

The import graph is built from the package's source with ast, not by importing it: imports
inside functions count as much as those at module level (a cycle hidden in a function is still
a cycle: it decides which module can be used without which), and so do relative imports,
absolute ``lgvi.`` imports and ``importlib.import_module("lgvi....")`` with a literal name.
Runs without the compiled module and without numpy.
"""

import ast
import os
import pathlib

import pytest

PACKAGE = "lgvi"
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
SOURCE = SOURCE / "python" / PACKAGE

#: The layers, bottom first. A module may import modules of lower layers only (not of its own
#: layer, not above): that makes the graph acyclic by construction and says which modules work
#: without which. Every module of the package must be listed, so a new one gets a place.
LAYERS = (
    ("_core",),                             # the compiled module (pybind11): imports nothing of the package
    ("_columns", "_check", "_attitude"),    # the trajectory schema, argument checks, attitude maths
    ("_toml",),                             # TOML text for the compiled reader
    ("_result",),                           # Result (one body or many): pure numpy, no compiled code
    ("_io",),                               # lgvi.load: reads run folders into _result's classes
    ("potential", "forcing"),               # potentials and forcing written in Python
    ("_api",),                              # Body, Scenario, simulate, Stepper (on _core)
    ("_ensemble",),                         # lgvi.ensemble (on _api's scenarios)
    ("plot", "viewer", "compare_plot"),     # figures and views: on top, nothing imports them
)
#: The package's __init__.py: the facade, above every layer. It may expose anything (lazily);
#: no module of the package may import it (that would be an import from the top).
FACADE = "__init__"

#: Upward imports that are kept on purpose, each inside a deprecated function that warns
#: (DeprecationWarning) and names its replacement: (importer, imported) -> the function.
#: Result.draw_figures calls lgvi.plot: the documented path is
#: lgvi.plot.draw_figures(result, out_dir); the method stays for code that calls it.
DEPRECATED_SHIMS = {("_result", "plot"): "_deprecated_draw_figures"}


def _exempt(importer, target, function):
    """Whether this import is the one a DEPRECATED_SHIMS entry allows (in that function only)."""
    return function is not None and DEPRECATED_SHIMS.get((importer, target)) == function


def _modules():
    """Module name -> path, for every .py file of the package (the package has no subpackages)."""
    assert SOURCE.is_dir(), f"the package's source is not at {SOURCE}"
    subpackages = [p for p in SOURCE.iterdir() if p.is_dir() and (p / "__init__.py").exists()]
    # The resolution below assumes a flat package; a subpackage needs it extended, so fail loudly.
    assert not subpackages, f"subpackages {subpackages}: extend the import graph test to resolve them"
    return {p.stem: p for p in sorted(SOURCE.glob("*.py"))}


def _target(dotted, known):
    """The package module an absolute dotted name refers to ('lgvi.plot.x' -> 'plot',
    'lgvi' -> the facade), or None for a module outside the package."""
    parts = dotted.split(".")
    if parts[0] != PACKAGE:
        return None
    if len(parts) == 1:
        return FACADE
    return parts[1] if parts[1] in known or parts[1] == "_core" else FACADE


def _imports(path, known):
    """The package modules `path` imports, as (imported module, enclosing function or None, line)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []

    def visit(node, function):
        for child in ast.iter_child_nodes(node):
            inner = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
            if isinstance(child, ast.Import):
                for alias in child.names:
                    target = _target(alias.name, known)
                    if target:
                        found.append((target, function, child.lineno))
            elif isinstance(child, ast.ImportFrom):
                if child.level > 1:
                    raise AssertionError(f"{path.name}:{child.lineno}: an import from above the package")
                base = PACKAGE + ("." + child.module if child.module else "") if child.level == 1 else child.module
                target = _target(base or "", known)
                if target == FACADE and (child.level == 1 or base == PACKAGE):
                    # from . import plot / from lgvi import plot: each name may be a submodule
                    for alias in child.names:
                        sub = alias.name
                        found.append((sub if sub in known or sub == "_core" else FACADE, function, child.lineno))
                elif target:
                    found.append((target, function, child.lineno))
            elif (isinstance(child, ast.Call) and getattr(child.func, "attr", getattr(child.func, "id", None))
                  in ("import_module", "__import__") and child.args and isinstance(child.args[0], ast.Constant)
                  and isinstance(child.args[0].value, str)):
                name = child.args[0].value
                target = _target(PACKAGE + name if name.startswith(".") else name, known)
                if target:
                    found.append((target, function, child.lineno))
            visit(child, inner)

    visit(tree, None)
    return found


def _graph():
    modules = _modules()
    known = set(modules)
    return modules, {name: _imports(path, known) for name, path in modules.items()}


def _layer_of():
    return {m: i for i, layer in enumerate(LAYERS) for m in layer}


def _cycle(edges):
    """One cycle of the graph {module: {imported}} as a list of modules, or None."""
    state = {}
    stack = []

    def dfs(m):
        state[m] = 1
        stack.append(m)
        for n in sorted(edges.get(m, ())):
            if state.get(n) == 1:
                return stack[stack.index(n):] + [n]
            if n not in state:
                found = dfs(n)
                if found:
                    return found
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(edges):
        if m not in state:
            found = dfs(m)
            if found:
                return found
    return None


def test_every_module_has_a_layer():
    # A module missing from LAYERS would escape the layer check; a listed module that no longer
    # exists means the table is stale. Either way the declared architecture is not the code's.
    modules = set(_modules()) - {FACADE}
    declared = set(_layer_of()) - {"_core"}
    assert modules - declared == set(), f"modules without a layer in LAYERS: {sorted(modules - declared)}"
    assert declared - modules == set(), f"LAYERS lists modules that do not exist: {sorted(declared - modules)}"
    assert sum(len(layer) for layer in LAYERS) == len(_layer_of()), "a module is listed in two layers"


def test_imports_go_down_the_layers():
    # Strictly downwards: an import within a layer or upwards (at module level or hidden in a
    # function) is what made _api -> _result -> plot -> _ensemble -> _api a circle.
    _, imports = _graph()
    layer = _layer_of()
    wrong = []
    for importer, targets in imports.items():
        if importer == FACADE:
            continue
        for target, function, line in targets:
            if target == FACADE:
                wrong.append(f"{importer}.py:{line} imports the package facade lgvi (the top)")
            elif layer[target] >= layer[importer] and not _exempt(importer, target, function):
                where = f" (in {function})" if function else ""
                wrong.append(f"{importer}.py:{line}{where} imports {target}: layer {layer[target]} is not below "
                             f"{importer}'s layer {layer[importer]}")
    assert wrong == [], "imports against the layer order:\n" + "\n".join(wrong)


def test_import_graph_is_acyclic():
    # Checked on its own (not only as a consequence of the layers) so that a failure names the
    # cycle. The deprecated shims are left out: each is an upward call in a function that warns.
    _, imports = _graph()
    edges = {m: {t for t, f, _ in ts if not _exempt(m, t, f)} for m, ts in imports.items()}
    assert _cycle(edges) is None, f"import cycle: {' -> '.join(_cycle(edges))}"


def test_nothing_imports_the_figure_modules():
    # plot and viewer are the top: the data classes and the API must work without matplotlib's
    # side of the package. Only the facade exposes them (lazily), and the named deprecated shim.
    _, imports = _graph()
    top = set(LAYERS[-1])
    users = sorted(f"{m}.py:{line}" for m, ts in imports.items() if m != FACADE
                   for t, f, line in ts if t in top and not _exempt(m, t, f))
    assert users == [], f"modules importing {sorted(top)}: {users}"


def test_deprecated_shims_warn():
    # An exemption is only honest if the function it covers is deprecated: it must call
    # warnings.warn(..., DeprecationWarning) and contain the upward import it is exempted for.
    modules, imports = _graph()
    for (importer, target), function in DEPRECATED_SHIMS.items():
        tree = ast.parse(modules[importer].read_text(encoding="utf-8"))
        defs = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == function]
        assert len(defs) == 1, f"{importer}.{function}: not found (drop its entry from DEPRECATED_SHIMS)"
        warns = [n for n in ast.walk(defs[0]) if isinstance(n, ast.Call) and getattr(n.func, "attr", "") == "warn"
                 and any(isinstance(a, ast.Name) and a.id == "DeprecationWarning" for a in n.args)]
        assert warns, f"{importer}.{function} imports {target} upwards but does not warn DeprecationWarning"
        assert (target, function) in {(t, f) for t, f, _ in imports[importer]}, \
            f"{importer}.{function} no longer imports {target}: drop its entry from DEPRECATED_SHIMS"


# The graph builder itself, on small sources: a test of the test, so that a parser that finds
# nothing cannot pass the checks above vacuously.
@pytest.mark.parametrize("source, expected", [
    ("from . import plot", [("plot", None)]),
    ("from .plot import draw_figures", [("plot", None)]),
    ("import lgvi.plot as p", [("plot", None)]),
    ("from lgvi import _api, plot", [("_api", None), ("plot", None)]),
    ("import lgvi", [("__init__", None)]),
    ("def f():\n    from ._api import _scenario\n", [("_api", "f")]),
    ("class C:\n    def m(self):\n        from . import _core\n", [("_core", "m")]),
    ("import importlib\nimportlib.import_module('lgvi.viewer')", [("viewer", None)]),
    ("import numpy\nfrom os import path", []),
])
def test_graph_builder(tmp_path, source, expected):
    path = tmp_path / "m.py"
    path.write_text(source)
    known = {"plot", "_api", "viewer", "_result"}
    assert [(t, f) for t, f, _ in _imports(path, known)] == expected


def test_cycle_finder():
    # The cycle the package had (through functions), as edges: it must be found.
    assert _cycle({"_api": {"_result"}, "_result": {"plot"}, "plot": {"_ensemble"}, "_ensemble": {"_api"}})
    assert _cycle({"a": {"b"}, "b": set()}) is None
