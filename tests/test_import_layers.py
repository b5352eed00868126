"""The two packages' layers: ``humotion_gym`` never imports ``baselines``; no import cycles.

The graph is read from the source with :mod:`ast`, every import statement counted
wherever it stands (a function-level import that would close a cycle is a cycle
all the same). ``from package import name`` is an edge to ``package.name`` where
that is a module, else to ``package``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("humotion_gym", "baselines")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _resolve(module: str, level: int, current: str, is_package: bool) -> str:
    if level == 0:
        return module
    base = current.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join([*base, module] if module else base)


def import_graph(modules: Mapping[str, Path]) -> dict[str, set[str]]:
    """Each internal module's internal imports (function-level ones included)."""
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        edges: set[str] = set()
        is_package = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(node.module or "", node.level, name, is_package)
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                           for a in node.names]  # fmt: skip
            else:
                continue
            for target in targets:
                while target and target not in modules:  # a.b.c -> the module a.b
                    target = target.rpartition(".")[0]
                if target and target != name:
                    edges.add(target)
        graph[name] = edges
    return graph


def cycles(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(_modules())


def test_the_benchmark_never_imports_the_baselines(graph):
    upward = sorted(
        f"{m} -> {t}"
        for m, targets in graph.items()
        if m.startswith("humotion_gym")
        for t in targets
        if t.split(".")[0] == "baselines"
    )
    assert not upward, "humotion_gym imports baselines:\n" + "\n".join(upward)


def test_no_import_cycles(graph):
    found = cycles(graph)
    assert not found, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_the_checks_fail_on_a_cycle_and_an_upward_import(tmp_path):
    # mutation: a graph with a three-module cycle, and a module importing upward
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []
    pkg = tmp_path / "humotion_gym"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "x.py").write_text("def f():\n    from . import y\n")
    (pkg / "y.py").write_text("from humotion_gym.x import f\nimport baselines.agents\n")
    (tmp_path / "agents.py").write_text("")
    mods = {"humotion_gym": pkg / "__init__.py", "humotion_gym.x": pkg / "x.py",
            "humotion_gym.y": pkg / "y.py", "baselines.agents": tmp_path / "agents.py"}  # fmt: skip
    g = import_graph(mods)
    assert g["humotion_gym.x"] == {"humotion_gym.y"}  # the function-level import counts
    assert "baselines.agents" in g["humotion_gym.y"]
    assert cycles(g) == [["humotion_gym.x", "humotion_gym.y"]]
