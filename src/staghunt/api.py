"""The entry point: ``plan(scenario, method=..., seed=...)``."""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from dataclasses import replace
from typing import Any, Callable

import numpy as np

from staghunt.budget import check_memory, estimate_plan
from staghunt.checks import plan_metrics, violations
from staghunt.costs import CostModel, evaluate, full_paths, to_absolute
from staghunt.engine import Engine, get_engine, side_by_side
from staghunt.result import PlanResult, Status
from staghunt.scenario import Scenario, SolverSettings, load_scenario
from staghunt.scenario.model import check_settings
from staghunt.solvers import METHODS
from staghunt.solvers.base import MethodRun
from staghunt.solvers.response import Certificate, CertifyOptions, certify_plan
from staghunt.solvers.swarm import Progress


def plan(
    scenario: Scenario | str | os.PathLike[str],
    method: str = "game",
    seed: int = 0,
    settings: SolverSettings | None = None,
    progress: Progress | None = None,
    engine: "str | Engine" = "auto",
    threads: int | None = None,
    certify: CertifyOptions | None = None,
    certify_progress: Callable[[int, int, int, int], None] | None = None,
    stop: str = "budget",
) -> PlanResult:
    """Plan paths for the team of ``scenario`` with ``method`` (see ``staghunt.solvers.METHODS``).

    ``scenario``: a :class:`Scenario`, a built-in name or a TOML path. ``settings`` overrides the
    scenario's solver settings. One ``numpy.random.Generator`` seeded with ``seed`` drives the
    whole run, so the same inputs, seed and engine give the same plan.

    ``engine``: ``"numba"`` (compiled kernels), ``"numpy"`` (the readable reference), ``"auto"``
    (numba if installed) or an engine object (:mod:`staghunt.engine`). The engines draw
    different random streams, so their plans differ (statistically equivalent). ``threads``:
    the compiled engine's thread count; ``None`` = adaptive (never slower than one thread).

    ``certify``: also certify the plan (:func:`staghunt.solvers.response.certify_plan`, its
    searches seeded from ``seed`` and run by the same engine) and store the
    :class:`~staghunt.solvers.response.Certificate` in the result (``None``: no certificate;
    the ``staghunt plan`` command certifies by default). A run whose arrays cannot fit in the
    available memory raises :class:`staghunt.budget.MemoryBudgetError` (a ``ValueError``) before
    anything is allocated (:func:`staghunt.budget.estimate_plan`). ``certify_progress(uav, n_uavs,
    iteration, iterations)`` follows its searches. A one-time compilation of the engine is timed
    apart from the search (``compile_time_s``).

    ``stop``: ``"budget"`` (default): each method's own stopping rule. ``"certified"`` (with
    ``certify``; for methods that can stop early, ``game``): the search also stops as soon as
    an intermediate plan passes the certificate, which is then the result's certificate (the
    same search on the same plan; its time counts in ``certificate_time_s``). For a closed-loop
    re-planner: the time to a certified equilibrium rather than the best plan of the budget.
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    settings = settings if settings is not None else scenario.solver
    resolved = check_plan(scenario, method, seed, settings, engine, threads, certify)
    prepare = getattr(resolved, "prepare", None)
    compile_s = float(prepare()) if callable(prepare) else 0.0
    if stop not in ("budget", "certified"):
        raise ValueError(f"stop must be 'budget' or 'certified', not {stop!r}")
    if stop == "certified" and certify is None:
        raise ValueError("stop='certified' needs certify (the certificate's budget)")
    checks: list[tuple[np.ndarray, Certificate, float]] = []

    def certified(wp: np.ndarray) -> bool:
        t = time.perf_counter()
        cert = _certificate(scenario, wp, certify, seed, settings, certify_progress, resolved)
        checks.append((np.array(wp, copy=True), cert, time.perf_counter() - t))
        return cert.is_equilibrium

    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    out = METHODS[method](MethodRun(scenario, settings, rng, progress, resolved.run_swarm,
                                    resolved.evaluate, certified if stop == "certified" else None))
    spent_checking = sum(c[2] for c in checks)
    wall = time.perf_counter() - t0 - spent_checking
    result = assemble(scenario, method, seed, settings, out.waypoints, out.history,
                      out.objective_history, out.evaluations, wall, out.leader_path, resolved.name,
                      out.details)
    result = replace(result, compile_time_s=compile_s)
    if certify is None:
        return result
    if checks and np.array_equal(checks[-1][0], result.waypoints):
        return replace(result, certificate=checks[-1][1], certificate_time_s=spent_checking)
    t0 = time.perf_counter()
    cert = _certificate(scenario, result.waypoints, certify, seed, settings, certify_progress, resolved)
    return replace(result, certificate=cert, certificate_time_s=time.perf_counter() - t0 + spent_checking)


def _certificate(scenario: Scenario, waypoints: np.ndarray, certify: CertifyOptions, seed: int,
                 settings: SolverSettings, progress: Callable[[int, int, int, int], None] | None,
                 engine: Engine) -> Certificate:
    """The certificate of ``waypoints``, run by ``engine``: with the compiled engine on several
    cores, the UAVs' searches run side by side, one thread each (the same certificate: each
    search has its own seed; no per-iteration barrier, which the small searches pay dearly)."""
    runner, workers = side_by_side(engine)
    return certify_plan(scenario, waypoints, particles=certify.particles, iterations=certify.iterations,
                        seed=seed, epsilon=certify.epsilon, settings=settings, progress=progress,
                        runner=runner, workers=workers)


def check_plan(
    scenario: Scenario,
    method: str,
    seed: int,
    settings: SolverSettings,
    engine: "str | Engine" = "auto",
    threads: int | None = None,
    certify: CertifyOptions | None = None,
    warn: Callable[[str], None] | None = None,
) -> Engine:
    """Every check :func:`plan` makes before it starts (the CLI makes them before it creates the
    output directory): the method, the seed, the settings, the certificate's budget and whether
    these settings can certify at all, the engine, and whether the run fits in memory
    (:mod:`staghunt.budget`; ``warn`` receives the warning above a quarter of the available
    memory). Returns the resolved engine; raises ``ValueError`` with one line."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(sorted(METHODS))}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    check_settings(settings)
    if certify is not None:
        certify.check()
        if settings.c1 == 0 and settings.c2 == 0 and certify.iterations > 0:
            # Refused by the certificate itself, but only after the search: check it now.
            raise ValueError("solver settings: c1 and c2 are both 0, so the certificate's search "
                             "cannot move towards any better path; give c1 or c2 > 0, or skip the "
                             "certificate (--no-certify)")
    resolved = get_engine(engine, threads)
    # Before anything is allocated: a run that cannot fit in memory is refused with one line.
    check_memory(estimate_plan(scenario, settings, method, resolved, threads, certify), warn=warn)
    return resolved


