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
    "sim": 2,
    "textures": 2,
    "assets": 3,
    "nav": 3,
    "scenes": 4,
    "augment": 5,
    "demos": 5,
    "dataset": 6,
    "policy": 7,
    "report": 8,
    "context": 1,
    "console": 1,
    "summary": 1,
    "stages": 9,
    "runner": 10,
    "__main__": 11,
}
"""Top-level module or package -> floor. A module may import its own floor or lower ones,
except the listed siblings (same floor, independent)."""

INDEPENDENT: set[frozenset[str]] = {frozenset({"augment", "demos"}), frozenset({"assets", "nav"})}


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
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else "factory"


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
