"""The team's local searches of ``game``: Pareto-improving moves of the whole team (no UAV worse off,
one better, eq. (9a)), in the site frame (:func:`team_polish`) and along the team's route
(:func:`team_slide`), each in one compiled call on the compiled engine (its Python loop is the
reference), and of blocks of consecutive waypoints (:func:`team_shift`, batched evaluations).
Used by :mod:`staghunt.solvers.game` on each start and on the selected plan."""

from __future__ import annotations

from typing import Any

import numpy as np

from staghunt.costs import NUMPY_COSTS, CostEngine, CostModel
from staghunt.solvers.dominance import preference
from staghunt.solvers.local import ACCEPT_TOL, POLISH_MIN_STEP, POLISH_STEP

SLIDE_FRACTIONS = (0.4, 0.2, 0.1, 0.05, 0.025, 0.0125)
"""The shares of the way to a neighbouring waypoint that :func:`team_slide` tries, in turn."""


def _team_search_start(model: CostModel, plan: np.ndarray, engine: CostEngine, max_evaluations: int,
                       sweep: int) -> tuple[np.ndarray | None, int]:
    """Where a team search (:func:`team_polish`, :func:`team_slide`) starts: ``(J, N)``, the
    ``(N,)`` costs of the feasible ``plan`` and the evaluations spent on them; ``(None, spent)``
    if a sweep of ``sweep`` candidates does not fit in ``max_evaluations`` (``spent`` 0) or the
    plan is infeasible (``spent`` N)."""
    N = plan.shape[0]
    if max_evaluations < N * (sweep + 1):
        return None, 0
    current = engine.evaluate(model, plan[None])
    if current.total_violation[0] != 0:
        return None, N
    return current.total[0], N


def _dominating(c: Any, J: np.ndarray) -> np.ndarray:
    """``(Q,)`` whether each evaluated candidate of ``c`` (:func:`staghunt.costs.evaluate`'s
    result for ``Q`` plans) is feasible and Pareto-dominates costs ``J`` ``(N,)`` (eq. (9a)),
    better somewhere by more than :data:`ACCEPT_TOL` (relative)."""
    return ((c.total_violation == 0) & np.all(c.total <= J, axis=1)
            & np.any(c.total < J * (1.0 - ACCEPT_TOL), axis=1))


def team_polish(model: CostModel, plan: np.ndarray, max_evaluations: int, engine: CostEngine = NUMPY_COSTS,
                step: float = POLISH_STEP, min_step: float = POLISH_MIN_STEP,
                compiled: bool = True) -> tuple[np.ndarray, int]:
    """Pareto-improving pattern search that moves the whole team: each sweep evaluates the
    ``6 K`` plans with one coordinate of one waypoint moved by ``+-step`` for *every* UAV (the
    formation's shape is kept) and takes, among the feasible ones that Pareto-dominate the plan
    (no UAV worse, one better, eq. (9a)), the one with the least summed cost (summed in UAV
    order; the first on a tie); else ``step`` halves, down to ``min_step`` metres. A swarm in the
    spherical encoding leaves a formation route metres from its local optimum; this finishes
    the descent without making any UAV worse off. Returns the ``(N, K, 3)`` plan (``plan``
    itself if nothing improved) and the path evaluations spent (``N`` per candidate,
    ``<= max_evaluations``). ``engine`` scores the candidates; where it has a team search
    (:meth:`~staghunt.costs.CostEngine.team_search`; the compiled engine's:
    :func:`~staghunt.engine.deviations.team_search`) and ``compiled``, the whole search is one
    call making the same decisions on the same costs; this loop is its reference."""
    N, K = plan.shape[0], plan.shape[1]
    moves = np.concatenate([np.eye(3 * K), -np.eye(3 * K)]).reshape(6 * K, 1, K, 3)
    J, spent = _team_search_start(model, plan, engine, max_evaluations, 6 * K)
    if J is None:
        return plan, spent
    found = _compiled(engine.team_search(model, plan, J, max_evaluations, spent, step=step, min_step=min_step),
                      plan) if compiled else None
    if found is not None:
        return found
    best = plan
    while step >= min_step and spent + N * 6 * K <= max_evaluations:
        cands = np.clip(best[None] + step * moves, model.lower, model.upper)  # (6K, N, K, 3)
        c = engine.evaluate(model, cands)
        spent += N * 6 * K
        better = _dominating(c, J)
        if not better.any():
            step /= 2
            continue
        i = np.flatnonzero(better)[np.argmin(_in_order(c.total[better], np.add))]
        best, J = cands[i], c.total[i]
    return best, spent


