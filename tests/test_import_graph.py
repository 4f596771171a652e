"""No import circles inside fdml (issue 10).

The graph is read from the source with :mod:`ast`: an edge ``a -> b`` for every ``import``
of an fdml module ``b`` in module ``a``.  Module-level imports must form no cycle at all.
Imports deferred into a function body run later and cannot deadlock an import, but a circle
through them still couples the modules both ways: they form none either.  Finally every module
is imported in a fresh interpreter in sorted and in reversed order.
"""

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import fdml

SRC = Path(fdml.__file__).parent


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


def _is_type_checking(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _imports(node: ast.AST, deferred: bool):
    """Import statements that run: module level (in try/if blocks too), and function bodies if ``deferred``."""
    for child in ast.iter_child_nodes(node):
        if _is_type_checking(child):
            continue
        if isinstance(child, (ast.Import, ast.ImportFrom)):
            yield child
        elif deferred or not isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            yield from _imports(child, deferred)


def _targets(stmt, module: str, is_package: bool) -> set[str]:
    if isinstance(stmt, ast.Import):
        return {a.name for a in stmt.names if a.name in MODULES}
    package = module if is_package else module.rpartition(".")[0]
    if stmt.level:
        base = ".".join(package.split(".")[: len(package.split(".")) - stmt.level + 1] + [stmt.module or ""]).strip(".")
    else:
        base = stmt.module or ""
    out = set()
    for a in stmt.names:
        sub = f"{base}.{a.name}"
        out.add(sub if sub in MODULES else base)
    return out & set(MODULES)


def import_graph(deferred: bool) -> dict[str, set[str]]:
    graph = {}
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        edges = set()
        for stmt in _imports(tree, deferred):
            edges |= _targets(stmt, name, path.name == "__init__.py")
        graph[name] = edges - {name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[frozenset]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            w = next(children, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.add(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append(frozenset(comp))
    return found


def test_cycle_finder_finds_a_cycle():
    # the finder is not vacuous: a three-module circle and a two-module one beside a tail
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"e"}, "e": {"d", "a"}, "f": {"a"}}
    assert sorted(map(sorted, cycles(g))) == [["a", "b", "c"], ["d", "e"]]


@pytest.mark.slow
def test_the_graph_sees_the_imports():
    g = import_graph(deferred=False)
    assert "fdml.channels" in g["fdml.record"]  # from .channels import ...
    assert "fdml.spectral" in g["fdml"]  # from .spectral import ...
    assert "fdml.models.effect_library" in g["fdml.models.effects"]
    deferred = import_graph(deferred=True)
    assert "fdml.adequacy" in deferred["fdml.estimate"] - g["fdml.estimate"]  # fit's adequacy check


def test_module_level_imports_form_no_cycle():
    assert cycles(import_graph(deferred=False)) == []


def test_deferred_imports_form_no_cycle_either():
    assert [sorted(c) for c in cycles(import_graph(deferred=True))] == []


def test_the_model_layer_does_not_import_upward():
    full = import_graph(deferred=True)
    # with_effects and realize are functions above the model classes (no registry filled from above);
    # make_model sits above the effects it applies; the effect library builds on the realisation
    assert full["fdml.models.base"] & {"fdml.models.effects", "fdml.models.realization", "fdml.simulate"} == set()
    base = importlib.import_module("fdml.models.base")
    assert not hasattr(base, "UPPER") and not hasattr(base.Model, "with_effects")
    assert "fdml.models.effects" not in full["fdml.models.kinds"] and "fdml.models.effects" in full["fdml.models.build"]
    assert "fdml.simulate" not in full["fdml.models.effect_library"]
    assert "fdml.models" not in full["fdml.models.effects"] | full["fdml.models.effect_library"]
    # the estimator's thresholds and the score screen sit below the estimator
    assert "fdml.estimate" not in full["fdml.summary"] | full["fdml.score"]


@pytest.mark.slow
def test_the_named_circles_are_gone():
    full = import_graph(deferred=True)
    # results -> summary -> compare -> estimate -> results: ALTERNATE_NAMES lives beside alternate_set
    assert "fdml.compare" not in full["fdml.summary"]
    assert not any({"fdml.summary", "fdml.compare"} <= c for c in cycles(full))
    # the effect registry is filled in one place: effects imports the library, never the reverse
    assert "fdml.models.effect_library" in import_graph(deferred=False)["fdml.models.effects"]
    assert "fdml.models.effects" not in full["fdml.models.effect_library"]
    assert not any({"fdml.commands._options", "fdml.commands._common"} <= c for c in cycles(full))


@pytest.mark.slow
@pytest.mark.parametrize("order", ["sorted", "reversed"])
def test_every_module_imports_in_a_fresh_interpreter(order):
    names = sorted(n for n in MODULES if not n.endswith("__main__"))
    if order == "reversed":
        names.reverse()
    code = "import importlib, sys\nfor n in sys.argv[1:]:\n    importlib.import_module(n)\n"
    proc = subprocess.run([sys.executable, "-c", code, *names], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