validate_settings = check_settings
"""Alias kept for callers of staghunt 0.1."""


def assemble(
    scenario: Scenario,
    method: str,
    seed: int,
    settings: SolverSettings,
    waypoints: np.ndarray,
    history: np.ndarray,
    objective_history: np.ndarray,
    evaluations: int,
    wall_time_s: float,
    leader_path: np.ndarray | None = None,
    engine: str = "numpy",
    details: Mapping[str, Any] | None = None,
) -> PlanResult:
    """Evaluate, check and package a plan ``(N, K, 3)`` into an immutable :class:`PlanResult`."""
    model = CostModel.from_scenario(scenario)
    names = [u.name for u in scenario.team]
    costs = evaluate(model, waypoints[None])
    broken = violations(model, waypoints, names)
    if broken:
        status = Status.INFEASIBLE
        more = f" (and {len(broken) - 3} more)" if len(broken) > 3 else ""
        message = "infeasible: " + "; ".join(broken[:3]) + more
    else:
        status = Status.FEASIBLE
        message = "feasible: all paths clear the obstacles, stay above ground and keep separation"
    path = full_paths(model, waypoints[None])[0]
    arrays = [np.array(waypoints), to_absolute(model.terrain, path), path[..., 2], history, objective_history]
    for a in arrays:
        a.setflags(write=False)
    return PlanResult(
        method=method,
        seed=seed,
        status=status,
        message=message,
        scenario=scenario,
        settings=settings,
        waypoints=arrays[0],
        paths=arrays[1],
        heights=arrays[2],
        costs=costs,
        metrics=plan_metrics(model, waypoints),
        history=arrays[3],
        objective_history=arrays[4],
        evaluations=evaluations,
        wall_time_s=wall_time_s,
        leader_path=leader_path,
        engine=engine,
        details=dict(details or {}),
    )
