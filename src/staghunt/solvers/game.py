"""``game`` (the default): the stag hunt solved to an equilibrium by best-response dynamics.

Every UAV is a player minimising its own ``J_n = J_s + beta_n J_f`` given the others' paths
(docs/model.md, the game). The paper's Algorithm 1 (``paper``) never lets a UAV best-respond, so
it stops at allocations that are neither equilibria nor better than the rigid baseline. This
method searches for an equilibrium directly, within the same budget as every other method,
``B = particles * (iterations + 1) * N`` single-UAV path evaluations, all drawn from the run's
one generator:

1. **Seed** (:data:`SEED_SHARE` of ``B``): the rigid-formation plan (:mod:`staghunt.solvers.rigid`),
   a feasible allocation with zero formation error that no UAV can improve much alone.
2. **Best-response rounds**: the UAVs in turn re-optimise their own path with the others fixed
   (single-UAV SPSO on ``J_n``, :func:`~staghunt.solvers.problem.solo_problem`), warm-started from
   the current path, the UAV's earlier replies, its :func:`formation_target` and perturbations of
   the current path (:data:`LOCAL_SHARE` of the particles), then refined by :func:`polish` (a
   pattern search in the site frame, :data:`POLISH_SHARE` of the reply's budget). A reply
   replaces the path only if the plan stays feasible and ``J_n`` drops by more than
   :data:`ACCEPT_TOL` (relative). With the paper's
   symmetric edge weights the game is a weighted potential game (docs/model.md, eq. (17)):
   every accepted reply lowers ``Phi = sum_n J_s,n / beta_n + 1/2 sum_n J_f,n``, so the rounds
   cannot cycle.
3. **Reply budget**: it starts at :data:`REPLY_START` of the remaining budget per reply and
   doubles whenever a round lowers no UAV's cost by more than :data:`GROW_BELOW`; a small
   search that finds nothing is no evidence of an equilibrium.
4. **Stop**: after a round in which no UAV gains more than ``epsilon *`` :data:`STOP_FRACTION`
   with a reply search at least as strong as the certificate's (:data:`VERIFY_EVALUATIONS`), or
   when the budget is spent (the remainder goes to a last round). Optionally
   (``staghunt.plan(..., stop="certified")``) also as soon as a round with every gain below
   ``epsilon`` leaves a plan that the certificate accepts.

The plan returned is the last allocation; :func:`staghunt.plan` then certifies it with an
independent search (:mod:`staghunt.solvers.response`). The run's ``details`` say what happened:
rounds, accepted replies, reply budgets and each round's largest relative gain.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from staghunt.costs import CostModel, Evaluator, evaluate, to_absolute
from staghunt.encoding import ANGLE_RANGE, encode
from staghunt.solvers.base import MethodRun, SolverOutput, register
from staghunt.solvers.problem import solo_problem
from staghunt.solvers.response import DEFAULT_EPSILON, DEFAULT_ITERATIONS, DEFAULT_PARTICLES
from staghunt.solvers.rigid import rigid_problem
from staghunt.scenario.model import SolverSettings
from staghunt.solvers.swarm import Progress, SwarmRunner

SEED_SHARE = 0.10
"""Share of the budget spent on the rigid seed."""
REPLY_START = 0.01
"""First reply budget (per UAV) as a share of the budget left after the seed."""
REPLY_PARTICLES = 50
"""Least particles of a reply search (fewer only if the run's ``particles`` is smaller)."""
REPLY_ITERATIONS = 100
"""Iterations a reply search aims at: larger reply budgets get more particles rather than more
iterations (a swarm's per-iteration overhead is paid once per iteration); 0 = always the least."""
LOCAL_SHARE = 0.25
"""Share of a reply's particles started near the UAV's current path."""
LOCAL_SPREAD = 0.05
"""Standard deviation of those perturbations, as a share of each spherical range."""
ACCEPT_TOL = 1e-9
"""A reply is accepted if it lowers ``J_n`` by more than this (relative)."""
GROW_BELOW = 0.005
"""Double the reply budget after a round whose largest relative gain is below this."""
STOP_FRACTION = 0.25
"""Converged: a verification-strength round with every gain below ``epsilon * STOP_FRACTION``."""
EPSILON = DEFAULT_EPSILON
"""The relative Nash gap the method aims below (the certificate's default tolerance)."""
VERIFY_EVALUATIONS = DEFAULT_PARTICLES * (DEFAULT_ITERATIONS + 1)
"""A reply search at least this strong (the default certificate's) may declare convergence."""
MIN_REPLY_ITERATIONS = 5
POLISH_SHARE = 0.25
"""Share of a reply's budget for the local polish of the swarm's best (:func:`polish`)."""
POLISH_STEP = 1.0
POLISH_MIN_STEP = 1e-3
"""Initial and final coordinate step (m) of the polish."""


class _Rows:
    """The seed's progress reported on the whole run's scale (``total`` rows)."""

    def __init__(self, progress: Progress, total: int) -> None:
        self.progress, self.total = progress, total

    def __call__(self, iteration: int, total: int, best_cost: np.ndarray) -> None:
        self.progress(iteration, self.total, best_cost)


def _reply_shape(evaluations: int, particles: int) -> tuple[int, int]:
    """``(particles, iterations)`` of a reply's swarm search spending about ``evaluations``."""
    p = REPLY_PARTICLES
    if REPLY_ITERATIONS > 0:
        p = max(p, evaluations // (REPLY_ITERATIONS + 1))
    p = max(1, min(particles, p))
    iterations = max(MIN_REPLY_ITERATIONS, evaluations // p - 1)
    return p, iterations


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


def polish(model: CostModel, plan: np.ndarray, n: int, max_evaluations: int,
           evaluator: Evaluator = evaluate, step: float = POLISH_STEP,
           min_step: float = POLISH_MIN_STEP) -> tuple[np.ndarray, int]:
    """Local pattern search on UAV ``n``'s free waypoints in the site frame, the others fixed.

    The spherical encoding moves every later waypoint with each step, so a swarm refines a
    path poorly; this moves one coordinate at a time. Each sweep evaluates the ``6 K`` paths
    with one coordinate of one waypoint moved by ``+-step`` (clamped to the site box) and the
    path combining every improving move; the best feasible one that lowers ``J_n`` is taken,
    else ``step`` halves, down to ``min_step`` metres. Returns the ``(N, K, 3)`` plan (``plan``
    itself if nothing improved) and the path evaluations spent (``<= max_evaluations``).
    ``evaluator`` scores the candidates (an engine's ``evaluate``); the plan's own cost is
    taken with the same evaluator, so every comparison is made in one arithmetic.
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


def _warm_particles(problem_space, start: np.ndarray, paths: list[np.ndarray], rng: np.random.Generator,
                    particles: int) -> np.ndarray:
    """``(W, 1, K, 3)`` spherical warm particles: ``paths`` (current first) encoded, then
    perturbations of the current one."""
    enc = [encode(p[None, None], start, problem_space)[0] for p in paths]  # each (1, K, 3)
    local = int(LOCAL_SHARE * particles)
    if local > 0:
        lo, hi = problem_space.lower[0], problem_space.upper[0]  # (3,)
        noise = rng.normal(0.0, LOCAL_SPREAD, size=(local, 1, enc[0].shape[1], 3)) * (hi - lo)
        enc.extend(np.clip(enc[0][None] + noise, lo, hi))
    return np.stack(enc)[:particles]


@dataclass(frozen=True, eq=False)
class RoundsOutcome:
    """What :func:`best_response_rounds` ends with: the ``(N, K, 3)`` ``plan``, its ``(N,)``
    ``costs`` ``J_n`` (``inf`` while infeasible), the path ``evaluations`` counted so far
    (including those spent before the rounds), the ``rounds`` (one dict each), the
    ``accepted`` replies and whether the rounds ``converged``."""

    plan: np.ndarray
    costs: np.ndarray
    evaluations: int
    rounds: list[dict[str, Any]]
    accepted: int
    converged: bool


def best_response_rounds(model: CostModel, plan: np.ndarray, settings: SolverSettings,
                         rng: np.random.Generator, runner: SwarmRunner, evaluator: Evaluator,
                         budget: int, spent: int = 0,
                         on_reply: Callable[[int, np.ndarray], None] | None = None,
                         repair: bool = False, reply_start: float = REPLY_START,
                         azimuth: float = ANGLE_RANGE,
                         certified: Callable[[np.ndarray], bool] | None = None) -> RoundsOutcome:
    """Steps 2-4 of the method from the allocation ``plan`` ``(N, K, 3)``: best-response
    rounds until they converge or ``budget`` path evaluations (``spent`` of them already used)
    are spent. ``on_reply(spent, J)`` follows every reply.

    ``repair``: the starting plan may be infeasible (a re-plan warm-started from a plan that a
    new obstacle cuts): while the plan is infeasible, a reply is accepted when it lowers the
    plan's total violation, and counts as a full gain; once feasible, the usual rule applies.
    Without ``repair`` only feasible improvements are ever accepted. ``reply_start``: the first
    reply budget as a share of the budget left (a warm re-plan starts near an equilibrium and
    gains from few strong replies rather than many weak ones). ``azimuth``: half-width of the
    replies' heading range (:func:`~staghunt.encoding.search_space`). ``certified(plan)``:
    after a round that leaves the plan feasible with no reply gaining more than
    :data:`EPSILON`, asks whether the plan is a certified equilibrium, and if so the rounds stop
    (converged; the round's ``certified`` flag says so). The check is not counted in the
    budget."""
    N, P = model.n_uavs, settings.particles
    plan = np.array(plan, dtype=float)
    current = evaluate(model, plan[None])
    J, violation = current.total[0], float(current.total_violation[0])
    replies: list[list[np.ndarray]] = [[plan[n].copy()] for n in range(N)]
    remaining = budget - spent
    reply_evals = max(int(reply_start * remaining), P)
    rounds: list[dict[str, Any]] = []
    accepted = 0
    converged = False
    while not converged:
        remaining = budget - spent
        per_reply = min(reply_evals, remaining // N - 1)
        local = int(POLISH_SHARE * per_reply)
        p_r, i_r = _reply_shape(per_reply - local, P)
        if N * (p_r * (i_r + 1) + local + 1) > remaining:
            break
        reply_settings = settings.with_(particles=p_r, iterations=i_r)
        gains = np.zeros(N)
        for n in range(N):
            problem = solo_problem(model, plan, n, settings.velocity_fraction, azimuth)
            paths = [*replies[n][::-1], formation_target(model, plan, n)]
            warm = _warm_particles(problem.space, problem.starts, paths, rng, p_r)
            out = runner(problem, reply_settings, rng, None, warm)
            spent += out.path_evaluations
            candidate = plan.copy()
            candidate[n] = out.best_waypoints[n]
            candidate, used = polish(model, candidate, n, local, evaluator)
            c = evaluate(model, candidate[None])  # the reply judged by the reference: 1 more path
            spent += used + 1
            new, new_violation = c.total[0], float(c.total_violation[0])
            if violation > 0:
                better = repair and new_violation < violation
            else:
                better = new_violation == 0 and new[n] < J[n] * (1.0 - ACCEPT_TOL)
            if better:
                gains[n] = 1.0 if violation > 0 else (J[n] - new[n]) / J[n]
                plan, J, violation = candidate, new, new_violation
                replies[n].append(plan[n].copy())
                del replies[n][:-4]
                accepted += 1
            if on_reply is not None:
                on_reply(spent, J)
        strong = p_r * (i_r + 1) + local >= VERIFY_EVALUATIONS
        rounds.append({"reply_particles": p_r, "reply_iterations": i_r,
                       "max_relative_gain": float(gains.max()), "relative_gains": gains.tolist(),
                       "verification": bool(strong)})
        converged = bool(strong and (violation == 0 or not repair) and gains.max() <= EPSILON * STOP_FRACTION)
        if certified is not None and not converged and violation == 0 and gains.max() <= EPSILON:
            rounds[-1]["certified"] = converged = bool(certified(plan))
        if gains.max() < GROW_BELOW:
            reply_evals *= 2
    return RoundsOutcome(plan, J, int(spent), rounds, accepted, converged)


@register("game", "stag-hunt game solved to an equilibrium: rigid seed, then best-response rounds (default)")
def solve_game(run: MethodRun) -> SolverOutput:
    scenario, settings, rng, progress = run.scenario, run.settings, run.rng, run.progress
    runner, evaluator = run.runner, run.evaluator
    model = CostModel.from_scenario(scenario)
    N, K, P, I = model.n_uavs, settings.waypoints, settings.particles, settings.iterations
    budget = P * (I + 1) * N
    history = np.full((I + 1, N), np.nan)
    unit = P * N  # evaluations per row of history

    # 1. Seed: the rigid formation.
    seed_iters = max(0, int(SEED_SHARE * (I + 1)) - 1)
    seed_settings = settings.with_(iterations=seed_iters)
    seed = runner(rigid_problem(model, K, settings.velocity_fraction), seed_settings, rng,
                  None if progress is None else _Rows(progress, I))
    spent = seed.path_evaluations
    history[: seed_iters + 1] = seed.record_history
    plan = np.array(seed.best_waypoints)

    # 2.-4. Best-response rounds.
    state = {"row": seed_iters + 1}

    def record(spent_now: int, J_now: np.ndarray) -> None:
        last = min(I + 1, spent_now // unit)
        history[state["row"]:last] = J_now
        state["row"] = max(state["row"], last)
        if progress is not None:
            progress(min(I, max(0, last - 1)), I, J_now.copy())

    out = best_response_rounds(model, plan, settings, rng, runner, evaluator, budget, spent, record,
                               certified=run.certified)
    plan, J, spent, row = out.plan, out.costs, out.evaluations, state["row"]
    history[row:] = J
    if progress is not None:
        progress(I, I, J.copy())
    details = {
        "seed": "rigid",
        "seed_evaluations": int(seed.path_evaluations),
        "rounds": out.rounds,
        "accepted_replies": out.accepted,
        "converged": out.converged,
        "unspent_evaluations": int(budget - spent),
    }
    return SolverOutput(
        waypoints=plan,
        history=history,
        objective_history=history.copy(),
        evaluations=int(spent),
        details=details,
    )
