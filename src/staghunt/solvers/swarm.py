"""The swarm loop shared by every method: propose, evaluate, update bests (Algorithm 1).

``S`` swarms (one per UAV, or one for a virtual leader) move in lock-step; particle ``i`` of
every swarm together forms joint allocation ``i``, evaluated as a whole into a cost vector over
``C`` players. Personal and global bests change only to an allocation that dominates them
(:mod:`staghunt.solvers.dominance`). With ``C = 1`` this is plain single-objective SPSO.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from staghunt.scenario.model import SolverSettings
from staghunt.solvers.dominance import best_index, dominates
from staghunt.solvers.problem import SwarmProblem
from staghunt.solvers.pso import position_step, velocity_step


_POOLS: dict[tuple[str, int], ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()


def shared_pool(workers: int, purpose: str) -> ThreadPoolExecutor:
    """One process-wide pool of ``workers`` threads per ``purpose`` (``"block"``: an engine's
    particle blocks; ``"certify"``: a certificate's UAV searches), created on first use:
    starting threads for every short run (``game``'s many replies, each re-plan's
    certificates) costs more than the runs (about a millisecond a thread). Its idle threads end
    with the process. Work on a pool must not wait for work on the same pool."""
    with _POOLS_LOCK:
        pool = _POOLS.get((purpose, workers))
        if pool is None:
            pool = _POOLS[purpose, workers] = ThreadPoolExecutor(workers, thread_name_prefix=f"staghunt-{purpose}")
        return pool


class Progress(Protocol):
    def __call__(self, iteration: int, total: int, best_cost: np.ndarray) -> None: ...


@dataclass(frozen=True, eq=False)
class SwarmOutcome:
    """``best``: ``(S, K, 3)`` spherical global best; ``best_waypoints``: ``(N, K, 3)`` the team
    waypoints it decodes to, exactly as the engine evaluated them (engines may decode with
    different rounding, and a plan grazing a constraint must keep the verdict it was given); ``best_cost``: ``(C,)``;
    ``history``: ``(iterations + 1, C)`` global-best cost after initialisation and each
    iteration; ``record_history``: ``(iterations + 1, R)`` its per-UAV record;
    ``history_violation``: ``(iterations + 1,)``; ``path_evaluations``: single-UAV path
    evaluations spent (:meth:`SwarmProblem.path_evaluations`)."""

    best: np.ndarray
    best_waypoints: np.ndarray
    best_cost: np.ndarray
    best_violation: float
    history: np.ndarray
    record_history: np.ndarray
    history_violation: np.ndarray
    path_evaluations: int


def run_swarm(
    problem: SwarmProblem,
    settings: SolverSettings,
    rng: np.random.Generator,
    progress: Progress | None = None,
    initial: np.ndarray | None = None,
) -> SwarmOutcome:
    """Run ``settings.iterations`` iterations of ``settings.particles`` joint particles (NumPy engine).

    ``initial``: optional warm start, ``(S, K, 3)`` or ``(W, S, K, 3)`` spherical particles that
    replace particles ``0 .. W-1`` of the uniform draw (at most ``P`` of them are used).
    """
    P, K = settings.particles, settings.waypoints
    space, objective = problem.space, problem.evaluate
    X = space.sample(rng, P, K)
    if initial is not None:
        warm = np.asarray(initial, dtype=float).reshape(-1, *X.shape[1:])[:P]
        X[: warm.shape[0]] = warm
    V = np.zeros_like(X)
    cost, viol, record = objective(X)
    pbest, pcost, pviol = X.copy(), cost.copy(), viol.copy()
    g = best_index(pcost, pviol)
    gbest, gcost, gviol = pbest[g].copy(), pcost[g].copy(), float(pviol[g])
    history = np.empty((settings.iterations + 1, cost.shape[1]))
    rhistory = np.empty((settings.iterations + 1, record.shape[1]))
    hviol = np.empty(settings.iterations + 1)
    history[0], rhistory[0], hviol[0] = gcost, record[g], gviol
    inertia = settings.c0
    for it in range(1, settings.iterations + 1):
        r1 = rng.random(X.shape)
        r2 = rng.random(X.shape)
        V = velocity_step(X, V, pbest, gbest, inertia, settings.c1, settings.c2, r1, r2, space.vmax)
        X, V = position_step(X, V, space.lower, space.upper)
        cost, viol, record = objective(X)
        better = dominates(cost, viol, pcost, pviol)
        pbest[better], pcost[better], pviol[better] = X[better], cost[better], viol[better]
        cand = dominates(cost, viol, gcost[None], np.float64(gviol))
        g = best_index(cost, viol, cand)
        if g >= 0:
            gbest, gcost, gviol = X[g].copy(), cost[g].copy(), float(viol[g])
            rhistory[it] = record[g]
        else:
            rhistory[it] = rhistory[it - 1]
        history[it], hviol[it] = gcost, gviol
        inertia *= settings.damping
        if progress is not None:
            progress(it, settings.iterations, gcost)
    return SwarmOutcome(
        best=gbest,
        best_waypoints=problem.team_waypoints(gbest[None])[0],
        best_cost=gcost,
        best_violation=gviol,
        history=history,
        record_history=rhistory,
        history_violation=hviol,
        path_evaluations=problem.path_evaluations(settings),
    )


SwarmRunner = Callable[..., SwarmOutcome]
"""What runs a :class:`SwarmProblem`: :func:`run_swarm` (NumPy reference) or an engine's
``run_swarm``, with the signature and contract of :func:`run_swarm`."""
