"""The sweep spec (TOML), declared once with pydantic, and its expansion into tasks.

A spec names scenarios, methods, seeds and a budget, plus a ``[grid]`` of scenario overrides
whose cartesian product multiplies the tasks::

    scenarios = ["scenario1"]            # built-in names or TOML paths (relative to the spec)
    methods = ["game", "rigid"]
    seeds = "1-8"                        # or [1, 2, 5]
    particles = 200                      # the budget of every plan (default: the scenario's)
    iterations = 100
    waypoints = 8

    [certificate]                        # each plan's certificate (defaults: staghunt plan's)
    particles = 100
    iterations = 50
    epsilon = 0.01

    [grid]
    beta = [0.5, 1, 2]                   # every UAV's beta
    weights = [[1, 1, 1, 1, 1]]          # every UAV's [w1..w5]
    waypoints = [6, 10]                  # K
    particles = [100, 200]               # the budget
    iterations = [50, 100]
    uav.2.beta = [0.5, 1]                # UAV 2 only (1-based index, or the UAV's name)
    uav.UAV3.weights = [[1, 2, 1, 1, 1]]

Every key is checked (an unknown key is an error naming it, with the keys allowed there) by
:class:`SweepFile`, whose JSON Schema (:func:`sweep_schema`, ``staghunt schema --sweep``)
editors can use. :func:`expand` then counts the tasks (a spec of more than :data:`MAX_TASKS`
is refused with its count before any scenario is read), loads every scenario, checks every grid
value by the scenario format's rules for the key it sets (a team's ``beta`` or ``weights``, a
``[solver]`` budget: a value's validity does not depend on the other axes', so each value is
checked once, not once per combination) and checks every distinct run (each budget with each
method, :func:`staghunt.api.check_plan`, memory included), all before any work starts: a bad
override is refused naming the scenario and the value. The tasks are then made on demand
(:mod:`staghunt.study.grid`), so a spec of a million tasks is expanded and checked against a
store in seconds (``benchmarks/sweep_scale.py``).
"""

from __future__ import annotations

import itertools
import json
import os
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field

from staghunt.api import check_plan
from staghunt.errors import FieldError
from staghunt.inputs import parse_seeds as read_seeds
from staghunt.inputs import parse_toml, read_text
from staghunt.scenario import builtin_names, builtin_path, load_scenario, scenario_from_dict, scenario_to_dict
from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.validation import plain, validate
from staghunt.solvers.response import DEFAULT_EPSILON, DEFAULT_ITERATIONS, DEFAULT_PARTICLES, CertifyOptions
from staghunt.study.grid import SOLVER_COLUMNS, Axis, ScenarioGrid, Sweep, combinations, task_key

__all__ = ["MAX_TASKS", "SpecError", "Sweep", "SweepFile", "count_tasks", "expand", "load_spec", "parse_seeds",
           "sweep_schema", "task_key"]

MAX_TASKS = 1_000_000
"""The most tasks one spec may make: the size whose expansion and resume check are measured
(``benchmarks/sweep_scale.py``); a larger spec is refused with its count before any scenario
is read."""

NonNegative = Annotated[float, Field(ge=0)]
Weights5 = Annotated[list[NonNegative], Field(min_length=5, max_length=5, description="[w1, w2, w3, w4, w5]")]


class SpecError(ValueError):
    """An invalid sweep spec (one line naming the key path, or the task, at fault)."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class CertificateTable(_Strict):
    """Budget of each UAV's deviation search, and the tolerance of the verdict."""

    particles: Annotated[int, Field(ge=1)] = DEFAULT_PARTICLES
    iterations: Annotated[int, Field(ge=0)] = DEFAULT_ITERATIONS
    epsilon: Annotated[float, Field(ge=0)] = DEFAULT_EPSILON


class UavGrid(_Strict):
    """Overrides of one UAV (``[grid.uav.<index or name>]``)."""

    beta: Optional[Annotated[list[NonNegative], Field(min_length=1)]] = None
    weights: Optional[Annotated[list[Weights5], Field(min_length=1)]] = None


