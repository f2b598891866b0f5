"""The tasks of an expanded sweep, made on demand: nothing per task is held in memory.

A sweep of ``scenarios x grid x seeds x methods`` has one :class:`ScenarioGrid` per scenario:
its checked base scenario, the grid's axes (each value with its JSON text), the checked run of
every distinct budget and method, and a *key template*. Task ``i`` (order: scenario, grid
combination, seed, method) is decoded from its index; :meth:`Sweep.task` builds its
:class:`~staghunt.study.tasks.PlanTask` (the scenario with the combination's overrides, the
checked run with its seed) only when it is submitted, and :meth:`Sweep.keys` streams every
task's key without building any task.

A key is :func:`task_key` of the task's configuration: sha256 of its JSON. Most of that text is
the same for every task of a scenario (the scenario's obstacles, terrain, formation...), so the
template holds it once, split at the *holes* where the overridden values, the method and the
seed go: a combination's text is the template's pieces joined with its values' texts, hashed
once per method; each seed then costs one copy of that hash state and the short text after
the seed (about 1 microsecond). The keys are byte for byte those of :func:`task_key`
(each grid checks its first key against it).
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
import math
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, overload

import numpy as np

from staghunt._version import __version__
from staghunt.solvers.response import CertifyOptions
from staghunt.study.tasks import PlanTask
from staghunt.task import UAV, Weights

if TYPE_CHECKING:
    from staghunt.api import PlanRequest
    from staghunt.scenario.model import Scenario

SOLVER_COLUMNS = ("waypoints", "particles", "iterations")
"""The grid's budget axes (the ``[solver]`` keys they override)."""

_JSON = {"sort_keys": True, "allow_nan": False, "separators": (",", ":"), "default": str}


def _dumps(value: Any) -> str:
    return json.dumps(value, **_JSON)  # type: ignore[arg-type]


def task_key(scenario_data: dict[str, Any], method: str, seed: int, settings: dict[str, Any],
             certify: CertifyOptions, engine: str) -> str:
    """sha256 (hex) of a task's full configuration: the scenario after overrides (plain data),
    method, seed, solver settings, certificate budget, engine and package version."""
    return hashlib.sha256(_dumps(_key_doc(scenario_data, method, seed, settings, certify, engine))
                          .encode("utf-8")).hexdigest()


def _key_doc(scenario_data: Any, method: Any, seed: Any, settings: Any, certify: CertifyOptions,
             engine: str) -> dict[str, Any]:
    return {"scenario": scenario_data, "method": method, "seed": seed if not isinstance(seed, int) else int(seed),
            "settings": settings, "certify": {"particles": certify.particles, "iterations": certify.iterations,
                                              "epsilon": certify.epsilon}, "engine": engine, "version": __version__}


@dataclass(frozen=True)
class Axis:
    """One grid axis: its result column, kind (``float``, ``int``, ``weights``), values and
    each value's JSON text (as it appears in a task's key)."""

    column: str
    kind: str
    values: tuple[Any, ...]

    @functools.cached_property
    def texts(self) -> tuple[str, ...]:
        return tuple(_dumps(v) for v in self.values)


def combinations(axes: Sequence[Axis]) -> int:
    """How many combinations of values the axes make (1 without axes)."""
    return math.prod(len(a.values) for a in axes)


