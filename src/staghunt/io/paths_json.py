"""``PATHS.json``: hand-made (or foreign) team paths for ``staghunt evaluate``.

Format (strict JSON; ``h`` is the height above ground, metres)::

    {"uavs": [
        {"name": "UAV1", "waypoints": [[x, y, h], ...]},      # the K free waypoints, or
        {"name": "UAV2", "path": [[x, y, h], ...]},           # start, K free waypoints, goal
        ...
    ]}

- One entry per UAV of the scenario, in the scenario's team order; ``name`` is optional and, when
  given, must be that UAV's name.
- Each entry gives exactly one of ``waypoints`` (the ``K`` free waypoints) or ``path`` (``K + 2``
  points whose first and last must equal the UAV's start and goal within ``1e-6`` m).
- Every UAV must have the same ``K >= 1``; all numbers must be finite and of magnitude at most
  :data:`staghunt.inputs.MAX_MAGNITUDE`.

A plan's own ``result.json`` (format ``staghunt-result/1``) is accepted as well: its
``uavs[n].path`` x, y and ``uavs[n].heights`` (without start and goal) are the waypoints.

A waypoint outside the site box makes the paths infeasible (the violation names it).

:func:`read_paths` raises ``ValueError`` with one line naming the offending entry.
:func:`evaluate_paths` costs and checks the paths with the same code as the planner.
"""

from __future__ import annotations

import math
import numbers
import os
from typing import Any

import numpy as np

from staghunt.budget import check_memory, estimate_evaluate
from staghunt.checks import outside_site, violations
from staghunt.costs import CostModel, evaluate
from staghunt.io.result_json import (
    INFINITY_NOTE,
    encode_number,
    load_json_strict,
    terms_dict,
    weighted_terms,
)
from staghunt.inputs import MAX_MAGNITUDE, check_waypoints, show
from staghunt.scenario.model import Scenario

TOP_KEYS = ("uavs",)
UAV_KEYS = ("name", "waypoints", "path")
END_TOLERANCE = 1e-6


def _points(value: Any, where: str) -> np.ndarray:
    """A JSON list of ``[x, y, h]`` triples of finite numbers -> ``(L, 3)`` array."""
    if not isinstance(value, list):
        raise ValueError(f"{where}: expected a list of [x, y, h] points, got {type(value).__name__}")
    out = np.empty((len(value), 3))
    for i, p in enumerate(value):
        if not isinstance(p, list) or len(p) != 3:
            raise ValueError(f"{where}[{i}]: expected a point [x, y, h] of 3 numbers, got {show(p)}")
        for j, v in enumerate(p):
            if isinstance(v, bool) or not isinstance(v, numbers.Real):
                raise ValueError(f"{where}[{i}][{j}]: expected a number, got {show(v)}")
            if isinstance(v, int) and abs(v) > MAX_MAGNITUDE:
                raise ValueError(f"{where}[{i}][{j}]: an integer beyond the supported magnitude "
                                 f"{MAX_MAGNITUDE:.0e}")
            if not math.isfinite(float(v)):
                raise ValueError(f"{where}[{i}][{j}]: must be a finite number, got {v!r}")
            if abs(float(v)) > MAX_MAGNITUDE:
                raise ValueError(f"{where}[{i}][{j}]: {float(v):.3g} is beyond the supported "
                                 f"magnitude {MAX_MAGNITUDE:.0e} (far outside any site)")
            out[i, j] = float(v)
    return out


