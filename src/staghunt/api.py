"""The entry point: ``plan(scenario, method=..., seed=...)``."""

from __future__ import annotations

import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from staghunt.budget import MemoryEstimate, check_memory, estimate_plan
from staghunt.checks import plan_metrics, violations
from staghunt.costs import CostModel, evaluate, full_paths, to_absolute
from staghunt.engine import Engine, get_engine, side_by_side
from staghunt.result import PlanResult, Status
from staghunt.scenario import Scenario, SolverSettings, load_scenario
from staghunt.solvers import METHODS
from staghunt.solvers.base import MethodRun, RequestError, check_seed
from staghunt.solvers.local import LocalSearch
from staghunt.solvers.response import (
    Certificate,
    CertificateWork,
    CertifyOptions,
    CertifyRequest,
    certify_plan,
    check_search,
)
from staghunt.solvers.swarm import Progress


@dataclass(frozen=True, eq=False)
class PlanRequest:
    """A run that :func:`check_plan` has checked: the scenario, method, seed, solver settings,
    the resolved engine, the certificate's options (``None``: none) and its searches' settings,
    the stopping rule and the memory estimate. :func:`plan` runs it without checking anything
    again."""

    scenario: Scenario
    method: str
    seed: int
    settings: SolverSettings
    engine: Engine
    certify: CertifyOptions | None
    stop: str
    estimate: MemoryEstimate
    certify_settings: SolverSettings | None = None

    def with_seed(self, seed: int) -> "PlanRequest":
        """The same run with another seed (the only field checked again)."""
        return replace(self, seed=check_seed(seed))

    def with_scenario(self, scenario: Scenario) -> "PlanRequest":
        """The same run on ``scenario``, the same team and budget in a changed world (the
        re-plans of a flight: the checked settings still hold; the memory estimate is the
        original run's)."""
        return replace(self, scenario=scenario)


class PlanRequestError(RequestError):
    """A run :func:`check_plan` refuses; ``field`` names the argument at fault (``method``,
    ``seed``, ``settings``, ``certify``, ``stop``) so that a caller can word it its own way."""


