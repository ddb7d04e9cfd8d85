"""The package's import graph: no circles, and the floors of docs/ARCHITECTURE.md hold."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import factory

ROOT = Path(factory.__file__).parent

FLOORS: dict[str, int] = {
    "schema": 0,
    "errors": 1,
    "config": 1,
    "store": 1,
    "context": 1,
    "console": 1,
    "cores": 1,
    "summary": 1,
    "tasks": 1,
    "tasks.base": 1,
    "tasks.*": 6,
    "sim": 2,
    "textures": 2,
    "assets": 3,
    "nav": 3,
    "robots": 4,
    "scenes": 4,
    "augment": 5,
    "demos.plan": 5,
    "demos.record": 5,
    "demos": 7,
    "dataset": 8,
    "policy": 9,
    "report": 10,
    "stages": 11,
    "runner": 12,
    "__main__": 13,
}
"""Module or package (dotted, below ``factory``) -> floor; a module takes the floor of its
longest listed prefix (``tasks.*``: every task package under ``factory/tasks/``; ``tasks``
alone is the registry and the :class:`~factory.tasks.base.Task` protocol, which lower floors
read). A module may import its own floor or lower ones, except the listed siblings (same
floor, independent)."""

INDEPENDENT: set[frozenset[str]] = {
    frozenset({"augment", "demos.plan"}),
    frozenset({"augment", "demos.record"}),
    frozenset({"assets", "nav"}),
    frozenset({"robots", "scenes"}),
}


def _modules() -> dict[str, Path]:
    mods = {}
    for path in ROOT.rglob("*.py"):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = path
    return mods


def _import_graph() -> dict[str, set[str]]:
    """Module -> the factory modules it imports anywhere (top level or inside functions)."""
    mods = _modules()

    def owner(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    for mod, path in mods.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")
                    parts = parts[: len(parts) - node.level + 1]
                    base = ".".join([*parts, base] if base else parts)
                names = [
                    f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names
                ]
            for name in names:
                if name.split(".")[0] == "factory" and (dep := owner(name)) and dep != mod:
                    deps.add(dep)
        graph[mod] = deps
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycles() -> None:
    cycles = _cycles(_import_graph())
    assert not cycles, "import circles: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_cycle_finder_finds_a_cycle() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def _top(mod: str) -> str:
    """The FLOORS key a module belongs to (its longest listed prefix), ``factory`` for the
    package's own top-level ``__init__``."""
    parts = mod.split(".")[1:]
    if not parts:
        return "factory"
    for n in range(len(parts), 0, -1):
        key = ".".join(parts[:n])
        if n < len(parts) and f"{key}.*" in FLOORS:
            return f"{key}.*"
        if key in FLOORS:
            return key
    return parts[0]


def test_floor_keys() -> None:
    """Sub-package keys resolve to the longest listed prefix."""
    assert _top("factory.demos.plan.grasps") == "demos.plan"
    assert _top("factory.demos.stage") == "demos"
    assert _top("factory.tasks") == "tasks"
    assert _top("factory.tasks.pick_place.plan") == "tasks.*"
    assert _top("factory") == "factory"


def test_floors() -> None:
    """Packages import downwards only (docs/ARCHITECTURE.md, "Packages and floors")."""
    graph = _import_graph()
    bad = []
    for mod, deps in graph.items():
        src = _top(mod)
        if src == "factory":
            continue
        if src not in FLOORS:
            pytest.fail(f"{src} has no floor: add it to FLOORS here and to docs/ARCHITECTURE.md")
        for dep in deps:
            dst = _top(dep)
            if dst in ("factory", src):
                continue
            up = FLOORS[dst] > FLOORS[src]
            sideways = FLOORS[dst] == FLOORS[src] and frozenset({src, dst}) in INDEPENDENT
            if up or sideways:
                bad.append(f"{mod} -> {dep}")
    assert not bad, "imports against the floors: " + ", ".join(sorted(bad))


def test_old_assets_path_warns() -> None:
    import importlib
    import sys

    sys.modules.pop("factory.scenes.assets", None)
    with pytest.warns(DeprecationWarning, match="factory.assets"):
        old = importlib.import_module("factory.scenes.assets")
    from factory.assets import AssetLibrary

    assert old.AssetLibrary is AssetLibrary