def paths_from_data(data: Any, scenario: Scenario, source: str = "PATHS.json") -> np.ndarray:
    """Validate parsed PATHS data against ``scenario``; return free waypoints ``(N, K, 3)`` ``(x, y, h)``."""
    if isinstance(data, dict) and "format" in data:
        return paths_from_result(data, scenario, source)
    if not isinstance(data, dict):
        raise ValueError(f"{source}: expected a JSON object {{\"uavs\": [...]}}, got {type(data).__name__}")
    for key in data:
        if key not in TOP_KEYS:
            raise ValueError(f"{source}: unknown key {show(key)}; allowed keys: {', '.join(TOP_KEYS)} "
                             "(or give a result.json written by 'staghunt plan')")
    if "uavs" not in data:
        raise ValueError(f"{source}: required key 'uavs' is missing")
    entries = data["uavs"]
    if not isinstance(entries, list):
        raise ValueError(f"{source}: uavs: expected a list, got {type(entries).__name__}")
    team = scenario.team
    if len(entries) != len(team):
        raise ValueError(
            f"{source}: uavs: scenario {scenario.name!r} has {len(team)} UAVs "
            f"({', '.join(u.name for u in team)}), the file gives {len(entries)}"
        )
    starts, goals = scenario.starts(), scenario.goals()
    result = []
    for n, (entry, uav) in enumerate(zip(entries, team)):
        where = f"{source}: uavs[{n}]"
        if not isinstance(entry, dict):
            raise ValueError(f"{where}: expected an object, got {type(entry).__name__}")
        for key in entry:
            if key not in UAV_KEYS:
                raise ValueError(f"{where}: unknown key {show(key)}; allowed keys: {', '.join(UAV_KEYS)}")
        name = entry.get("name")
        if name is not None and name != uav.name:
            raise ValueError(
                f"{where}.name: {show(name)} is not UAV {n + 1} of the scenario ({uav.name!r}); "
                f"list the UAVs in the scenario's order: {', '.join(u.name for u in team)}"
            )
        has_wp, has_path = "waypoints" in entry, "path" in entry
        if has_wp == has_path:
            raise ValueError(f"{where}: give exactly one of 'waypoints' (free waypoints) or 'path' (start to goal)")
        if has_wp:
            pts = _points(entry["waypoints"], f"{where}.waypoints")
            if len(pts) < 1:
                raise ValueError(f"{where}.waypoints: needs at least 1 free waypoint")
        else:
            full = _points(entry["path"], f"{where}.path")
            if len(full) < 3:
                raise ValueError(
                    f"{where}.path: needs start, at least 1 free waypoint and goal (>= 3 points), got {len(full)}"
                )
            for label, got, want in (("first", full[0], starts[n]), ("last", full[-1], goals[n])):
                if np.max(np.abs(got - want)) > END_TOLERANCE:
                    end = "start" if label == "first" else "goal"
                    raise ValueError(
                        f"{where}.path: {label} point {got.tolist()} is not {uav.name}'s {end} "
                        f"{want.tolist()} (tolerance {END_TOLERANCE:g} m)"
                    )
            pts = full[1:-1]
        if result and len(pts) != len(result[0]):
            raise ValueError(
                f"{where}: has {len(pts)} free waypoints but uavs[0] has {len(result[0])}; "
                f"every UAV needs the same number"
            )
        result.append(pts)
    return np.stack(result) if result else np.zeros((0, 0, 3))


def paths_from_result(data: dict[str, Any], scenario: Scenario, source: str = "result.json") -> np.ndarray:
    """The free waypoints ``(N, K, 3)`` ``(x, y, h)`` of a plan's ``result.json`` data (checked
    with :func:`staghunt.io.result_json.check_result_data`), converted to PATHS form (``path``
    x, y with ``heights``) and validated against ``scenario`` like any PATHS.json."""
    from staghunt.io.result_json import check_result_data

    check_result_data(data, source)
    entries = []
    for u in data["uavs"]:
        pts = [[p[0], p[1], h] for p, h in zip(u["path"], u["heights"])]
        entry: dict[str, Any] = {"path": pts}
        if isinstance(u.get("name"), str):
            entry["name"] = u["name"]
        entries.append(entry)
    return paths_from_data({"uavs": entries}, scenario, source)


def read_paths(path: str | os.PathLike[str], scenario: Scenario) -> np.ndarray:
    """Read and validate a ``PATHS.json`` for ``scenario``; free waypoints ``(N, K, 3)`` ``(x, y, h)``."""
    return paths_from_data(load_json_strict(path), scenario, source=os.fspath(path))


def evaluate_paths(scenario: Scenario, waypoints: np.ndarray) -> dict[str, Any]:
    """Cost and check free waypoints ``(N, K, 3)`` ``(x, y, h)`` of ``scenario``'s team.

    Returns strict-JSON-able data (infinity as ``"inf"``): ``status`` (``"feasible"`` /
    ``"infeasible"``), ``violations`` (plain-language list), and per UAV ``total`` (``J_n``),
    ``single`` (``J_s``), ``formation`` (``J_f``), the five ``terms`` unweighted and
    ``weighted_terms`` (``w_i * term_i``, ``0 * inf = 0``).
    """
    wp = check_waypoints(waypoints, scenario.n_uavs)
    check_memory(estimate_evaluate(scenario.n_uavs, len(scenario.world.cylinders), wp.shape[1]),
                 shrink="fewer waypoints")
    model = CostModel.from_scenario(scenario)
    names = [u.name for u in scenario.team]
    with np.errstate(all="ignore"):  # extreme (validated) inputs give inf costs, not warnings
        costs = evaluate(model, wp[None])
        broken = outside_site(model, wp, names) + violations(model, wp, names)
    uavs = []
    for i, name in enumerate(names):
        w = f"uavs[{i}]"
        terms = costs.terms[0, i]
        uavs.append(
            {
                "name": name,
                "total": encode_number(costs.total[0, i], f"{w}.total"),
                "single": encode_number(costs.single[0, i], f"{w}.single"),
                "formation": encode_number(costs.formation[0, i], f"{w}.formation"),
                "terms": terms_dict(terms, f"{w}.terms"),
                "weighted_terms": terms_dict(
                    weighted_terms(scenario.team[i].weights.as_array(), terms), f"{w}.weighted_terms"
                ),
            }
        )
    return {
        "scenario": scenario.name,
        "notes": {"infinity": INFINITY_NOTE},
        "waypoints_per_uav": int(wp.shape[1]),
        "status": "infeasible" if broken else "feasible",
        "violations": list(broken),
        "uavs": uavs,
    }
