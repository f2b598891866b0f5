"""OR-Tools for the allocation (:mod:`staghunt.inspection.allocation` holds the model, the
timing, the lower bound, the greedy baseline and the local search): the routing model with a
time dimension (each UAV's endurance its capacity, the windows as cumul ranges, each task's ways
a disjunction), the bisection on the makespan, and :func:`solve`, what the planner runs."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from staghunt.inspection.allocation import (
    Allocation, Problem, _dropped, _result, greedy, improve, lower_bound, time_routes,
)
from staghunt.inspection.tasks import window_of

__all__ = ["TICK", "solve", "solve_ortools"]

TICK = 0.1
"""OR-Tools' time unit (s)."""


@dataclass
class _Model:
    """An OR-Tools routing model of a problem (nodes: each active UAV's start and end, then one
    node per task way) and how to read a solution back."""

    routing: object
    manager: object
    dim: object
    node_of: dict
    active: list


def _model(problem: Problem, bound_s: float | None, span: bool):
    from ortools.constraint_solver import pywrapcp

    fleet, tasks = problem.fleet, problem.tasks
    active = [k for k in range(fleet.n) if fleet.active[k]]
    N = len(active)
    points: list[tuple[np.ndarray, np.ndarray]] = [(fleet.starts[k], fleet.starts[k]) for k in active]
    points += [(fleet.goals[k], fleet.goals[k]) for k in active]
    service = [0.0] * (2 * N)
    node_of: dict[tuple[int, int], int] = {}
    for t in tasks:
        for wi, w in enumerate(t.ways):
            node_of[(t.index, wi)] = len(points)
            points.append((w.entry, w.exit))
            service.append(problem.service(t))
    manager = pywrapcp.RoutingIndexManager(len(points), N, list(range(N)), list(range(N, 2 * N)))
    routing = pywrapcp.RoutingModel(manager)
    exits = np.array([p[1] for p in points])
    entries = np.array([p[0] for p in points])
    dist = np.linalg.norm(exits[:, None, :] - entries[None, :, :], axis=-1)
    callbacks = []
    for v, k in enumerate(active):  # a matrix by node, read by OR-Tools itself (no Python call per arc)
        ticks = np.rint((problem.slack * dist / float(fleet.speed[k]) + np.array(service)[:, None]) / TICK).astype(np.int64)
        callbacks.append(routing.RegisterTransitMatrix(ticks.tolist()))
        routing.SetArcCostEvaluatorOfVehicle(callbacks[-1], v)
    ends = [float(fleet.ready[k] + fleet.endurance[k]) for k in active]
    horizon = int(math.ceil((max(ends) if np.isfinite(ends).all() else 1e6) / TICK)) + 1
    routing.AddDimensionWithVehicleTransitAndCapacity(callbacks, horizon, [horizon] * N, False, "time")
    dim = routing.GetDimensionOrDie("time")
    if span:
        dim.SetGlobalSpanCostCoefficient(100)
    for v, k in enumerate(active):
        ready = int(round(float(fleet.ready[k]) / TICK))
        dim.CumulVar(routing.Start(v)).SetRange(ready, ready)
        last = ready + int(math.floor(float(fleet.endurance[k]) / TICK)) if np.isfinite(fleet.endurance[k]) else horizon
        if bound_s is not None:
            last = min(last, int(math.floor(bound_s / TICK)))
        dim.CumulVar(routing.End(v)).SetMax(last)
    for t in tasks:
        idx = [manager.NodeToIndex(node_of[(t.index, wi)]) for wi in range(len(t.ways))]
        allowed = [v for v, k in enumerate(active) if k in t.uavs]
        for i in idx:
            if len(allowed) < N:  # (SetAllowedVehiclesForIndex's Python binding rejects lists in OR-Tools 9.15)
                routing.VehicleVar(i).SetValues([-1] + allowed)
            if t.window is not None:
                lo, hi = window_of(t)
                dim.CumulVar(i).SetRange(int(math.ceil(lo / TICK)), max(int(math.floor(hi / TICK)), int(math.ceil(lo / TICK))))
        # every task may be left out at a penalty (far above any makespan for a required one), so
        # that a tight bound still has solutions for the local search to improve; a plan that
        # leaves a required task out is refused by the caller
        weight = int(1e9) if t.required else int(1e7) * max(1, t.priority)
        routing.AddDisjunction(idx, weight + int(t.duration / TICK))
    return _Model(routing, manager, dim, node_of, active)