class Grid(_Strict):
    """Scenario overrides; the sweep runs their cartesian product."""

    beta: Optional[Annotated[list[NonNegative], Field(min_length=1, description="every UAV's beta")]] = None
    weights: Optional[Annotated[list[Weights5], Field(min_length=1, description="every UAV's weights")]] = None
    waypoints: Optional[Annotated[list[Annotated[int, Field(ge=1)]], Field(min_length=1, description="K")]] = None
    particles: Optional[Annotated[list[Annotated[int, Field(ge=1)]], Field(min_length=1)]] = None
    iterations: Optional[Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=1)]] = None
    uav: dict[Annotated[str, Field(pattern=r"\S")], UavGrid] = Field(
        default_factory=dict, description="per-UAV overrides, keyed by 1-based index or UAV name")


class SweepFile(_Strict):
    """A staghunt sweep: scenarios x grid x methods x seeds, one plan plus certificate each."""

    model_config = ConfigDict(title="staghunt sweep")

    scenarios: Annotated[list[Annotated[str, Field(pattern=r"\S")]], Field(
        min_length=1, description="built-in names or scenario TOML paths (relative to the spec)")]
    methods: Annotated[list[str], Field(min_length=1, description="planning methods ('staghunt methods')")]
    seeds: str | Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=1)] = Field(
        description="'1-8', '1,4,7', '1-3,8' or an array of integers >= 0")
    particles: Optional[Annotated[int, Field(ge=1)]] = Field(None, description="default: the scenario's")
    iterations: Optional[Annotated[int, Field(ge=0)]] = None
    waypoints: Optional[Annotated[int, Field(ge=1)]] = None
    engine: Literal["numba", "numpy"] = "numba"
    certificate: CertificateTable = Field(default_factory=CertificateTable)
    grid: Grid = Field(default_factory=Grid)


