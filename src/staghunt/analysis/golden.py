"""Golden results: small seeded plans stored in ``tests/golden/<method>.json``.

A golden record holds, for one method on :data:`SCENARIO` with a tiny budget
(:data:`PARTICLES` particles, :data:`ITERATIONS` iterations, seed :data:`SEED`, the NumPy
reference engine), the final free waypoints and each UAV's ``J_n`` at full precision. The test
suite re-plans and compares within :data:`TOLERANCE`, so a refactor that changes results cannot
go unnoticed; the files change only when regenerated on purpose
(``python tests/test_golden.py --update``).

The scenario is the paper's own model: the built-in scenario with ``costs.min_clearance = 0``
(the paper forbids only touching an obstacle; the built-in file adds a 1 m margin), so the
records keep reproducing the paper's cost whatever safety margin the built-in file carries.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

FORMAT = "staghunt-golden/1"
SCENARIO = "scenario2"
SEED = 7
PARTICLES = 12
ITERATIONS = 4
TOLERANCE = 1e-12
"""Relative (and absolute, for values near 0) tolerance of the comparison."""


def _enc(v: float) -> float | str:
    v = float(v)
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return v


def _dec(v: Any) -> float:
    return math.inf if v == "inf" else (-math.inf if v == "-inf" else float(v))


def golden_record(method: str, **settings_changes: Any) -> dict[str, Any]:
    """Plan :data:`SCENARIO` with ``method`` at the golden budget (``settings_changes``: other
    solver settings, e.g. ``starts=1``); the record to store or compare."""
    from staghunt.api import plan
    from staghunt.scenario import load_scenario

    scenario = load_scenario(SCENARIO)
    scenario = replace(scenario, costs=replace(scenario.costs, min_clearance=0.0))
    settings = scenario.solver.with_(particles=PARTICLES, iterations=ITERATIONS, **settings_changes)
    result = plan(scenario, method, SEED, settings, engine="numpy")
    return {
        "format": FORMAT,
        "method": method,
        "scenario": SCENARIO,
        "seed": SEED,
        "particles": PARTICLES,
        "iterations": ITERATIONS,
        "waypoints": np.asarray(result.waypoints, dtype=float).tolist(),
        "J_n": [_enc(v) for v in result.costs.total[0]],
        "evaluations": int(result.evaluations),
    }


def golden_differences(actual: dict[str, Any], expected: dict[str, Any], tol: float = TOLERANCE) -> list[str]:
    """Plain-language differences between two golden records (empty if they agree)."""
    out: list[str] = []
    for key in ("format", "method", "scenario", "seed", "particles", "iterations", "evaluations"):
        if actual.get(key) != expected.get(key):
            out.append(f"{key}: {actual.get(key)!r} != stored {expected.get(key)!r}")
    a = np.asarray(actual["waypoints"], dtype=float)
    e = np.asarray(expected["waypoints"], dtype=float)
    if a.shape != e.shape:
        out.append(f"waypoints: shape {a.shape} != stored {e.shape}")
    else:
        bad = ~np.isclose(a, e, rtol=tol, atol=tol)
        if bad.any():
            idx = tuple(int(i) for i in np.argwhere(bad)[0])
            out.append(f"waypoints{list(idx)}: {a[idx]!r} != stored {e[idx]!r} "
                       f"({int(bad.sum())} values differ by more than {tol:g})")
    ja = np.array([_dec(v) for v in actual["J_n"]])
    je = np.array([_dec(v) for v in expected["J_n"]])
    if ja.shape != je.shape:
        out.append(f"J_n: {len(ja)} values != stored {len(je)}")
    else:
        same = (ja == je) | np.isclose(ja, je, rtol=tol, atol=tol)
        for n in np.nonzero(~same)[0]:
            out.append(f"J_n[{n}]: {ja[n]!r} != stored {je[n]!r}")
    return out