def _compiled(found: tuple[np.ndarray, int] | None, plan: np.ndarray) -> tuple[np.ndarray, int] | None:
    """What an engine's team search of ``plan`` found (:meth:`~staghunt.costs.CostEngine.team_search`),
    as the Python loops return it (``plan`` itself if nothing improved); ``None`` if it has none."""
    if found is None:
        return None
    return (plan if np.array_equal(found[0], plan) else found[0]), found[1]


def _in_order(total: np.ndarray, op: np.ufunc) -> np.ndarray:
    """``(Q,)`` ``op`` (``np.add``, ``np.multiply``) of the columns of ``total`` ``(Q, N)`` taken
    in UAV order, ``((t_0 op t_1) op t_2) ...``: the arithmetic of the compiled twin."""
    out = total[:, 0].copy()
    for n in range(1, total.shape[1]):
        out = op(out, total[:, n])
    return out


def team_slide(model: CostModel, plan: np.ndarray, max_evaluations: int, engine: CostEngine = NUMPY_COSTS,
               fractions: tuple[float, ...] = SLIDE_FRACTIONS, compiled: bool = True) -> tuple[np.ndarray, int]:
    """Pareto-improving search over *when* the team passes where: each sweep evaluates the
    ``2 K`` plans with waypoint ``k`` of *every* UAV moved the same ``fraction`` of the way
    towards its waypoint ``k - 1`` or ``k + 1`` (the start or the goal at the ends), and takes,
    among the feasible ones that Pareto-dominate the plan (no UAV worse, one better, eq. (9a)),
    the one with the least ``sum_n ln J_n`` (the least product of ``J_n`` over the plan's
    ``J_n``, multiplied in UAV order: the same order without logarithms, whose last bit differs
    between libraries; the first on a tie); else the next, smaller fraction. The waypoints are
    synchronised, so sliding them along the team's route changes the formation error at each
    waypoint and the separations, for all UAVs at once: the equilibria selected on different
    seeds of scenario 2 differed mostly in this (the same route, its waypoints spaced
    differently), which neither a one-coordinate move (:func:`team_polish`) nor a UAV alone
    can change. Returns the ``(N, K, 3)`` plan (``plan`` itself if nothing improved) and the
    path evaluations spent (``N`` per candidate, ``<= max_evaluations``). ``engine`` scores the
    candidates; where it has a team search (:meth:`~staghunt.costs.CostEngine.team_search`) and
    ``compiled``, the whole search is one call making the same decisions; this loop is its
    reference."""
    N, K = plan.shape[0], plan.shape[1]
    J, spent = _team_search_start(model, plan, engine, max_evaluations, 2 * K)
    if J is None:
        return plan, spent
    found = _compiled(engine.team_search(model, plan, J, max_evaluations, spent, fractions=tuple(fractions)),
                      plan) if compiled else None
    if found is not None:
        return found
    best = plan
    starts, goals = np.asarray(model.starts)[:, None], np.asarray(model.goals)[:, None]  # (N, 1, 3)
    rows = np.arange(K)
    for fraction in fractions:
        while spent + N * 2 * K <= max_evaluations:
            full = np.concatenate([starts, best, goals], axis=1)  # (N, K + 2, 3)
            cands = np.repeat(best[None], 2 * K, axis=0)  # (2K, N, K, 3): towards k - 1, then k + 1
            cands[rows, :, rows] += fraction * (full[:, :K] - best).transpose(1, 0, 2)
            cands[K + rows, :, rows] += fraction * (full[:, 2:] - best).transpose(1, 0, 2)
            cands = np.clip(cands, model.lower, model.upper)
            c = engine.evaluate(model, cands)
            spent += N * 2 * K
            better = _dominating(c, J)
            if not better.any():
                break
            i = np.flatnonzero(better)[np.argmin(_in_order(c.total[better] / J, np.multiply))]
            best, J = cands[i], c.total[i]
    return best, spent