def sweep_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of the sweep spec."""
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **SweepFile.model_json_schema()}


def parse_seeds(text: str) -> tuple[int, ...]:
    """``"1-8"``, ``"3"``, ``"1,4,7"``, ``"1-3,8"`` -> seeds in order, duplicates dropped
    (:func:`staghunt.inputs.parse_seeds`, its error as a :class:`SpecError`)."""
    try:
        return read_seeds(text, limit=MAX_TASKS)
    except FieldError as exc:
        raise SpecError(str(exc)) from None


def load_spec(path: str | os.PathLike[str]) -> tuple[SweepFile, Path]:
    """Read and check the spec at ``path``; returns it and the directory relative paths are
    resolved against. Raises :class:`SpecError` (``PATH: key: detail``)."""
    source = os.fspath(path)
    try:
        data = parse_toml(read_text(source, "sweep spec (TOML)"), source)
        return validate(plain(data), SweepFile), Path(source).parent
    except ScenarioError as exc:
        raise SpecError(f"{source}: {exc}") from None
    except (ValueError, OSError) as exc:
        raise SpecError(" ".join(str(exc).split())) from None




def _axes(grid: Grid) -> list[Axis]:
    """Every grid axis, in a fixed order (the order overrides are applied in: a UAV's own axis
    after the team's); a value listed twice is refused (it would make the same tasks twice)."""
    axes: list[Axis] = []
    if grid.beta is not None:
        axes.append(Axis("beta", "float", tuple(float(v) for v in grid.beta)))
    if grid.weights is not None:
        axes.append(Axis("weights", "weights", tuple(tuple(float(x) for x in w) for w in grid.weights)))
    for uav, g in grid.uav.items():
        if g.beta is not None:
            axes.append(Axis(f"uav.{uav}.beta", "float", tuple(float(v) for v in g.beta)))
        if g.weights is not None:
            axes.append(Axis(f"uav.{uav}.weights", "weights", tuple(tuple(float(x) for x in w) for w in g.weights)))
    for name in SOLVER_COLUMNS:
        values = getattr(grid, name)
        if values is not None:
            axes.append(Axis(name, "int", tuple(int(v) for v in values)))
    for axis in axes:
        if len(set(axis.values)) != len(axis.values):
            twice = next(v for k, v in enumerate(axis.values) if v in axis.values[:k])
            raise SpecError(f"grid.{axis.column}: the value {json.dumps(twice)} is listed twice")
    return [replace(a, values=tuple(list(v) if a.kind == "weights" else v for v in a.values)) for a in axes]


def _uav_index(team: list[dict[str, Any]], ident: str, scenario: str) -> int:
    names = [str(u.get("name")) for u in team]
    if ident in names:
        return names.index(ident)
    if ident.isdigit() and 1 <= int(ident) <= len(team):
        return int(ident) - 1
    raise SpecError(f"grid.uav.{ident}: scenario {scenario!r} has no UAV {ident!r} "
                    f"(give 1 to {len(team)} or a name: {', '.join(names)})")


def _targets(axis: Axis, team: list[dict[str, Any]], scenario: str) -> tuple[int, ...] | None:
    """The UAVs whose value ``axis`` sets (``None``: a budget axis)."""
    if axis.column in SOLVER_COLUMNS:
        return None
    if axis.column.startswith("uav."):
        return (_uav_index(team, axis.column[4:].rsplit(".", 1)[0], scenario),)
    return tuple(range(len(team)))


def _describe(scenario: str, overrides: dict[str, Any]) -> str:
    parts = [f"{k} = {json.dumps(v)}" for k, v in overrides.items()]
    return f"scenario {scenario!r}" + (f" with {', '.join(parts)}" if parts else "")


def _check_value(scenario: str, data: dict[str, Any], axis: Axis, targets: tuple[int, ...] | None,
                 value: Any) -> None:
    """One grid value checked by the scenario format's own rules for the key it sets (the
    team's ``beta`` or ``weights``, or a ``[solver]`` budget), magnitudes included."""
    from staghunt.inputs import check_magnitudes
    from staghunt.scenario.schema import Solver, Uav

    try:
        if targets is None:
            entry = {**data["solver"], axis.column: value}
            check_magnitudes({"solver": entry})
            validate(entry, Solver)
        else:
            field = axis.column.rsplit(".", 1)[-1]
            team = [dict(u, **{field: value}) if i in targets else u for i, u in enumerate(data["team"])]
            check_magnitudes({"team": team})
            for i in targets:
                try:
                    validate(team[i], Uav)
                except ScenarioError as exc:
                    raise ScenarioError(exc.detail, f"team[{i}]" + (f".{exc.key}" if exc.key else "")) from None
    except ValueError as exc:
        raise SpecError(f"{_describe(scenario, {axis.column: value})}: {' '.join(str(exc).split())}") from None


_SPEC_KEYS = {"method": "methods[{}]", "certify": "certificate"}
"""The key of the spec at fault of a run's refusal (:func:`staghunt.api.check_plan`'s field);
other refusals name the task."""


def _requests(base: Any, axes: list[Axis], spec: SweepFile, seed: int,
              cert: CertifyOptions) -> dict[tuple[tuple[int, int, int], str], Any]:
    """The checked run (:func:`staghunt.api.check_plan`, memory included) of every distinct
    budget of the grid and every method, keyed by ``((waypoints, particles, iterations), method)``."""
    budget = [a for a in axes if a.column in SOLVER_COLUMNS]
    out = {}
    for values in itertools.product(*[a.values for a in budget]):
        changes = {a.column: v for a, v in zip(budget, values)}
        settings = base.solver.with_(**changes)
        variant = replace(base, solver=settings)
        for m, method in enumerate(spec.methods):
            try:
                request = check_plan(variant, method, seed, settings, spec.engine, 1, cert)
            except ValueError as exc:
                field = getattr(exc, "field", None)
                where = _SPEC_KEYS.get(field, f"{_describe(base.name, changes)}, method {method!r}").format(m)
                raise SpecError(f"{where}: {' '.join(str(exc).split())}") from None
            out[((settings.waypoints, settings.particles, settings.iterations), method)] = request
    return out


def count_tasks(spec: SweepFile, seeds: tuple[int, ...]) -> int:
    """How many tasks ``spec`` makes (known before any scenario is read)."""
    return len(spec.scenarios) * combinations(_axes(spec.grid)) * len(seeds) * len(spec.methods)


def expand(spec: SweepFile, base_dir: Path | None = None) -> Sweep:
    """Every task of ``spec``, checked before any work: its size against :data:`MAX_TASKS`
    (before any scenario is read), scenarios loaded, every grid value through the scenario's
    validation, every distinct run checked (:func:`staghunt.api.check_plan`, memory included).
    The tasks themselves are made on demand (:class:`~staghunt.study.grid.Sweep`). Raises
    :class:`SpecError` naming the scenario, override or method at fault."""
    base_dir = base_dir if base_dir is not None else Path(".")
    if len(set(spec.methods)) != len(spec.methods):
        raise SpecError("methods: a method is listed twice")
    seeds = parse_seeds(spec.seeds) if isinstance(spec.seeds, str) else tuple(dict.fromkeys(spec.seeds))
    axes = _axes(spec.grid)
    total = len(spec.scenarios) * combinations(axes) * len(seeds) * len(spec.methods)
    if total > MAX_TASKS:
        raise SpecError(
            f"the spec makes {total:,} tasks ({len(spec.scenarios)} scenario{'s' * (len(spec.scenarios) != 1)} x "
            f"{combinations(axes):,} grid combinations x {len(seeds):,} seeds x {len(spec.methods)} "
            f"method{'s' * (len(spec.methods) != 1)}); a sweep runs at most {MAX_TASKS:,}: split it into "
            "several specs (e.g. by seeds), each with its own --out")
    # The certificate's table and every method are checked with each run (check_plan, below).
    cert = CertifyOptions(spec.certificate.particles, spec.certificate.iterations, float(spec.certificate.epsilon))
    top = {k: getattr(spec, k) for k in SOLVER_COLUMNS if getattr(spec, k) is not None}
    grids: list[ScenarioGrid] = []
    seen_sources: set[str] = set()
    for i, source in enumerate(spec.scenarios):
        if source in seen_sources:
            raise SpecError(f"scenarios[{i}]: {source!r} is listed twice")
        seen_sources.add(source)
        if source in builtin_names():
            where, anchor = source, builtin_path(source).parent
        else:
            path = Path(source) if Path(source).is_absolute() else base_dir / source
            where, anchor = str(path), path.parent
        try:
            scenario = load_scenario(where)
        except ValueError as exc:
            raise SpecError(f"scenarios[{i}]: {' '.join(str(exc).split())}") from None
        data = scenario_to_dict(scenario)
        data["solver"] = {**data.get("solver", {}), **top}
        try:
            base = scenario_from_dict(data, name=scenario.name, base_dir=anchor) if top else scenario
        except ScenarioError as exc:
            raise SpecError(f"{_describe(scenario.name, {})}: {exc}") from None
        base_data = json.loads(json.dumps(scenario_to_dict(base), allow_nan=False, default=str))
        targets = [_targets(axis, base_data["team"], scenario.name) for axis in axes]
        for axis, uavs in zip(axes, targets):
            for value in axis.values:
                _check_value(scenario.name, base_data, axis, uavs, value)
        requests = _requests(base, axes, spec, seeds[0], cert)
        grid = ScenarioGrid(base, base_data, axes, targets, requests, spec.methods, cert, spec.engine)
        idle = grid.idle_axes()
        if idle:
            raise SpecError(f"grid.{idle[0]}: changes nothing in scenario {scenario.name!r} (every value it "
                            "sets is set again by a UAV's own grid key)")
        grids.append(grid)
    kinds = tuple((a.column, a.kind) for a in axes if a.kind != "int")
    return Sweep(spec, tuple(grids), kinds, seeds, tuple(spec.methods), cert)
