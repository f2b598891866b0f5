"""The import graph between the packages of ``staghunt``: no cycle, and every arrow points down
the layers of :data:`LAYERS`, top-level and deferred (function-level) imports alike. The command
line (``cli``, ``__main__``) and the package's own ``__init__`` (the public facade) sit on top:
they may import anything, and nothing below imports them."""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import staghunt

ROOT = Path(staghunt.__file__).parent
TOP = {"cli", "__main__", "(facade)"}

LAYERS: list[set[str]] = [
    {"_version", "errors"},  # foundation: imports nothing of ours
    {"inputs", "encoding", "world", "camera"},  # reading untrusted input; the world's shapes; cameras
    {"task"},  # team, formation, objectives and payloads
    {"scenario", "geo"},  # the problem as given; the site frame
    {"costs"},
    {"checks", "solvers", "acquisition", "safety"},  # acquisition: capture plans, triggering and coverage; safety: the one judge
    {"engine", "trajectory"},  # engines run the solvers' problems; timing of checked paths
    {"budget", "result"},
    {"io"},  # files in and out
    {"api"},  # check_plan / plan
    {"inspection"},  # task management: objectives to allocated, planned inspections
    {"study"},  # many plans as tasks (sweep; compare runs on it)
    {"analysis"},  # certify, compare, the paper's figures
    {"flight"},  # closed loop: plans through api, reads results through analysis
    {"plots"},
    {"missions"},  # export: flies missions in simulation, draws them
    TOP,
]
"""The packages from the bottom up: a package may import its own modules and packages of lower
layers only (so, within a layer, none imports another)."""


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


def _modules() -> dict[str, Path]:
    """``{module name: file}`` of every module of ``staghunt`` (a package by its ``__init__``)."""
    return {".".join(("staghunt", *p.relative_to(ROOT).with_suffix("").parts)).removesuffix(".__init__"): p
            for p in ROOT.rglob("*.py")}