SHIFT_STEP = 2.0
"""First step (m) of :func:`team_shift`; it halves down to :data:`~staghunt.solvers.local.POLISH_MIN_STEP`."""
SHIFT_PASSES = 3
"""Most rounds of :func:`team_shift` then slide and polish in :func:`team_refine`."""


def shift_moves(K: int) -> np.ndarray:
    """``(3 K (K + 1), 1, K, 3)`` the unit moves of :func:`team_shift`: every block of consecutive
    waypoints ``a .. b - 1`` (``0 <= a < b <= K``) moved by ``+-1`` along one axis."""
    a, b = np.triu_indices(K + 1, k=1)  # every block [a, b)
    k = np.arange(K)
    inside = (k[None] >= a[:, None]) & (k[None] < b[:, None])  # (blocks, K)
    axes = np.eye(3)  # (3, 3)
    moves = inside[:, None, :, None] * axes[None, :, None, :]  # (blocks, 3, K, 3)
    moves = moves.reshape(-1, K, 3)
    return np.concatenate([moves, -moves])[:, None]


def team_shift(model: CostModel, plan: np.ndarray, max_evaluations: int, engine: CostEngine = NUMPY_COSTS,
               step: float = SHIFT_STEP, min_step: float = POLISH_MIN_STEP) -> tuple[np.ndarray, int]:
    """Pareto-improving pattern search over *blocks* of the team's route: each sweep evaluates
    the ``3 K (K + 1)`` plans with a block of consecutive waypoints (one to all ``K``) of *every*
    UAV moved by ``+-step`` along one axis (:func:`shift_moves`; the formation's shape kept) and
    takes, among the feasible ones that Pareto-dominate the plan (no UAV worse, one better, eq.
    (9a)), the one with the least ``sum_n ln J_n`` (as in :func:`team_slide`); else ``step``
    halves, down to ``min_step`` metres.

    The turning and climb terms (eqs. 2d, 2e) sum *changes* of direction between segments: a
    route whose waypoints wiggle by a metre pays for every wiggle, and moving one waypoint
    (:func:`team_polish`) straightens one bend only by bending its neighbours, so that search
    stops on such a route; moving the whole wiggly stretch at once removes it (scenario 1,
    rigid seeds of 500 particles x 100 iterations, seeds 1-20, after the slide and polish: both
    followers' ``J_n`` within 204, near the family's lower edge of 202, on 10 seeds; 16 after up
    to three rounds of shift, slide and polish). Returns the ``(N, K, 3)`` plan (``plan`` itself if nothing
    improved) and the path evaluations spent (``N`` per candidate, ``<= max_evaluations``)."""
    N, K = plan.shape[0], plan.shape[1]
    moves = shift_moves(K)
    J, spent = _team_search_start(model, plan, engine, max_evaluations, len(moves))
    if J is None:
        return plan, spent
    best = plan
    while step >= min_step and spent + N * len(moves) <= max_evaluations:
        cands = np.clip(best[None] + step * moves, model.lower, model.upper)  # (M, N, K, 3)
        c = engine.evaluate(model, cands)
        spent += N * len(moves)
        better = _dominating(c, J)
        if not better.any():
            step /= 2
            continue
        i = np.flatnonzero(better)[np.argmin(_in_order(c.total[better] / J, np.multiply))]
        best, J = cands[i], c.total[i]
    return best, spent