class ScenarioGrid:
    """One scenario of a sweep and its grid. ``base``: the checked scenario with the spec's
    top-level budget; ``targets[a]``: the UAV indices axis ``a`` overrides (``None``: a budget
    axis); ``requests[(budget, method)]``: the checked run of each distinct budget
    ``(waypoints, particles, iterations)``."""

    def __init__(self, base: "Scenario", base_data: dict[str, Any], axes: Sequence[Axis],
                 targets: Sequence[tuple[int, ...] | None], requests: dict[tuple[tuple[int, int, int], str], "PlanRequest"],
                 methods: Sequence[str], certify: CertifyOptions, engine: str) -> None:
        from staghunt.io.result_json import settings_to_dict

        self.base, self.axes, self.targets, self.requests = base, tuple(axes), tuple(targets), requests
        self.methods, self.engine = tuple(methods), engine
        self.size = combinations(self.axes)
        self._radix = tuple(len(a.values) for a in self.axes)
        # Which axis sets each UAV's beta and weights (the last one applied wins, as in _apply).
        self._owner: dict[tuple[int, str], int] = {}
        for a, (axis, uavs) in enumerate(zip(self.axes, self.targets)):
            for i in uavs or ():
                self._owner[(i, axis.column.rsplit(".", 1)[-1])] = a
        self._budget_axes = {axis.column: a for a, axis in enumerate(self.axes) if axis.column in SOLVER_COLUMNS}
        self._texts = [a.texts for a in self.axes]
        self._last: tuple[tuple[int, ...], "Scenario"] | None = None
        self._template(base_data, settings_to_dict(base.solver), certify)
        reference = task_key(self.scenario_data((0,) * len(self.axes)), self.methods[0], 0,
                             settings_to_dict(self.variant((0,) * len(self.axes)).solver), certify, engine)
        if self.key((0,) * len(self.axes), self.methods[0], 0) != reference:  # a bug, never the user's input
            raise RuntimeError(f"sweep keys of scenario {base.name!r} differ from task_key()")

    def idle_axes(self) -> list[str]:
        """Columns of the axes that set nothing (every value they set is set again by a later
        axis): their values would make the same tasks twice."""
        used = set(self._owner.values()) | set(self._budget_axes.values())
        return [a.column for k, a in enumerate(self.axes) if k not in used]

    # -- the key template ------------------------------------------------------------------

    def _template(self, base_data: dict[str, Any], settings: dict[str, Any], certify: CertifyOptions) -> None:
        plain = _dumps(_key_doc(base_data, "", 0, settings, certify, self.engine))
        nonce = next(f"h{n}" for n in itertools.count() if f"\\u0000h{n}:" not in plain)
        def hole(name: str) -> str:
            return f"\x00{nonce}:{name}\x00"

        scenario = json.loads(json.dumps(base_data))
        for (i, field), a in self._owner.items():
            scenario["team"][i][field] = hole(str(a))
        settings = dict(settings)
        for column, a in self._budget_axes.items():
            scenario.setdefault("solver", {})[column] = hole(str(a))
            settings[column] = hole(str(a))
        text = _dumps(_key_doc(scenario, hole("m"), hole("s"), settings, certify, self.engine))
        parts = re.split(r'"\\u0000' + nonce + r':(\w+)\\u0000"', text)
        segments, holes = parts[0::2], parts[1::2]
        if holes.count("m") != 1 or holes.count("s") != 1 or holes.index("m") > holes.index("s"):
            raise RuntimeError("sweep key template: the method and the seed must appear once, in that order")
        m, s = holes.index("m"), holes.index("s")
        if m != 0:
            raise RuntimeError("sweep key template: a value hole before the method")
        head = hashlib.sha256(segments[0].encode("utf-8"))
        self._heads = {}
        for method in self.methods:
            h = head.copy()
            h.update(_dumps(method).encode("utf-8"))
            self._heads[method] = h
        # segments[k] comes before holes[k]: the scenario's holes lie between the method and the
        # seed, the settings' after the seed.
        self._mid = ([segments[k] for k in range(m + 1, s)], [int(holes[k]) for k in range(m + 1, s)], segments[s])
        self._tail = ([segments[k] for k in range(s + 1, len(holes))], [int(holes[k]) for k in range(s + 1, len(holes))],
                      segments[len(holes)])

    def _join(self, part: tuple[list[str], list[int], str], idx: tuple[int, ...]) -> bytes:
        segments, axes, end = part
        texts = self._texts
        return ("".join([seg + texts[a][idx[a]] for seg, a in zip(segments, axes)]) + end).encode("utf-8")

    def combo_hashes(self, idx: tuple[int, ...]) -> tuple[dict[str, Any], bytes]:
        """``({method: sha256 state up to the seed}, the text after the seed)`` of combination ``idx``."""
        mid = self._join(self._mid, idx)
        states = {}
        for method, head in self._heads.items():
            h = head.copy()
            h.update(mid)
            states[method] = h
        return states, self._join(self._tail, idx)

    def key(self, idx: tuple[int, ...], method: str, seed: int) -> str:
        """The key of combination ``idx``, ``method``, ``seed``."""
        states, tail = self.combo_hashes(idx)
        h = states[method].copy()
        h.update(b"%d" % seed + tail)
        return h.hexdigest()

    # -- combinations ----------------------------------------------------------------------

    def combo(self, c: int) -> tuple[int, ...]:
        """The value indices (one per axis) of combination ``c`` (the last axis varies fastest)."""
        out = []
        for n in reversed(self._radix):
            c, r = divmod(c, n)
            out.append(r)
        return tuple(reversed(out))

    def combos(self) -> Iterator[tuple[int, ...]]:
        return itertools.product(*[range(n) for n in self._radix])

    def overrides(self, idx: tuple[int, ...]) -> dict[str, Any]:
        """``{column: value}`` of combination ``idx``."""
        return {a.column: a.values[i] for a, i in zip(self.axes, idx)}

    def budget(self, idx: tuple[int, ...]) -> tuple[int, int, int]:
        """``(waypoints, particles, iterations)`` of combination ``idx``."""
        s = self.base.solver
        values = {"waypoints": s.waypoints, "particles": s.particles, "iterations": s.iterations}
        for column, a in self._budget_axes.items():
            values[column] = self.axes[a].values[idx[a]]
        return values["waypoints"], values["particles"], values["iterations"]

    def scenario_data(self, idx: tuple[int, ...]) -> dict[str, Any]:
        """The base scenario's plain data with combination ``idx`` applied (what :func:`task_key` hashes)."""
        from staghunt.scenario import scenario_to_dict

        data = json.loads(json.dumps(scenario_to_dict(self.base), allow_nan=False, default=str))
        for (i, field), a in self._owner.items():
            data["team"][i][field] = self.axes[a].values[idx[a]]
        for column, a in self._budget_axes.items():
            data["solver"][column] = self.axes[a].values[idx[a]]
        return data

    def variant(self, idx: tuple[int, ...]) -> "Scenario":
        """The base scenario with combination ``idx`` applied (every value was checked by
        :func:`staghunt.study.spec.expand`, so nothing is validated again); the last one is
        kept (consecutive tasks share their combination)."""
        if self._last is not None and self._last[0] == idx:
            return self._last[1]
        team = []
        for i, u in enumerate(self.base.team):
            w = u.weights
            beta, ws = w.beta, (w.w1, w.w2, w.w3, w.w4, w.w5)
            if (i, "beta") in self._owner:
                a = self._owner[(i, "beta")]
                beta = float(self.axes[a].values[idx[a]])
            if (i, "weights") in self._owner:
                a = self._owner[(i, "weights")]
                ws = tuple(float(v) for v in self.axes[a].values[idx[a]])
            team.append(u if (beta, ws) == (w.beta, (w.w1, w.w2, w.w3, w.w4, w.w5))
                        else UAV(u.name, u.start, u.goal, u.radius, Weights(beta, *ws)))
        k, p, n = self.budget(idx)
        scenario = replace(self.base, team=tuple(team),
                           solver=self.base.solver.with_(waypoints=k, particles=p, iterations=n))
        self._last = (idx, scenario)
        return scenario


