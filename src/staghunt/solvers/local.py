"""Local deviations of one UAV: a pattern search on its own path with the others fixed.

Shared by the default method's replies and its check before certificates
(:mod:`staghunt.solvers.game`), the equilibrium certificate (:mod:`staghunt.solvers.response`)
and the re-planner (:mod:`staghunt.flight.replan`): the spherical encoding of the swarms moves every
later waypoint with each step, so a swarm refines a path poorly and cannot move one waypoint a
little; this search moves one coordinate at a time in the site frame.
"""

from __future__ import annotations

from concurrent.futures import Future, wait
from dataclasses import dataclass

import numpy as np

from staghunt.costs import NUMPY_COSTS, CostEngine, CostModel, to_absolute
from staghunt.solvers.swarm import shared_pool

ACCEPT_TOL = 1e-9
"""A reply is accepted if it lowers ``J_n`` by more than this (relative)."""
POLISH_STEP = 1.0
POLISH_MIN_STEP = 1e-3
"""Initial and final coordinate step (m) of the polish."""


def polish(model: CostModel, plan: np.ndarray, n: int, max_evaluations: int,
           engine: CostEngine = NUMPY_COSTS, step: float = POLISH_STEP,
           min_step: float = POLISH_MIN_STEP, compiled: bool = True) -> tuple[np.ndarray, int]:
    """Local pattern search on UAV ``n``'s free waypoints in the site frame, the others fixed.

    The spherical encoding moves every later waypoint with each step, so a swarm refines a
    path poorly; this moves one coordinate at a time. Each sweep evaluates the ``6 K`` paths
    with one coordinate of one waypoint moved by ``+-step`` (clamped to the site box) and the
    path combining every improving move; the best feasible one that lowers ``J_n`` is taken,
    else ``step`` halves, down to ``min_step`` metres. Returns the ``(N, K, 3)`` plan (``plan``
    itself if nothing improved) and the path evaluations spent (``<= max_evaluations``).
    ``engine`` scores the candidates (its ``evaluate``); the plan's own cost is taken by the
    same engine, so every comparison is made in one arithmetic. Where the engine has a
    deviation evaluator (:meth:`~staghunt.costs.CostEngine.deviations`; the compiled engine's:
    :class:`~staghunt.engine.deviations.Deviations`), the candidates are scored by it and, with
    ``compiled``, the whole search is one call making the same decisions on the same costs
    (its ``polish``); this loop is its reference.
    """
    K = plan.shape[1]
    moves = np.concatenate([np.eye(3 * K), -np.eye(3 * K)]).reshape(6 * K, K, 3)
    if max_evaluations < 6 * K + 1:
        return plan, 0
    current = engine.evaluate(model, plan[None])
    if current.total_violation[0] != 0:
        return plan, 0
    best, J = plan, float(current.total[0, n])
    spent = 0
    # Only UAV n's path changes and the others' stay clear of each other (the plan is feasible):
    # an engine may evaluate the deviation alone (same J_n, same feasibility verdicts).
    fast = engine.deviations(model, plan, n, current)
    if fast is not None and compiled:  # the same search in one compiled call
        path, _, spent = fast.polish(J, max_evaluations, step, min_step)
        if np.array_equal(path, plan[n]):
            return plan, spent
        best = plan.copy()
        best[n] = path
        return best, spent

    def own(paths: np.ndarray) -> np.ndarray:
        return fast(paths) if fast is not None else _own_costs(model, best, n, paths, engine)

    while step >= min_step and spent + 6 * K + 1 <= max_evaluations:
        cands = np.clip(best[n][None] + step * moves, model.lower, model.upper)
        Jc = own(cands)
        spent += len(cands)
        gain = J - Jc  # (6K,)
        if not gain.max() > ACCEPT_TOL * J:
            step /= 2
            continue
        g = gain.reshape(2, 3 * K)
        direction = np.where(g[0] >= g[1], 1.0, -1.0) * (np.maximum(g[0], g[1]) > 0)
        combined = np.clip(best[n] + step * direction.reshape(K, 3), model.lower, model.upper)
        Jcomb = own(combined[None])[0]
        spent += 1
        i = int(np.argmax(gain))
        new = best.copy()
        new[n], J = (combined, Jcomb) if Jcomb < Jc[i] else (cands[i], float(Jc[i]))
        best = new
    return best, spent


def _own_costs(model: CostModel, plan: np.ndarray, n: int, paths: np.ndarray,
               engine: CostEngine) -> np.ndarray:
    """``(Q,)`` ``J_n`` of ``plan`` with UAV ``n``'s path replaced by each of ``paths``
    ``(Q, K, 3)``; ``inf`` where the deviation breaks a hard constraint."""
    team = np.repeat(plan[None], len(paths), axis=0)
    team[:, n] = paths
    c = engine.evaluate(model, team)
    return np.where(c.total_violation == 0, c.total[:, n], np.inf)


@dataclass(frozen=True, eq=False)
class LocalSearch:
    """UAV ``n``'s local search (:func:`polish`) from ``plan`` ``(N, K, 3)`` with at most
    ``budget`` path evaluations in ``arithmetic`` (the name of the engine that made it: two
    searches in the same arithmetic make the same decisions): the ``(K, 3)`` ``path`` it
    ends on (``plan[n]`` if nothing improved) and the ``evaluations`` it spent. The certificate
    (:func:`staghunt.solvers.response.certify_plan`) takes it instead of making the same search
    again (:meth:`stands_for`): the same computation, so the same result."""

    plan: np.ndarray
    n: int
    budget: int
    arithmetic: str
    path: np.ndarray
    evaluations: int

    def stands_for(self, plan: np.ndarray, n: int, budget: int, engine: CostEngine) -> bool:
        """Whether this is :func:`polish` ``(plan, n, budget, engine)``'s search."""
        return (self.n == n and self.budget == budget and self.arithmetic == engine.name
                and self.plan.shape == plan.shape and bool(np.array_equal(self.plan, plan)))

    def moved(self, plan: np.ndarray) -> np.ndarray:
        """What :func:`polish` returns for this search of ``plan``: ``plan`` itself if nothing
        improved, else a copy with UAV ``n``'s path replaced."""
        if np.array_equal(self.path, plan[self.n]):
            return plan
        out = plan.copy()
        out[self.n] = self.path
        return out


@dataclass(frozen=True, eq=False)
class LocalPass:
    """What :func:`local_pass` ends with: the ``(N, K, 3)`` ``plan``, its ``(N,)`` ``costs``, the
    ``(N,)`` relative ``gains`` taken (0 where none), the path ``evaluations`` spent and the
    ``searches`` made (:class:`LocalSearch`, in order; those from the final plan stand for the
    certificate's searches of it)."""

    plan: np.ndarray
    costs: np.ndarray
    gains: np.ndarray
    evaluations: int
    searches: tuple[LocalSearch, ...]


def local_pass(model: CostModel, plan: np.ndarray, J: np.ndarray, per_uav: int, epsilon: float,
               engine: CostEngine = NUMPY_COSTS, limit: float = np.inf, workers: int = 1) -> LocalPass:
    """Every UAV in turn makes a local search (:func:`polish`, ``per_uav`` evaluations) from the
    feasible ``plan`` ``(N, K, 3)`` with costs ``J`` ``(N,)``; a path that lowers its ``J_n`` by
    more than ``epsilon`` (relative) and keeps the plan feasible is taken. No search starts that
    could take the evaluations past ``limit``.

    ``workers > 1``: the next ``workers`` searches are made side by side from the current plan
    (``engine`` must then be thread-safe, as the engines are), and each stands until
    a gain changes the plan; the ones made before a gain are dropped and made again from the
    new plan (at most ``workers - 1`` searches wasted per gain, on the other cores). The same
    decisions as one at a time, so the same result. Measured on two cores: a pass of 3 UAVs
    1.0-1.2x as fast, of 8 UAVs 1.2-1.4x (benchmarks/README.md)."""
    N = len(J)
    gains = np.zeros(N)
    spent = 0
    searches: list[LocalSearch] = []
    pool = shared_pool(workers, "local") if workers > 1 and N > 1 else None
    ahead: dict[int, Future[tuple[np.ndarray, int]]] = {}
    dropped: list[Future[tuple[np.ndarray, int]]] = []
    for n in range(N):
        if spent + per_uav > limit:
            break
        if pool is not None:
            for m in range(n, min(N, n + workers)):
                if m not in ahead:
                    ahead[m] = pool.submit(polish, model, plan, m, per_uav, engine)
            moved, used = ahead.pop(n).result()
        else:
            moved, used = polish(model, plan, n, per_uav, engine)
        searches.append(LocalSearch(np.array(plan), n, per_uav, engine.name, np.array(moved[n]), used))
        spent += used
        if moved is plan:
            continue
        c = engine.evaluate(model, moved[None])
        spent += 1
        if c.total_violation[0] == 0 and c.total[0, n] < J[n] * (1.0 - epsilon):
            gains[n] = (J[n] - c.total[0, n]) / J[n]
            plan, J = moved, c.total[0]
            dropped.extend(f for f in ahead.values() if not f.cancel())  # made from the plan before
            ahead = {}
    wait([*dropped, *ahead.values()])  # nothing left running on return
    return LocalPass(plan, J, gains, spent, tuple(searches))


def formation_target(model: CostModel, plan: np.ndarray, n: int) -> np.ndarray:
    """``(K, 3)`` ``(x, y, h)``: where UAV ``n`` would zero its own formation error (eq. 5) at
    every waypoint with the others' paths of ``plan`` ``(N, K, 3)`` fixed: the ``mu[n]``-weighted
    mean over its edges of the team-mate's position plus the reference offset. ``plan[n]`` if
    ``n`` weighs no edge."""
    incident = (model.mu[n] > 0) & ((model.heads == n) | (model.tails == n))
    if not incident.any():
        return plan[n].copy()
    absolute = to_absolute(model.terrain, plan)  # (N, K, 3)
    target = np.zeros_like(absolute[0])
    for e in np.flatnonzero(incident):
        w, head, tail = model.mu[n, e], model.heads[e], model.tails[e]
        if head == n:
            target += w * (absolute[tail] + model.ref_diff[e])
        else:
            target += w * (absolute[head] - model.ref_diff[e])
    target /= model.mu[n, incident].sum()
    out = target.copy()
    out[:, 2] = target[:, 2] - model.terrain.height(target[:, 0], target[:, 1])
    return np.clip(out, model.lower, model.upper)
