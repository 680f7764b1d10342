"""The house: folders, the layer map, private names and size caps (docs/style.md §2).

The layer map lives in one place, the table under "Map of the layers" in README.md; this
module reads it and checks the code against it: every package is in it, a package imports
only from its own layer or below (imports inside functions included), the import graph has
no cycle, no module imports an underscore name from another package, the package root holds
at most 12 modules, no module exceeds 900 lines and no function 80 code lines.
"""

import ast
import importlib
import pkgutil
import re
from pathlib import Path

import pytest

import freqid_casadi

PACKAGE = "freqid_casadi"
ROOT = Path(freqid_casadi.__file__).resolve().parent
README = ROOT.parent / "README.md"
#: private modules at the package root that every package may use (docs/style.md §2)
ROOT_HELPERS = {"_cplx", "_interrupt", "_malloc", "_progress", "_textio", "_threads", "_validate",
                "_workers"}
MAX_ROOT_MODULES = 12
MAX_MODULE_LINES = 900
MAX_FUNCTION_LINES = 80


def _all_modules():
    names = [PACKAGE] + [m.name for m in pkgutil.walk_packages(freqid_casadi.__path__,
                                                                PACKAGE + ".")]
    return sorted(names)


MODULES = _all_modules()
PACKAGES = {m for m in MODULES if hasattr(importlib.import_module(m), "__path__")}


def _source_file(name):
    return Path(importlib.import_module(name).__file__)


def read_layer_map(text):
    """{top-level name: layer} from the README's table after the layer-map marker."""
    lines = text.split("<!-- layer map: read by tests/test_layout.py -->", 1)[1].splitlines()
    layers = {}
    for line in lines[3:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        for name in re.findall(r"`([\w.]+)`", cells[1]):
            layers[name] = int(cells[0])
    return layers


LAYERS = read_layer_map(README.read_text(encoding="utf-8"))
FACADE = max(LAYERS.values()) + 1      # the package itself re-exports the API: top


def _layer(name, layers=LAYERS):
    parts = name.split(".")
    assert parts[0] == PACKAGE
    if len(parts) == 1:
        return FACADE
    if parts[1] not in layers:
        raise KeyError(f"{name} is not in README.md's layer map (Map of the layers)")
    return layers[parts[1]]


def _package_of(name, packages=PACKAGES):
    return name if name in packages else name.rsplit(".", 1)[0]


def _imports(name, source, packages=PACKAGES, modules=frozenset(MODULES)):
    """(lineno, target module, imported attribute or None) of every package import."""
    here = _package_of(name, packages)
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name, None) for a in node.names
                      if a.name.split(".")[0] == PACKAGE]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = here.split(".")
                base = ".".join(parts[:len(parts) - (node.level - 1)])
                if node.module:
                    base = f"{base}.{node.module}"
            else:
                base = node.module or ""
            if base.split(".")[0] != PACKAGE:
                continue
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                found.append((node.lineno, sub, None) if sub in modules
                             else (node.lineno, base, alias.name))
    return sorted(found, key=lambda item: item[0])


def _violations(name, source, layers=LAYERS, **kw):
    mine = _layer(name, layers)
    return [f"{name}:{line} imports {target} (layer {_layer(target, layers)} > {mine})"
            for line, target, _ in _imports(name, source, **kw)
            if _layer(target, layers) > mine]


def _is_private(part):
    return part.startswith("_") and not part.startswith("__")


def _private_crossings(name, source, packages=PACKAGES, **kw):
    """Imports in ``source`` of an underscore module or name that lives in another package
    (the root's shared helpers excepted)."""
    here = _package_of(name, packages)
    bad = []
    for line, target, attr in _imports(name, source, packages=packages, **kw):
        private = any(_is_private(p) for p in target.split(".")[1:]) or \
            _is_private(attr or "")
        if not private or _package_of(target, packages) == here:
            continue
        if target.rsplit(".", 1) == [PACKAGE, target.split(".")[-1]] and \
                target.split(".")[-1] in ROOT_HELPERS and not _is_private(attr or ""):
            continue
        bad.append(f"{name}:{line} imports {target}{'.' + attr if attr else ''}")
    return bad


# ------------------------------------------------------------------ the map
def test_layer_map_is_read_from_the_readme():
    assert LAYERS["core"] == 1 and LAYERS["cli"] > LAYERS["report"] > LAYERS["plots"]
    assert LAYERS["errors"] == 0 and LAYERS["fitting"] > LAYERS["solvers"]


def test_every_module_is_in_the_layer_map():
    for name in MODULES:
        _layer(name)


def test_layer_map_names_only_what_exists():
    tops = {m.split(".")[1] for m in MODULES if m != PACKAGE}
    assert set(LAYERS) <= tops, f"README's map names {sorted(set(LAYERS) - tops)}"