def _run(model: _Model, problem: Problem, solutions: int, time_cap_s: float, start: list[list[tuple[int, int]]] | None
         ) -> list[list[tuple[int, int]]] | None:
    """Solve ``model`` (cheapest insertion, then guided local search for ``solutions``
    solutions within ``time_cap_s``), from ``start`` when it fits; the plan, or ``None``."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    routing, manager = model.routing, model.manager
    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PARALLEL_CHEAPEST_INSERTION
    params.local_search_metaheuristic = routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
    params.solution_limit = int(solutions)
    params.time_limit.FromMilliseconds(int(time_cap_s * 1000))
    solution = None
    if start is not None:
        routing.CloseModelWithParameters(params)
        first = routing.ReadAssignmentFromRoutes(
            [[manager.NodeToIndex(model.node_of[tw]) for tw in start[k]] for k in model.active], True)
        if first is not None:
            solution = routing.SolveFromAssignmentWithParameters(first, params)
    if solution is None:
        solution = routing.SolveWithParameters(params)
    if solution is None:
        return None
    inverse = {n: key for key, n in model.node_of.items()}
    plan: list[list[tuple[int, int]]] = [[] for _ in range(problem.fleet.n)]
    for v, k in enumerate(model.active):
        i = routing.Start(v)
        while not routing.IsEnd(i):
            node = manager.IndexToNode(i)
            if node in inverse:
                plan[k].append(inverse[node])
            i = solution.Value(routing.NextVar(i))
    return plan


_LOGGING: list[bool] = []


def _quiet() -> None:
    """OR-Tools' C++ log goes to stderr until absl's log is set up: set it up once per process,
    errors only (a rejected start assignment is not the user's concern)."""
    if _LOGGING:
        return
    _LOGGING.append(True)
    try:
        from ortools.init.python import init

        init.CppBridge.init_logging("staghunt")
        init.CppBridge.set_flags(init.CppFlags(stderrthreshold=3, log_prefix=False))
    except Exception:  # noqa: BLE001 - only the log's wording is at stake
        pass


def solve_ortools(problem: Problem, solutions: int = 60, rounds: int = 8, time_cap_s: float = 10.0,
                  start: Allocation | None = None, span: bool = False) -> Allocation:
    """OR-Tools' routing for the makespan.

    Default (``span=False``): bisection on the makespan. Each round bounds every UAV's end by
    ``M`` and asks OR-Tools for an allocation of least total flight time within it (cheapest
    insertion, then ``solutions`` solutions of guided local search, from the best allocation so
    far); found: the upper end drops to its makespan, else the lower end rises to ``M``. Starts
    from ``[lower bound, start's makespan]``, ``rounds`` rounds or until the two are within 1 %.
    OR-Tools' local search guides itself well by summed costs and poorly by a maximum, so this
    reaches lower makespans in less time than minimising the global span directly.

    ``span=True``: one run minimising the time dimension's global span (the makespan), for
    ``solutions`` solutions within ``time_cap_s``: the textbook model, used as the reference
    with a long time limit. ``time_cap_s`` bounds each run on a slow machine; the solution
    counts are the reproducible budget."""
    _quiet()
    started = time.perf_counter()
    best = start.routes if start is not None and start.ok else None
    plan0 = [start.tasks_of(k) for k in range(problem.fleet.n)] if best is not None else None
    if span:
        plan = _run(_model(problem, None, True), problem, solutions, time_cap_s, plan0)
        if plan is None:
            return _infeasible(problem, started)
        return _result(problem, "ortools-span", plan, _dropped(problem, plan), started,
                       {"solutions": solutions, "time_cap_s": time_cap_s})
    lo = lower_bound(problem)
    if plan0 is None:
        plan0 = _run(_model(problem, None, False), problem, solutions, time_cap_s, None)
        if plan0 is None:
            return _infeasible(problem, started)
    hi = max(r.end for r in time_routes(problem, plan0)[0])
    best_plan, trace = plan0, []
    for _ in range(rounds):
        if hi <= lo * 1.01:
            break
        bound = 0.5 * (lo + hi)
        plan = _run(_model(problem, bound, False), problem, solutions, time_cap_s, best_plan)
        ok = plan is not None and not [i for i in _dropped(problem, plan) if problem.tasks[i].required]
        if ok:
            end = max(r.end for r in time_routes(problem, plan)[0])
            if end < hi:
                best_plan, hi = plan, end
            else:
                lo = bound
        else:
            lo = bound
        trace.append([round(bound, 1), bool(ok)])
    return _result(problem, "ortools", best_plan, _dropped(problem, best_plan), started,
                   {"solutions_per_round": solutions, "rounds": trace, "time_cap_s": time_cap_s})


def _infeasible(problem: Problem, started: float) -> Allocation:
    return Allocation("ortools", "infeasible", "OR-Tools found no allocation: the endurances or time windows cannot "
                      "all be met", (), math.inf, lower_bound(problem), tuple(t.index for t in problem.tasks),
                      time.perf_counter() - started)


def solve(problem: Problem, method: str = "ortools", solutions: int = 30, rounds: int = 6,
          time_cap_s: float = 1.0) -> Allocation:
    """Allocate with ``method``: ``"ortools"`` (:func:`solve_ortools` started from the greedy
    allocation, so never worse than it, then :func:`improve`) or ``"greedy"`` (the baseline,
    as it is)."""
    g = greedy(problem)
    if method == "greedy":
        return g
    o = solve_ortools(problem, solutions, rounds, time_cap_s, start=g)
    if not o.ok:
        return o
    started = time.perf_counter()
    plan = improve(problem, [o.tasks_of(k) for k in range(problem.fleet.n)], time_cap_s=2.0 * time_cap_s)
    better = _result(problem, "ortools", plan, _dropped(problem, plan), started, dict(o.details))
    if better.ok and better.makespan < o.makespan - 1e-9:
        return replace(better, solve_time_s=o.solve_time_s + better.solve_time_s,
                       details={**o.details, "improved_from": o.makespan})
    return o
