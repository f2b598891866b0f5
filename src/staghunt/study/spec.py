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
editors can use. :func:`expand` then loads every scenario, applies every combination of
overrides through the scenario's own validation (:func:`staghunt.scenario.scenario_from_dict`)
and checks every run (:func:`staghunt.api.check_plan`), all before any work starts: a bad
override is refused with the task it makes named.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field

from staghunt._version import __version__
from staghunt.api import check_plan
from staghunt.errors import FieldError
from staghunt.inputs import parse_seeds as read_seeds
from staghunt.inputs import parse_toml, read_text
from staghunt.io.result_json import settings_to_dict
from staghunt.scenario import builtin_names, builtin_path, load_scenario, scenario_from_dict, scenario_to_dict
from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.validation import plain, validate
from staghunt.solvers.response import DEFAULT_EPSILON, DEFAULT_ITERATIONS, DEFAULT_PARTICLES, CertifyOptions
from staghunt.study.tasks import PlanTask

__all__ = ["SpecError", "Sweep", "SweepFile", "expand", "load_spec", "parse_seeds", "sweep_schema", "task_key"]

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
        return read_seeds(text)
    except FieldError as exc:
        raise SpecError(str(exc)) from None


@dataclass(frozen=True, eq=False)
class Sweep:
    """An expanded, checked spec: ``tasks`` in a stable order (scenario, overrides, seed,
    method), ``overrides``: the override columns as ``(name, kind)`` with ``kind`` one of
    ``"float"``, ``"int"``, ``"weights"``."""

    spec: SweepFile
    tasks: tuple[PlanTask, ...]
    overrides: tuple[tuple[str, str], ...]
    seeds: tuple[int, ...]
    certify: CertifyOptions


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


def task_key(scenario_data: dict[str, Any], method: str, seed: int, settings: dict[str, Any],
             certify: CertifyOptions, engine: str) -> str:
    """sha256 (hex) of a task's full configuration: the scenario after overrides (plain data),
    method, seed, solver settings, certificate budget, engine and package version."""
    doc = {"scenario": scenario_data, "method": method, "seed": int(seed), "settings": settings,
           "certify": {"particles": certify.particles, "iterations": certify.iterations,
                       "epsilon": certify.epsilon}, "engine": engine, "version": __version__}
    text = json.dumps(doc, sort_keys=True, allow_nan=False, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _axes(grid: Grid) -> list[tuple[str, str, list[Any]]]:
    """``(column, kind, values)`` of every grid axis, in a fixed order."""
    axes: list[tuple[str, str, list[Any]]] = []
    if grid.beta is not None:
        axes.append(("beta", "float", [float(v) for v in grid.beta]))
    if grid.weights is not None:
        axes.append(("weights", "weights", [[float(x) for x in w] for w in grid.weights]))
    for uav, g in grid.uav.items():
        if g.beta is not None:
            axes.append((f"uav.{uav}.beta", "float", [float(v) for v in g.beta]))
        if g.weights is not None:
            axes.append((f"uav.{uav}.weights", "weights", [[float(x) for x in w] for w in g.weights]))
    for name in ("waypoints", "particles", "iterations"):
        values = getattr(grid, name)
        if values is not None:
            axes.append((name, "int", [int(v) for v in values]))
    return axes


def _uav_index(team: list[dict[str, Any]], ident: str, scenario: str) -> int:
    names = [str(u.get("name")) for u in team]
    if ident in names:
        return names.index(ident)
    if ident.isdigit() and 1 <= int(ident) <= len(team):
        return int(ident) - 1
    raise SpecError(f"grid.uav.{ident}: scenario {scenario!r} has no UAV {ident!r} "
                    f"(give 1 to {len(team)} or a name: {', '.join(names)})")


def _apply(data: dict[str, Any], overrides: dict[str, Any], scenario: str) -> dict[str, Any]:
    out = copy.deepcopy(data)
    team = out["team"]
    for column, value in overrides.items():
        if column in ("beta", "weights"):
            for u in team:
                u[column] = copy.deepcopy(value)
        elif column.startswith("uav."):
            ident, what = column[4:].rsplit(".", 1)
            team[_uav_index(team, ident, scenario)][what] = copy.deepcopy(value)
        else:
            out.setdefault("solver", {})[column] = value
    return out


def _describe(scenario: str, overrides: dict[str, Any]) -> str:
    parts = [f"{k} = {json.dumps(v)}" for k, v in overrides.items()]
    return f"scenario {scenario!r}" + (f" with {', '.join(parts)}" if parts else "")


_SPEC_KEYS = {"method": "methods[{}]", "certify": "certificate"}
"""The key of the spec at fault of a run's refusal (:func:`staghunt.api.check_plan`'s field);
other refusals name the task."""


def expand(spec: SweepFile, base_dir: Path | None = None) -> Sweep:
    """Every task of ``spec``, checked: scenarios loaded, overrides applied through the
    scenario's validation, every run checked (:func:`staghunt.api.check_plan`, memory included).
    Raises :class:`SpecError` naming the scenario, override or method at fault."""
    base_dir = base_dir if base_dir is not None else Path(".")
    if len(set(spec.methods)) != len(spec.methods):
        raise SpecError("methods: a method is listed twice")
    seeds = parse_seeds(spec.seeds) if isinstance(spec.seeds, str) else tuple(dict.fromkeys(spec.seeds))
    # The certificate's table and every method are checked with each run (check_plan, below).
    cert = CertifyOptions(spec.certificate.particles, spec.certificate.iterations, float(spec.certificate.epsilon))
    axes = _axes(spec.grid)
    top = {k: getattr(spec, k) for k in ("particles", "iterations", "waypoints") if getattr(spec, k) is not None}
    tasks: list[PlanTask] = []
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
        base = scenario_to_dict(scenario)
        base["solver"] = {**base.get("solver", {}), **top}
        for combo in itertools.product(*[values for _, _, values in axes]):
            overrides = {column: value for (column, _, _), value in zip(axes, combo)}
            what = _describe(scenario.name, overrides)
            data = _apply(base, overrides, scenario.name)
            try:
                variant = scenario_from_dict(data, name=scenario.name, base_dir=anchor)
            except ScenarioError as exc:
                raise SpecError(f"{what}: {exc}") from None
            variant_data = json.loads(json.dumps(scenario_to_dict(variant), allow_nan=False, default=str))
            settings = variant.solver
            settings_data = settings_to_dict(settings)
            requests = {}
            for m, method in enumerate(spec.methods):
                try:
                    requests[method] = check_plan(variant, method, seeds[0], settings, spec.engine, 1, cert)
                except ValueError as exc:
                    field = getattr(exc, "field", None)
                    where = _SPEC_KEYS.get(field, f"{what}, method {method!r}").format(m)
                    raise SpecError(f"{where}: {' '.join(str(exc).split())}") from None
            for seed in seeds:  # seed-major: the first results already span the methods
                for method in spec.methods:
                    key = task_key(variant_data, method, seed, settings_data, cert, spec.engine)
                    labels = {"scenario": scenario.name, "method": method, "seed": int(seed), **overrides,
                              "particles": settings.particles, "iterations": settings.iterations,
                              "waypoints": settings.waypoints, "engine": spec.engine}
                    tasks.append(PlanTask(requests[method].with_seed(seed), key, labels))
    kinds = tuple((column, kind) for column, kind, _ in axes if kind != "int")
    return Sweep(spec, tuple(tasks), kinds, seeds, cert)