def team_refine(model: CostModel, plan: np.ndarray, each: int, left: int,
                engine: CostEngine = NUMPY_COSTS) -> tuple[np.ndarray, int]:
    """:func:`team_slide`, then :func:`team_polish`; then, while ``each`` covers a sweep of
    :func:`team_shift`, up to :data:`SHIFT_PASSES` rounds of a team shift followed by another
    slide and polish, as long as the shift improves. Each search has at most ``each`` path
    evaluations, all together at most ``left``. Every step leaves no UAV worse off. Returns the
    ``(N, K, 3)`` plan (``plan`` itself if nothing improved) and the evaluations spent."""
    slid, spent = team_slide(model, plan, min(each, left), engine)
    best, used = team_polish(model, slid, min(each, left - spent), engine)
    spent += used
    sweep = plan.shape[0] * len(shift_moves(plan.shape[1]))  # path evaluations of one team_shift sweep
    for _ in range(SHIFT_PASSES if each >= 2 * sweep else 0):
        shifted, used = team_shift(model, best, min(each, left - spent), engine)
        spent += used
        if shifted is best:
            break
        slid, used = team_slide(model, shifted, min(each, left - spent), engine)
        spent += used
        best, used = team_polish(model, slid, min(each, left - spent), engine)
        spent += used
    return best, spent


POWELL_XTOL = 1e-2
"""Line-search tolerance (m) of :func:`team_powell`."""
POWELL_FTOL = 1e-5
"""Powell stops when a sweep of its directions lowers ``sum_n ln J_n`` by less than this share."""


def team_powell(model: CostModel, plan: np.ndarray, max_evaluations: int,
                engine: CostEngine = NUMPY_COSTS) -> tuple[np.ndarray, int]:
    """Pareto-improving descent of the team's route by SciPy's Powell method (conjugate
    directions, derivative-free): it minimises ``sum_n ln J_n`` over one move ``(K, 3)`` common
    to every UAV's free waypoints (the formation's shape kept, ``3 K`` variables), a move that
    leaves the plan infeasible or any UAV worse off than in ``plan`` scoring worse than every
    admissible one. Deterministic; one plan ``(N, K, 3)`` per evaluation.

    The pattern searches (:func:`team_polish`, :func:`team_slide`, :func:`team_shift`) move along
    fixed directions with a halving step and stop in the narrow valleys that the turning and
    climb terms (eqs. 2d, 2e) make, where a step along any one direction makes some UAV worse;
    Powell's line searches along directions it builds from its progress go down them (scenario
    1 at 500 x 300, seeds 1, 15, 17: followers from 204-205 to 202 after the pattern searches had
    stopped, in 9,000-17,000 plans). Moving each UAV on its own as well (``(N + 1) 3 K``
    variables) gained 0-0.5 % more at the paper's budget for 10,000 plans more: not done.
    Returns the best plan found that Pareto-dominates ``plan`` (feasible, no UAV worse, one better
    by more than :data:`ACCEPT_TOL`; ``plan`` itself if none) and the path evaluations spent
    (``N`` per plan, ``<= max_evaluations``)."""
    from scipy.optimize import minimize  # SciPy's optimiser loads only when a run polishes

    N, K = plan.shape[0], plan.shape[1]
    J_start, spent = _team_search_start(model, plan, engine, max_evaluations, 1)
    if J_start is None:
        return plan, spent
    state = {"spent": spent, "best": plan, "key": float(preference(J_start[None], np.zeros(1))[0][0])}
    lower, upper = np.broadcast_to(model.lower, plan.shape), np.broadcast_to(model.upper, plan.shape)

    class _Spent(Exception):
        pass

    def objective(x: np.ndarray) -> float:
        if state["spent"] + N > max_evaluations:
            raise _Spent
        candidate = np.clip(plan + x.reshape(1, K, 3), lower, upper)
        c = engine.evaluate(model, candidate[None])
        state["spent"] += N
        if c.total_violation[0] != 0 or np.any(c.total[0] > J_start):
            return 1e6 + float(c.total_violation[0])
        key = float(preference(c.total, c.total_violation)[0][0])
        if key < state["key"] and _dominating(c, J_start)[0]:
            state.update(best=candidate, key=key)
        return key

    try:  # the budget, not Powell's own limits, ends the search if it has not converged
        minimize(objective, np.zeros(3 * K), method="Powell",
                 options={"xtol": POWELL_XTOL, "ftol": POWELL_FTOL, "maxfev": 10**9, "maxiter": 10**9})
    except _Spent:
        pass
    return state["best"], int(state["spent"])