@pytest.mark.parametrize("name", MODULES)
def test_import_direction(name):
    source = _source_file(name).read_text(encoding="utf-8")
    assert not _violations(name, source)


def test_import_direction_check_has_teeth():
    bad = ("from ..fitting.fit import fit\n"
           "def f():\n    from .. import plots\n    import freqid_casadi.report.folder\n"
           "from freqid_casadi import FrequencyData\n"
           "from ..errors import DataError\n")
    found = _violations("freqid_casadi.core.model", bad)
    assert [v.split(" imports ")[1].split(" ")[0] for v in found] == [
        "freqid_casadi.fitting.fit", "freqid_casadi.plots", "freqid_casadi.report.folder",
        "freqid_casadi"]
    # resolved targets of a sub-package module
    assert _imports("freqid_casadi.baselines.subspace", "from ..core.data import FrequencyData\n"
                    "from ._ssmodel import check_order\nfrom .. import _cplx\n") == [
        (1, "freqid_casadi.core.data", "FrequencyData"),
        (2, "freqid_casadi.baselines._ssmodel", "check_order"),
        (3, "freqid_casadi._cplx", None)]


# ------------------------------------------------------------------ private stays private
@pytest.mark.parametrize("name", MODULES)
def test_no_private_import_crosses_a_package(name):
    source = _source_file(name).read_text(encoding="utf-8")
    assert not _private_crossings(name, source)


def test_private_check_has_teeth():
    src = ("from ..io._table import NUMBER\nfrom ..io import decode_text\n"
           "from ..uncertainty.covariance import _z\nfrom .. import _cplx\n"
           "from .._validate import check_flag\nfrom .._validate import _hidden\n"
           "from ._checks import validate\n")
    found = _private_crossings("freqid_casadi.fitting.fit", src)
    assert [f.split(" imports ")[1] for f in found] == [
        "freqid_casadi.io._table.NUMBER", "freqid_casadi.uncertainty.covariance._z",
        "freqid_casadi._validate._hidden"]


def test_studies_use_only_the_public_api():
    bad = []
    for name in (m for m in MODULES if m.split(".")[1:2] == ["studies"]):
        source = _source_file(name).read_text(encoding="utf-8")
        for line, target, attr in _imports(name, source):
            if target.split(".")[1:2] == ["studies"]:
                continue
            if any(_is_private(p) for p in target.split(".")[1:]) or _is_private(attr or ""):
                bad.append(f"{name}:{line} {target} {attr or ''}")
    assert not bad, f"studies import private names: {bad}"


# ------------------------------------------------------------------ the graph
def _graph():
    """Module -> set of package modules it imports (imports inside functions included)."""
    graph = {}
    for name in MODULES:
        source = _source_file(name).read_text(encoding="utf-8")
        graph[name] = {t for _, t, _ in _imports(name, source) if t != name}
    return graph


def _cycle(graph):
    """One import cycle of ``graph`` as a list of modules, or None (depth-first search)."""
    state, stack = {}, []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        state[node] = 2
        stack.pop()
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_import_graph_is_acyclic():
    # a package's __init__ re-exports its modules; its modules import siblings, not it
    graph = {k: {t for t in v if not (k.startswith(t + ".") and t in PACKAGES)}
             for k, v in _graph().items()}
    cycle = _cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_cycle_check_has_teeth():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


# ------------------------------------------------------------------ caps
def test_package_root_holds_few_modules():
    modules = sorted(p.name for p in ROOT.glob("*.py"))
    assert len(modules) <= MAX_ROOT_MODULES, modules


def _code_lines(node, lines):
    body = lines[node.lineno - 1:node.end_lineno]
    n = sum(1 for line in body if line.strip() and not line.strip().startswith("#"))
    first = node.body[0] if node.body else None
    if isinstance(first, ast.Expr) and isinstance(getattr(first, "value", None), ast.Constant) \
            and isinstance(first.value.value, str):
        n -= first.end_lineno - first.lineno + 1
    return n


def test_modules_and_functions_stay_readable():
    long_modules, long_functions = [], []
    for path in sorted(ROOT.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        if len(lines) > MAX_MODULE_LINES:
            long_modules.append(f"{path.relative_to(ROOT)} ({len(lines)})")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = _code_lines(node, lines)
                if n > MAX_FUNCTION_LINES:
                    long_functions.append(f"{path.relative_to(ROOT)}:{node.name} ({n})")
    assert not long_modules, f"modules over {MAX_MODULE_LINES} lines: {long_modules}"
    assert not long_functions, f"functions over {MAX_FUNCTION_LINES} lines: {long_functions}"
