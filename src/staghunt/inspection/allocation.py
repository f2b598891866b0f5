"""Allocation, the task management layer's decision: which UAV flies which tasks, in which order
and which way, so that the last UAV is done as early as possible (the makespan), within each
UAV's endurance and every task's time window.

Two solvers share one model (:class:`Problem`) and one route timing (:func:`time_routes`); the
OR-Tools one and :func:`~staghunt.inspection.routing.solve`, which runs them, are in
:mod:`staghunt.inspection.routing`:

- :func:`solve_ortools`: OR-Tools' vehicle routing (a time dimension with each UAV's endurance
  as its capacity, the windows as cumuls' ranges, waiting allowed; each task's ways are a
  disjunction of which exactly one is flown, optional objectives at a penalty; the makespan
  minimised through the dimension's global span), first solution by cheapest insertion,
  improved by guided local search for a fixed number of solutions (reproducible) within a time
  cap;
- :func:`greedy`: the baseline, cheapest insertion: tasks by window then longest first, each
  inserted where it raises the makespan least.

:func:`lower_bound`: no allocation can end earlier (module docstring of :func:`lower_bound`).
Times are in seconds after take-off; transit between tasks is the straight line at the UAV's
transit speed plus ``stop_s`` per task (to slow down and speed up), a lower bound of the legs
the game then plans round the obstacles.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from staghunt.inspection.tasks import Fleet, Task, window_of

__all__ = ["Allocation", "Problem", "Route", "Visit", "greedy", "improve", "lower_bound", "shortfall", "time_routes"]



@dataclass(frozen=True)
class Visit:
    """Task ``task`` flown its way ``way``, from ``start`` to ``end`` (s)."""

    task: int
    way: int
    start: float
    end: float


@dataclass(frozen=True)
class Route:
    """UAV ``uav``'s visits in order, when it is done (at its goal, s) and how its time splits
    into capture work, transit and waiting for windows."""

    uav: int
    visits: tuple[Visit, ...]
    end: float
    work: float
    transit: float
    wait: float


@dataclass(frozen=True)
class Problem:
    """Tasks for a fleet; ``stop_s``: time lost slowing down into and speeding up out of a task;
    ``slack``: the planned transit time over the straight line's at the transit speed (the legs
    go round obstacles, speed up and slow down; the lower bound takes the straight line)."""

    tasks: tuple[Task, ...]
    fleet: Fleet
    stop_s: float = 2.0
    slack: float = 1.0

    def service(self, t: Task) -> float:
        return t.duration + self.stop_s

    def travel(self, k: int, a: np.ndarray, b: np.ndarray) -> float:
        return self.slack * self.fleet.travel(k, a, b)


@dataclass(frozen=True, eq=False)
class Allocation:
    """Who flies what. ``status``: ``"allocated"`` every required task has a UAV (optional ones
    may be in ``dropped``); ``"infeasible"``: no allocation meets the endurances and windows,
    ``message`` says what is missing. ``makespan``: the last UAV's end (s); ``lower_bound``:
    no allocation ends before it."""

    method: str
    status: str
    message: str
    routes: tuple[Route, ...]
    makespan: float
    lower_bound: float
    dropped: tuple[int, ...] = ()
    solve_time_s: float = 0.0
    details: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "allocated"

    def tasks_of(self, uav: int) -> list[tuple[int, int]]:
        """``[(task, way), ...]`` of UAV ``uav`` in flying order."""
        return [(v.task, v.way) for r in self.routes if r.uav == uav for v in r.visits]


def time_routes(problem: Problem, plan: list[list[tuple[int, int]]]) -> tuple[list[Route], list[str]]:
    """Time each UAV's ``[(task, way), ...]``: leave when ready, transit, wait for a window if
    early; returns the routes and the broken constraints in words (empty if none)."""
    fleet, tasks = problem.fleet, problem.tasks
    routes, broken = [], []
    for k, visits in enumerate(plan):
        t = float(fleet.ready[k])
        pos = fleet.starts[k]
        work = transit = wait = 0.0
        out = []
        for ti, wi in visits:
            task = tasks[ti]
            way = task.ways[wi]
            leg = problem.travel(k, pos, way.entry)
            t += leg
            transit += leg
            lo, hi = window_of(task)
            if t < lo:
                wait += lo - t
                t = lo
            if t > hi + 1e-6:
                broken.append(f"{fleet.names[k]} reaches task {ti} ({task.objective}) at {t:.0f} s, after its window")
            start = t
            t += problem.service(task)
            work += problem.service(task)
            out.append(Visit(ti, wi, start, t))
            pos = way.exit
        leg = problem.travel(k, pos, fleet.goals[k])
        t += leg
        transit += leg
        used = t - float(fleet.ready[k])
        if used > fleet.endurance[k] + 1e-6:
            broken.append(f"{fleet.names[k]} needs {used:.0f} s of flight, its endurance is {fleet.endurance[k]:.0f} s")
        routes.append(Route(k, tuple(out), t, work, transit, wait))
    return routes, broken


def lower_bound(problem: Problem) -> float:
    """No allocation ends earlier than the largest of:

    - each UAV's own trip from its start to its goal;
    - for each required task, the fastest capable UAV's trip start -> task -> goal (waiting for
      its window);
    - the work shared evenly plus the transit it needs: for any trip length ``theta``, the tasks whose
      shortest trip (out from a start to it and back from it to a goal, over the capable UAVs) is
      at least ``theta`` are flown by UAVs that fly at least ``theta`` each, and the one with the
      most of their work has at least their work over the number of active UAVs: so at least
      ``theta + W(theta) / N``, for every ``theta`` among those trips (the smallest one gives all
      the work plus the shortest trip).

    Transit is the straight line at the transit speed and a task takes its length at its speed:
    no slowing down, no detour, no stop, no transit between tasks; so it is a bound the planned
    mission cannot beat."""
    fleet, tasks = problem.fleet, problem.tasks
    active = [k for k in range(fleet.n) if fleet.active[k]]
    if not active:
        return math.inf
    best = max(float(fleet.ready[k]) + fleet.travel(k, fleet.starts[k], fleet.goals[k]) for k in active)
    required = [t for t in tasks if t.required]
    if not required:
        return best
    trips, works = [], []
    for t in required:
        lo, _ = window_of(t)
        one, trip = math.inf, math.inf
        for k in t.uavs:
            if not fleet.active[k]:
                continue
            for w in t.ways:
                go, back = fleet.travel(k, fleet.starts[k], w.entry), fleet.travel(k, w.exit, fleet.goals[k])
                trip = min(trip, float(fleet.ready[k]) + go + back)
                one = min(one, max(float(fleet.ready[k]) + go, lo) + t.duration + back)
        best = max(best, one)
        trips.append(trip)
        works.append(t.duration)
    order = np.argsort(trips)[::-1]
    longest_first = np.cumsum(np.asarray(works)[order])
    for theta, work in zip(np.asarray(trips)[order], longest_first):
        best = max(best, float(theta) + float(work) / len(active))
    return best


def _result(problem: Problem, method: str, plan: list[list[tuple[int, int]]], dropped: list[int], started: float,
            details: dict | None = None) -> Allocation:
    routes, broken = time_routes(problem, plan)
    lb = lower_bound(problem)
    makespan = max(r.end for r in routes) if routes else 0.0
    missing = [i for i in dropped if problem.tasks[i].required]
    if broken or missing:
        what = broken[:2] + [f"task {i} ({problem.tasks[i].objective}) has no UAV" for i in missing[:2]]
        return Allocation(method, "infeasible", "; ".join(what), tuple(routes), makespan, lb, tuple(dropped),
                          time.perf_counter() - started, details or {})
    return Allocation(method, "allocated", f"makespan {makespan:.0f} s (lower bound {lb:.0f} s)", tuple(routes),
                      makespan, lb, tuple(dropped), time.perf_counter() - started, details or {})


def _route_end(problem: Problem, k: int, visits: list[tuple[int, int]]) -> tuple[float, bool]:
    """End time of UAV ``k`` flying ``visits`` and whether it meets its endurance and windows."""
    fleet, tasks = problem.fleet, problem.tasks
    t = float(fleet.ready[k])
    pos = fleet.starts[k]
    for ti, wi in visits:
        way = tasks[ti].ways[wi]
        t += problem.travel(k, pos, way.entry)
        lo, hi = window_of(tasks[ti])
        if t > hi + 1e-6:
            return t, False
        t = max(t, lo) + problem.service(tasks[ti])
        pos = way.exit
    t += problem.travel(k, pos, fleet.goals[k])
    return t, t - float(fleet.ready[k]) <= fleet.endurance[k] + 1e-6


def greedy(problem: Problem) -> Allocation:
    """Cheapest insertion for the makespan: tasks with a window first (earliest first), then the
    longest first; each goes to the UAV, position and way that raise the makespan least (ties:
    the smallest increase of that UAV's end). A task no UAV can take is dropped."""
    started = time.perf_counter()
    fleet, tasks = problem.fleet, problem.tasks
    order = sorted(range(len(tasks)), key=lambda i: (tasks[i].window is None, window_of(tasks[i])[0],
                                                     -tasks[i].duration, i))
    plan: list[list[tuple[int, int]]] = [[] for _ in range(fleet.n)]
    ends = [(_route_end(problem, k, []) if fleet.active[k] else (0.0, True))[0] for k in range(fleet.n)]
    dropped: list[int] = []
    for ti in order:
        best = None
        for k in tasks[ti].uavs:
            if not fleet.active[k]:
                continue
            for pos in range(len(plan[k]) + 1):
                for wi in range(len(tasks[ti].ways)):
                    trial = plan[k][:pos] + [(ti, wi)] + plan[k][pos:]
                    end, ok = _route_end(problem, k, trial)
                    if not ok:
                        continue
                    span = max([end] + [e for j, e in enumerate(ends) if j != k])
                    key = (span, end - ends[k], k, pos, wi)
                    if best is None or key < best[0]:
                        best = (key, k, trial, end)
        if best is None:
            dropped.append(ti)
            continue
        _, k, trial, end = best
        plan[k] = trial
        ends[k] = end
    return _result(problem, "greedy", plan, dropped, started)


def _dropped(problem: Problem, plan: list[list[tuple[int, int]]]) -> list[int]:
    seen = {ti for visits in plan for ti, _ in visits}
    return [t.index for t in problem.tasks if t.index not in seen]


def improve(problem: Problem, plan: list[list[tuple[int, int]]], passes: int = 200,
            time_cap_s: float = 2.0) -> list[list[tuple[int, int]]]:
    """Local search for the makespan: move a task of the UAV that ends last (any way round) to any
    place in another route, or exchange it with another route's task, or move it within its own
    route, whenever that brings the two routes' later end below the makespan; until no move
    helps (or ``passes`` moves, or ``time_cap_s``). Routes are timed exactly
    (:func:`_route_end`), endurance and windows kept."""
    started = time.perf_counter()
    fleet, tasks = problem.fleet, problem.tasks
    plan = [list(r) for r in plan]
    ends = [(_route_end(problem, k, plan[k])[0] if fleet.active[k] else 0.0) for k in range(fleet.n)]

    def fits(k: int, route: list[tuple[int, int]]) -> float | None:
        end, ok = _route_end(problem, k, route)
        return end if ok else None

    for _ in range(passes):
        if time.perf_counter() - started > time_cap_s:
            break
        worst = max((k for k in range(fleet.n) if fleet.active[k]), key=lambda k: ends[k])
        span = ends[worst]
        best = None  # (new max of the two ends, k, route_worst, route_k, end_worst, end_k)
        for i, (ti, _) in enumerate(plan[worst]):
            rest = plan[worst][:i] + plan[worst][i + 1:]
            e_rest = fits(worst, rest)
            if e_rest is None:
                continue
            for k in tasks[ti].uavs:
                if not fleet.active[k]:
                    continue
                if k == worst:
                    for pos in range(len(rest) + 1):
                        for wi in range(len(tasks[ti].ways)):
                            trial = rest[:pos] + [(ti, wi)] + rest[pos:]
                            e = fits(worst, trial)
                            if e is not None and e < span - 1e-6 and (best is None or e < best[0]):
                                best = (e, worst, trial, trial, e, e)
                    continue
                for pos in range(len(plan[k]) + 1):
                    for wi in range(len(tasks[ti].ways)):
                        trial = plan[k][:pos] + [(ti, wi)] + plan[k][pos:]
                        e = fits(k, trial)
                        if e is None:
                            continue
                        top = max(e, e_rest)
                        if top < span - 1e-6 and (best is None or top < best[0]):
                            best = (top, k, rest, trial, e_rest, e)
                for j, (tj, wj) in enumerate(plan[k]):  # exchange
                    if worst not in tasks[tj].uavs:
                        continue
                    a = plan[worst][:i] + [(tj, wj)] + plan[worst][i + 1:]
                    b = plan[k][:j] + [(ti, plan[worst][i][1])] + plan[k][j + 1:]
                    ea, eb = fits(worst, a), fits(k, b)
                    if ea is None or eb is None:
                        continue
                    top = max(ea, eb)
                    if top < span - 1e-6 and (best is None or top < best[0]):
                        best = (top, k, a, b, ea, eb)
        if best is None:
            break
        _, k, rw, rk, ew, ek = best
        plan[worst], ends[worst] = rw, ew
        if k != worst:
            plan[k], ends[k] = rk, ek
    return plan


def shortfall(problem: Problem, alloc: Allocation) -> str:
    """Why no allocation fits the endurances, in words: what is missing."""
    fleet = problem.fleet
    lb = lower_bound(problem)
    short = [k for k in range(fleet.n) if fleet.active[k] and fleet.endurance[k] < lb]
    total = sum(float(fleet.endurance[k]) for k in range(fleet.n) if fleet.active[k])
    need = sum(t.duration for t in problem.tasks if t.required)
    if need > total:
        return (f"endurance too short for any allocation: the required capture work alone takes {need:.0f} s, the "
                f"team has {total:.0f} s of flight in all ({need - total:.0f} s missing)")
    if short:
        return (f"endurance too short for any allocation: every UAV needs at least {lb:.0f} s (lower bound of the "
                f"makespan), {fleet.names[short[0]]} has {fleet.endurance[short[0]]:.0f} s")
    return f"no allocation meets every endurance and time window ({alloc.message})"