@dataclass(frozen=True, eq=False)
class Sweep:
    """An expanded, checked spec (:func:`staghunt.study.spec.expand`): ``len(sweep)`` tasks in a
    stable order (scenario, grid combination, seed, method), made on demand (:meth:`task`,
    :attr:`tasks`); ``overrides``: the override columns as ``(name, kind)`` with ``kind`` one of
    ``"float"``, ``"weights"`` (the budget columns are always there)."""

    spec: Any
    grids: tuple[ScenarioGrid, ...]
    overrides: tuple[tuple[str, str], ...]
    seeds: tuple[int, ...]
    methods: tuple[str, ...]
    certify: CertifyOptions

    def __len__(self) -> int:
        return sum(g.size for g in self.grids) * len(self.seeds) * len(self.methods)

    @property
    def tasks(self) -> "TaskList":
        """Every task, as a lazy sequence."""
        return TaskList(self, range(len(self)))

    def locate(self, i: int) -> tuple[ScenarioGrid, tuple[int, ...], int, str]:
        """(grid, combination, seed, method) of task ``i``."""
        if not 0 <= i < len(self):
            raise IndexError(f"task {i} of {len(self)}")
        per_combo = len(self.seeds) * len(self.methods)
        for grid in self.grids:
            if i < grid.size * per_combo:
                c, rest = divmod(i, per_combo)
                s, m = divmod(rest, len(self.methods))
                return grid, grid.combo(c), self.seeds[s], self.methods[m]
            i -= grid.size * per_combo
        raise AssertionError("unreachable")

    def task(self, i: int) -> PlanTask:
        """Task ``i``: its checked run (the scenario with the combination's overrides), key and labels."""
        grid, idx, seed, method = self.locate(i)
        scenario = grid.variant(idx)
        request = replace(grid.requests[(grid.budget(idx), method)], scenario=scenario, seed=seed)
        s = scenario.solver
        labels = {"scenario": scenario.name, "method": method, "seed": seed, **grid.overrides(idx),
                  "particles": s.particles, "iterations": s.iterations, "waypoints": s.waypoints,
                  "engine": self.spec.engine}
        return PlanTask(request, grid.key(idx, method, seed), labels)

    def keys(self) -> Iterator[str]:
        """Every task's key, in the tasks' order, without making any task."""
        seeds = [b"%d" % s for s in self.seeds]
        for grid in self.grids:
            for idx in grid.combos():
                states, tail = grid.combo_hashes(idx)
                hashes = [states[m] for m in self.methods]
                for seed in seeds:
                    text = seed + tail
                    for state in hashes:
                        h = state.copy()
                        h.update(text)
                        yield h.hexdigest()


class TaskList(Sequence[PlanTask]):
    """Some tasks of a sweep (``indices`` into it, in order), each made when read; slicing
    gives another :class:`TaskList`."""

    def __init__(self, sweep: Sweep, indices: "range | np.ndarray") -> None:
        self.sweep, self.indices = sweep, indices

    def __len__(self) -> int:
        return len(self.indices)

    @overload
    def __getitem__(self, i: int) -> PlanTask: ...

    @overload
    def __getitem__(self, i: slice) -> "TaskList": ...

    def __getitem__(self, i: int | slice) -> "PlanTask | TaskList":
        if isinstance(i, slice):
            return TaskList(self.sweep, self.indices[i])
        return self.sweep.task(int(self.indices[i]))

    def __iter__(self) -> Iterator[PlanTask]:
        for i in self.indices:
            yield self.sweep.task(int(i))