def plan(
    scenario: "Scenario | str | os.PathLike[str] | PlanRequest",
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

    ``scenario``: a :class:`Scenario`, a built-in name or a TOML path; or a :class:`PlanRequest`
    from :func:`check_plan`, run as checked (``method``, ``seed``, ``settings``, ``engine``,
    ``threads``, ``certify`` and ``stop`` are then taken from it, not from the arguments). ``settings`` overrides the
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
    apart from the search (``compile_time_s``). With ``certify``, the default method with several
    starts (``settings.starts``) certifies every start's plan to select among the equilibria it
    found (docs/model.md section 6.1); ``certificate_time_s`` counts all those certificates.

    ``stop``: ``"budget"`` (default): each method's own stopping rule. ``"certified"`` (with
    ``certify``; for methods that can stop early, ``game``): the search also stops as soon as
    an intermediate plan passes the certificate, which is then the result's certificate (the
    same search on the same plan; its time counts in ``certificate_time_s``). With several
    starts the run ends at its first certified equilibrium (often the rigid start's) and searches
    none of the starts after it, so nothing is selected among equilibria
    (``details["selection"]["stopped_at_first_certified"]``). For a closed-loop re-planner: the
    time to a certified equilibrium rather than the best plan of the budget.
    """
    if isinstance(scenario, PlanRequest):
        request = scenario
    else:
        if not isinstance(scenario, Scenario):
            scenario = load_scenario(scenario)
        request = check_plan(scenario, method, seed, settings if settings is not None else scenario.solver,
                             engine, threads, certify, stop=stop)
    scenario, method, seed, settings = request.scenario, request.method, request.seed, request.settings
    certify, stop, resolved = request.certify, request.stop, request.engine
    compile_s = float(resolved.prepare())
    checks: list[tuple[np.ndarray, Certificate, float, CertificateWork]] = []

    def certificate_of(wp: np.ndarray, searched: Sequence[LocalSearch] = (), refute: bool = False) -> Certificate:
        """The certificate of ``wp``, made once per plan (a method may ask for several plans').
        ``refute``: a certificate stopped at its first refutation will do (its verdict is the
        full one's); one asked for in full later completes it, searching only what it did not."""
        assert certify is not None
        entry = next((i for i, (seen, _, _, _) in enumerate(checks) if np.array_equal(seen, wp)), None)
        if entry is not None:
            seen, cert, seconds, work = checks[entry]
            if cert.complete or refute:
                return cert
        else:
            seen, seconds, work = np.array(wp, copy=True), 0.0, CertificateWork()
        t = time.perf_counter()
        cert = certify_waypoints(request, wp, certify_progress, searched, refute, work)
        row = (seen, cert, seconds + time.perf_counter() - t, work)
        if entry is None:
            checks.append(row)
        else:
            checks[entry] = row
        return cert

    def certified(wp: np.ndarray, searched: Sequence[LocalSearch] = ()) -> bool:
        return certificate_of(wp, searched, refute=True).is_equilibrium

    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    out = METHODS[method](MethodRun(scenario, settings, rng, progress, resolved.run_swarm,
                                    resolved, certified if stop == "certified" else None,
                                    certificate_of if certify is not None else None,
                                    side_by_side(resolved)[1]))
    spent_checking = sum(c[2] for c in checks)
    wall = time.perf_counter() - t0 - spent_checking
    result = assemble(scenario, method, seed, settings, out.waypoints, out.history,
                      out.objective_history, out.evaluations, wall, out.leader_path, resolved.name,
                      out.details)
    result = replace(result, compile_time_s=compile_s)
    if certify is None:
        return result
    cert = certificate_of(result.waypoints)  # often made during the search already
    return replace(result, certificate=cert, certificate_time_s=sum(c[2] for c in checks))


def certify_waypoints(request: PlanRequest, waypoints: np.ndarray,
                      progress: Callable[[int, int, int, int], None] | None,
                      searched: Sequence[LocalSearch] = (), refute: bool = False,
                      work: CertificateWork | None = None) -> Certificate:
    """The certificate of ``waypoints`` ``(N, K, 3)`` with the checked ``request``'s certificate
    options (``request.certify``, not ``None``) and seed, run by its engine: with the compiled engine on
    several cores, the UAVs' searches run side by side, one thread each (the same certificate:
    each search has its own seed; no per-iteration barrier, which the small searches pay dearly).
    ``searched``: local searches already made from ``waypoints``; ``refute``, ``work``:
    ``certify_plan``'s."""
    assert request.certify is not None and request.certify_settings is not None
    engine, workers = side_by_side(request.engine)
    checked = CertifyRequest.of_checked(request.scenario, waypoints, request.certify_settings,
                                        request.certify, request.seed)
    return certify_plan(checked, progress=progress, runner=engine.run_swarm, workers=workers,
                        engine=engine, searched=searched, refute=refute, work=work)


def check_plan(
    scenario: Scenario,
    method: str,
    seed: int,
    settings: SolverSettings,
    engine: "str | Engine" = "auto",
    threads: int | None = None,
    certify: CertifyOptions | None = None,
    warn: Callable[[str], None] | None = None,
    stop: str = "budget",
    memory: bool = True,
) -> PlanRequest:
    """Every check :func:`plan` needs, made once, before anything runs (the CLI makes them before
    it creates the output directory): the method, the seed, the settings, the certificate's
    budget and whether these settings can certify at all, the stopping rule, the engine, and
    (``memory``) whether the run fits in memory (:mod:`staghunt.budget`; ``warn`` receives the
    warning above a quarter of the available memory). Returns the checked
    :class:`PlanRequest`; raises :class:`PlanRequestError` (or
    :class:`~staghunt.budget.MemoryBudgetError`), ``ValueError`` subclasses, with one line."""
    if method not in METHODS:
        raise PlanRequestError(f"unknown method {method!r}; choose one of {', '.join(sorted(METHODS))}", "method")
    try:
        seed = check_seed(seed)
        certify_settings = check_search(settings, certify)
    except RequestError as exc:
        raise PlanRequestError(str(exc), exc.field) from None
    if stop not in ("budget", "certified"):
        raise PlanRequestError(f"stop must be 'budget' or 'certified', not {stop!r}", "stop")
    if stop == "certified" and certify is None:
        raise PlanRequestError("stop='certified' needs certify (the certificate's budget)", "stop")
    resolved = get_engine(engine, threads)
    estimate = estimate_plan(scenario, settings, method, resolved, threads, certify)
    if memory:  # before anything is allocated: a run that cannot fit in memory is refused
        check_memory(estimate, warn=warn)
    return PlanRequest(scenario, method, seed, settings, resolved, certify, stop, estimate, certify_settings)


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