def _module_level_imports(tree: ast.Module) -> list[ast.Import | ast.ImportFrom]:
    """The import statements a module runs when it is imported, and those for type checkers
    (under ``if TYPE_CHECKING``): its top level, inside ``if`` and ``try`` blocks; not inside
    functions or classes (deferred imports)."""
    found: list[ast.Import | ast.ImportFrom] = []

    def visit(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                found.append(node)
            elif isinstance(node, ast.If):
                visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                visit(node.body)
                for handler in node.handlers:
                    visit(handler.body)
                visit(node.orelse)
                visit(node.finalbody)

    visit(tree.body)
    return found


def module_graph() -> dict[str, set[str]]:
    """``{module: modules it imports at module level}`` (:func:`_module_level_imports`); an
    imported name is the module it names, or the module that defines it (``from a.b import c``:
    ``a.b.c`` if that is a module, else ``a.b``). A module importing its own package (its
    ``__init__``) is left out: a package's facade re-exports its modules."""
    modules = _modules()

    def target(name: str) -> str | None:
        parts = name.split(".")
        return next((".".join(parts[:i]) for i in range(len(parts), 0, -1) if ".".join(parts[:i]) in modules), None)

    graph: dict[str, set[str]] = defaultdict(set)
    for module, path in modules.items():
        for node in _module_level_imports(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif node.level == 0 and node.module:
                names = [f"{node.module}.{a.name}" for a in node.names]
            else:
                continue
            for name in names:
                t = target(name) if name.startswith("staghunt") else None
                if t is not None and t != module and not module.startswith(t + "."):
                    graph[module].add(t)
    return graph


def test_no_cycle_between_modules():
    """No two modules import each other, directly or through others, at module level: inside a
    package or across packages (deferred imports, inside functions, are the packages' test's)."""
    assert cycles(module_graph()) == []


def test_the_module_graph_sees_type_checking_imports(tmp_path):
    """An import for type checkers only still counts (it is a cycle for them), one in a function
    does not."""
    tree = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import a\n"
                     "try:\n    import b\nexcept ImportError:\n    import c\ndef f():\n    import d\n")
    names = [n.module if isinstance(n, ast.ImportFrom) else n.names[0].name for n in _module_level_imports(tree)]
    assert names == ["typing", "a", "b", "c"]
    assert cycles({"staghunt.solvers.base": {"staghunt.solvers.response"},
                   "staghunt.solvers.response": {"staghunt.solvers.base"}}) != []


MAX_MODULE_LINES = 450


def test_every_module_is_at_most_450_lines():
    long = {str(p.relative_to(ROOT)): n for p in ROOT.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES}
    assert long == {}


def test_no_cycle_between_packages():
    graph = {a: {b for b in bs if b not in TOP} for a, bs in package_graph().items() if a not in TOP}
    assert cycles(graph) == []


def test_nothing_below_imports_the_command_line_or_the_facade():
    offenders = {a: sorted(bs & TOP) for a, bs in package_graph().items() if a not in TOP and bs & TOP}
    assert offenders == {}


def layer_of(package: str) -> int:
    for i, layer in enumerate(LAYERS):
        if package in layer:
            return i
    raise KeyError(package)


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """``"a -> b"`` for every package ``a`` importing ``b`` of its own layer or one above."""
    return [f"{a} -> {b}" for a, bs in sorted(graph.items()) for b in sorted(bs)
            if a not in TOP and layer_of(b) >= layer_of(a)]


def test_every_package_has_a_layer():
    packages = {p.name for p in ROOT.iterdir() if (p / "__init__.py").exists()}
    packages |= {p.stem for p in ROOT.glob("*.py")} - {"__init__"}
    placed = set().union(*LAYERS)
    assert sorted(packages - placed) == []


def test_every_import_points_down_the_layers():
    assert upward_imports(package_graph()) == []


def test_the_layer_check_finds_upward_imports():
    assert upward_imports({"costs": {"scenario", "api"}, "checks": {"solvers"}}) == ["checks -> solvers", "costs -> api"]


def test_the_cycle_finder_finds_cycles():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_planning_leaves_the_simulator_unloaded():
    """``import staghunt``, the CLI's parser and the compiled engine do not load the simulator,
    TOPP-RA or Matplotlib (0.7 s and about 70 MB that only ``fly``, ``export`` and the figures
    need; the compile helper imports the engine too); ``staghunt.fly`` loads it on first use."""
    import subprocess
    import sys

    code = ("import sys, staghunt, staghunt.cli, staghunt.engine.numba_engine\n"
            "staghunt.cli.build_parser()\n"
            "loaded = [m for m in ('staghunt.flight', 'rotorpy', 'toppra', 'matplotlib') if m in sys.modules]\n"
            "assert not loaded, loaded\n"
            "assert callable(staghunt.fly) and 'staghunt.flight' in sys.modules\n"
            "from staghunt.missions import export_result, FORMATS\n"
            "assert export_result.__module__ == 'staghunt.missions.export' and len(FORMATS) == 7\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_commands_that_plan_nothing_compile_nothing(tmp_path):
    """``show``, ``schema``, ``methods`` and ``evaluate`` (the NumPy reference's costs) neither
    load the compiled kernels nor write to Numba's cache: a first ``staghunt show`` costs no
    compilation (``export`` and ``plan`` are covered where they run)."""
    import os
    import subprocess
    import sys

    cache = tmp_path / "numba-cache"
    code = (
        "import json, sys, numpy as np, staghunt\n"
        "from staghunt.cli import main\n"
        "s = staghunt.load_scenario('scenario1')\n"
        "t = np.linspace(0.2, 0.8, 4)[:, None]\n"
        "uavs = [{'waypoints': (u.start + t * (np.array(u.goal) - u.start)).tolist()} for u in s.team]\n"
        f"json.dump({{'uavs': uavs}}, open({str(tmp_path / 'paths.json')!r}, 'w'))\n"
        f"codes = [main(a) for a in (['show', 'scenario2'], ['schema'], ['methods'],\n"
        f"                           ['evaluate', 'scenario1', {str(tmp_path / 'paths.json')!r}])]\n"
        "assert codes[:3] == [0, 0, 0] and codes[3] in (0, 3), codes\n"
        "assert 'staghunt.engine.kernels' not in sys.modules\n"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    subprocess.run([sys.executable, "-c", code], check=True, env=env, stdout=subprocess.DEVNULL)
    assert not cache.exists() or not any(cache.rglob("*.nbi"))


def module_graph_within(package: str) -> dict[str, set[str]]:
    """``{module: modules of the same package it imports}`` for the modules of ``staghunt.<package>``,
    top-level and deferred imports alike (relative imports resolved)."""
    graph: dict[str, set[str]] = defaultdict(set)
    base = ROOT / package
    for path in base.rglob("*.py"):
        module = ".".join(("staghunt", package, *path.relative_to(base).with_suffix("").parts)).removesuffix(".__init__")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            prefix = f"staghunt.{package}."
            for name in names:
                if name.startswith(prefix) and (base / Path(*name[len(prefix):].split("."))).with_suffix(".py").exists():
                    if name != module:
                        graph[module].add(name)
    return graph


def test_no_import_cycle_between_the_modules_of_the_flight_room():
    """The flight room's parts import down, never round (flight/aside.py took its solve
    function by name instead of importing the re-planner that imports it)."""
    for package in ("flight", "safety", "trajectory"):
        assert cycles(module_graph_within(package)) == [], package


ENGINE_WORDS = ("engine", "evaluator", "resolved", "runner", "solo", "certifier")
"""Words that name an engine (or a callable of one) in the source."""


def probing(source: str) -> list[str]:
    """Where ``source`` probes an engine instead of using its contract
    (:class:`staghunt.engine.Engine`): any ``__self__`` (a bound method's owner), and any
    ``getattr``/``hasattr`` asking for a capability of the contract (its methods, ``run_swarm``)
    or asking an object whose name says engine (``line: code``, by line)."""
    from staghunt.engine import Engine

    members = {m for m in dir(Engine) if not m.startswith("_")} | {"run_swarm"}
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and node.attr == "__self__":
            found.append(node)
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("getattr", "hasattr")
              and len(node.args) >= 2):
            owner, what = ast.unparse(node.args[0]).lower(), node.args[1]
            asks = isinstance(what, ast.Constant) and what.value in members
            if asks or any(w in owner for w in ENGINE_WORDS):
                found.append(node)
        elif isinstance(node, ast.Constant) and node.value == "__self__":
            found.append(node)
    return [f"{n.lineno}: {ast.unparse(n)}" for n in sorted(found, key=lambda n: (n.lineno, n.col_offset))]


def test_nothing_probes_an_engine_for_its_capabilities():
    """Solvers and callers use the engine's declared contract (``prepare``, ``team_search``,
    ``deviations``, ...; the NumPy reference answers each): no ``__self__`` to recover an engine
    from a bound method, no ``getattr``/``hasattr`` on an engine."""
    found = {str(p.relative_to(ROOT)): hits for p in sorted(ROOT.rglob("*.py"))
             if (hits := probing(p.read_text(encoding="utf-8")))}
    assert found == {}


def test_the_probing_check_finds_probing():
    source = ('engine = getattr(evaluator, "__self__", None)\n'
              'fast = engine.deviations(m) if hasattr(engine, "deviations") else None\n'
              'prepare = getattr(resolved, "prepare", None)\n'
              'threads = getattr(engine, "threads", 1)\n'
              'run = getattr(x, "run_swarm")\n'
              'ok = getattr(args, "threads", 0), getattr(result.status, "value", 1), hasattr(table, "to_pydict")\n')
    assert [h.split(":")[0] for h in probing(source)] == ["1", "1", "2", "3", "4", "5"]
