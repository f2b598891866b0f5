"""The import graph between the packages of ``staghunt``: no cycle, top-level and deferred
(function-level) imports alike. The command line (``cli``, ``__main__``) and the package's own
``__init__`` (the public facade) sit on top and are left out: they may import anything, and
nothing below imports them."""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import staghunt

ROOT = Path(staghunt.__file__).parent
TOP = {"cli", "__main__", "(facade)"}


def _package(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "(facade)"


def package_graph() -> dict[str, set[str]]:
    """``{package: packages it imports}`` over every module, every import statement."""
    graph: dict[str, set[str]] = defaultdict(set)
    for path in ROOT.rglob("*.py"):
        module = ".".join(("staghunt", *path.relative_to(ROOT).with_suffix("").parts)).removesuffix(".__init__")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                if name == "staghunt" or name.startswith("staghunt."):
                    a, b = _package(module), _package(name)
                    if a != b:
                        graph[a].add(b)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one package (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def test_no_cycle_between_packages():
    graph = {a: {b for b in bs if b not in TOP} for a, bs in package_graph().items() if a not in TOP}
    assert cycles(graph) == []


def test_nothing_below_imports_the_command_line_or_the_facade():
    offenders = {a: sorted(bs & TOP) for a, bs in package_graph().items() if a not in TOP and bs & TOP}
    assert offenders == {}


def test_the_cycle_finder_finds_cycles():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []
