"""Local deviations of one UAV: a pattern search on its own path with the others fixed.

Shared by the default method's replies and its check before certificates
(:mod:`staghunt.solvers.game`), the equilibrium certificate (:mod:`staghunt.solvers.response`)
and the re-planner (:mod:`staghunt.flight.replan`): the spherical encoding of the swarms moves every
later waypoint with each step, so a swarm refines a path poorly and cannot move one waypoint a
little; this search moves one coordinate at a time in the site frame.
"""

from __future__ import annotations

import numpy as np

from staghunt.costs import CostModel, Evaluator, evaluate

ACCEPT_TOL = 1e-9
"""A reply is accepted if it lowers ``J_n`` by more than this (relative)."""
POLISH_STEP = 1.0
POLISH_MIN_STEP = 1e-3
"""Initial and final coordinate step (m) of the polish."""


def polish(model: CostModel, plan: np.ndarray, n: int, max_evaluations: int,
           evaluator: Evaluator = evaluate, step: float = POLISH_STEP,
           min_step: float = POLISH_MIN_STEP, compiled: bool = True) -> tuple[np.ndarray, int]:
    """Local pattern search on UAV ``n``'s free waypoints in the site frame, the others fixed.

    The spherical encoding moves every later waypoint with each step, so a swarm refines a
    path poorly; this moves one coordinate at a time. Each sweep evaluates the ``6 K`` paths
    with one coordinate of one waypoint moved by ``+-step`` (clamped to the site box) and the
    path combining every improving move; the best feasible one that lowers ``J_n`` is taken,
    else ``step`` halves, down to ``min_step`` metres. Returns the ``(N, K, 3)`` plan (``plan``
    itself if nothing improved) and the path evaluations spent (``<= max_evaluations``).
    ``evaluator`` scores the candidates (an engine's ``evaluate``); the plan's own cost is
    taken with the same evaluator, so every comparison is made in one arithmetic. On the
    compiled engine (``compiled``) the whole search is one compiled call making the same
    decisions on the same costs (:meth:`~staghunt.engine.deviations.Deviations.polish`); this
    loop is its reference.
    """
    K = plan.shape[1]
    moves = np.concatenate([np.eye(3 * K), -np.eye(3 * K)]).reshape(6 * K, K, 3)
    if max_evaluations < 6 * K + 1:
        return plan, 0
    current = evaluator(model, plan[None])
    if current.total_violation[0] != 0:
        return plan, 0
    best, J = plan, float(current.total[0, n])
    spent = 0
    # Only UAV n's path changes and the others' stay clear of each other (the plan is feasible):
    # an engine may evaluate the deviation alone (same J_n, same feasibility verdicts).
    engine = getattr(evaluator, "__self__", None)
    fast = engine.deviations(model, plan, n) if hasattr(engine, "deviations") else None
    if fast is not None and compiled:  # the same search in one compiled call
        path, _, spent = fast.polish(J, max_evaluations, step, min_step)
        if np.array_equal(path, plan[n]):
            return plan, spent
        best = plan.copy()
        best[n] = path
        return best, spent

    def own(paths: np.ndarray) -> np.ndarray:
        return fast(paths) if fast is not None else _own_costs(model, best, n, paths, evaluator)

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
               evaluator: Evaluator) -> np.ndarray:
    """``(Q,)`` ``J_n`` of ``plan`` with UAV ``n``'s path replaced by each of ``paths``
    ``(Q, K, 3)``; ``inf`` where the deviation breaks a hard constraint."""
    team = np.repeat(plan[None], len(paths), axis=0)
    team[:, n] = paths
    c = evaluator(model, team)
    return np.where(c.total_violation == 0, c.total[:, n], np.inf)


def local_pass(model: CostModel, plan: np.ndarray, J: np.ndarray, per_uav: int, epsilon: float,
               evaluator: Evaluator = evaluate, limit: float = np.inf) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Every UAV in turn makes a local search (:func:`polish`, ``per_uav`` evaluations) from the
    feasible ``plan`` ``(N, K, 3)`` with costs ``J`` ``(N,)``; a path that lowers its ``J_n`` by
    more than ``epsilon`` (relative) and keeps the plan feasible is taken. No search starts that
    could take the evaluations past ``limit``. Returns the plan, its costs, the ``(N,)`` relative
    gains taken (0 where none) and the path evaluations spent."""
    gains = np.zeros(len(J))
    spent = 0
    for n in range(len(J)):
        if spent + per_uav > limit:
            break
        moved, used = polish(model, plan, n, per_uav, evaluator)
        spent += used
        if moved is plan:
            continue
        c = evaluator(model, moved[None])
        spent += 1
        if c.total_violation[0] == 0 and c.total[0, n] < J[n] * (1.0 - epsilon):
            gains[n] = (J[n] - c.total[0, n]) / J[n]
            plan, J = moved, c.total[0]
    return plan, J, gains, spent
