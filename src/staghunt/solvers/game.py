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
   ``epsilon`` leaves a plan that the certificate accepts; before the certificate is asked,
   every UAV makes the certificate's own local search (:data:`LOCAL_CHECK_EVALUATIONS`), and a
   gain beyond ``epsilon`` is taken as a reply instead.

The plan returned is the last allocation; :func:`staghunt.plan` then certifies it with an
independent search (:mod:`staghunt.solvers.response`). The run's ``details`` say what happened:
rounds, accepted replies, reply budgets and each round's largest relative gain.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from staghunt.costs import CostEngine, CostModel, evaluate
from staghunt.encoding import ANGLE_RANGE, encode
from staghunt.solvers.base import MethodRun, SolverOutput, register
from staghunt.solvers.dominance import dominates
from staghunt.solvers.finish import descent_fits, finish
from staghunt.solvers.independent import solo_model
from staghunt.solvers.local import (  # noqa: F401  (formation_target, polish: re-exported)
    ACCEPT_TOL, LocalSearch, formation_target, local_pass, polish,
)
from staghunt.solvers.problem import solo_problem, team_problem
from staghunt.solvers.response import (DEFAULT_EPSILON, DEFAULT_ITERATIONS, DEFAULT_PARTICLES, Certificate,
                                       LOCAL_SHARE as CERTIFICATE_LOCAL_SHARE)
from staghunt.solvers.selection import Candidate, select, summary as _summary
from staghunt.solvers.team_search import (  # noqa: F401  (re-exported)
    SLIDE_FRACTIONS, team_polish, team_refine, team_slide,
)
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
GROW_BELOW = 0.005
"""Double the reply budget after a round whose largest relative gain is below this."""
STOP_FRACTION = 0.25
"""Converged: a verification-strength round with every gain below ``epsilon * STOP_FRACTION``."""
EPSILON = DEFAULT_EPSILON
"""The relative Nash gap the method aims below (the certificate's default tolerance)."""
VERIFY_EVALUATIONS = DEFAULT_PARTICLES * (DEFAULT_ITERATIONS + 1)
"""A reply search at least this strong (the default certificate's) may declare convergence."""
LOCAL_CHECK_EVALUATIONS = int(CERTIFICATE_LOCAL_SHARE * VERIFY_EVALUATIONS)
"""Budget of each UAV's local search before a certificate is asked (the default certificate's own)."""
MIN_REPLY_ITERATIONS = 5
POLISH_SHARE = 0.25
"""Share of a reply's budget for the local polish of the swarm's best (:func:`polish`)."""
RIGID_MIN_ITERATIONS = 100
"""Least iterations of the rigid seed of a search with several starts, in runs of at least three
times as many iterations (shorter runs, measured nowhere, keep :data:`SEED_SHARE`): the formation
route it finds is where the selected equilibrium usually lies, and with :data:`SEED_SHARE` alone
a small run's seed (30 iterations at 500 x 300) ends on the right corridor but far above its
best route, or on a worse corridor."""
FINISH_SHARE = 0.01
"""Share of the budget a search with several starts keeps for its finish
(:func:`~staghunt.solvers.finish.finish`) if that covers twice the Powell descent's
:data:`~staghunt.solvers.finish.POWELL_PLANS` plans (else nothing is kept): the starts' rounds
otherwise spend it all."""
TEAM_POLISH_SHARE = 0.02
"""Most of the budget one :func:`team_polish` (or :func:`team_slide`) may spend (it usually needs far less)."""


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



def _warm_particles(problem_space, start: np.ndarray, paths: list[np.ndarray], rng: np.random.Generator,
                    particles: int) -> np.ndarray:
    """``(W, 1, K, 3)`` spherical warm particles: ``paths`` (current first) encoded, then
    perturbations of the current one."""
    enc = encode(np.stack(paths)[:, None], start, problem_space)  # (len(paths), 1, K, 3), in one call
    local = int(LOCAL_SHARE * particles)
    if local > 0:
        lo, hi = problem_space.lower[0], problem_space.upper[0]  # (3,)
        noise = rng.normal(0.0, LOCAL_SPREAD, size=(local, 1, enc.shape[2], 3)) * (hi - lo)
        enc = np.concatenate([enc, np.clip(enc[0][None] + noise, lo, hi)])
    return enc[:particles]


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
                         rng: np.random.Generator, runner: SwarmRunner, engine: CostEngine,
                         budget: int, spent: int = 0,
                         on_reply: Callable[[int, np.ndarray], None] | None = None,
                         repair: bool = False, reply_start: float = REPLY_START,
                         azimuth: float = ANGLE_RANGE,
                         certified: Callable[..., bool] | None = None, workers: int = 1) -> RoundsOutcome:
    """Steps 2-4 of the method from the allocation ``plan`` ``(N, K, 3)``: best-response
    rounds until they converge or ``budget`` path evaluations (``spent`` of them already used)
    are spent: the replies' swarms run by ``runner``, their polish and every plan judged by
    ``engine``. ``on_reply(spent, J)`` follows every reply.

    ``repair``: the starting plan may be infeasible (a re-plan warm-started from a plan that a
    new obstacle cuts): while the plan is infeasible, a reply is accepted when it lowers the
    plan's total violation, and counts as a full gain; once feasible, the usual rule applies.
    Without ``repair`` only feasible improvements are ever accepted. ``reply_start``: the first
    reply budget as a share of the budget left (a warm re-plan starts near an equilibrium and
    gains from few strong replies rather than many weak ones). ``azimuth``: half-width of the
    replies' heading range (:func:`~staghunt.encoding.search_space`). ``certified(plan,
    searched=)``: after a round that leaves the plan feasible with no reply gaining more than
    :data:`EPSILON`, first lets every UAV make a local search (:func:`polish`,
    :data:`LOCAL_CHECK_EVALUATIONS`, counted in the budget; ``workers`` of them side by side,
    :func:`~staghunt.solvers.local.local_pass`) and takes a gain beyond :data:`EPSILON` as a
    reply (the round's ``local_check_gains``); otherwise asks whether the plan is a certified
    equilibrium, handing it these searches (the certificate's own from the plan), and if so
    the rounds stop (converged; the round's ``certified`` flag says so). The certificate is not
    counted in the budget."""
    N, P = model.n_uavs, settings.particles
    plan = np.array(plan, dtype=float)
    current = engine.evaluate(model, plan[None])
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
            candidate, used = polish(model, candidate, n, local, engine)
            c = engine.evaluate(model, candidate[None])  # the reply judged as a whole plan: 1 more path
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
            # Before the certificate: each UAV's local search from the plan, the one the
            # certificate also makes (a quarter of its default budget); a gain beyond epsilon is
            # a better reply, taken, and the rounds go on without a certificate that would fail.
            done = local_pass(model, plan, J, LOCAL_CHECK_EVALUATIONS, EPSILON, engine, budget - spent, workers)
            plan, J, local_gains, spent = done.plan, done.costs, done.gains, spent + done.evaluations
            accepted += int(np.count_nonzero(local_gains))
            gains = np.maximum(gains, local_gains)  # no growth of the replies after a gain
            rounds[-1]["local_check_gains"] = local_gains.tolist()
            if not local_gains.any():
                rounds[-1]["certified"] = converged = bool(certified(plan, searched=done.searches))
        if gains.max() < GROW_BELOW:
            reply_evals *= 2
    return RoundsOutcome(plan, J, int(spent), rounds, accepted, converged)


START_KINDS = ("rigid", "independent", "weighted", "random")
"""The starts of the search, in order; beyond these, :data:`MORE_STARTS` in turn."""
MORE_STARTS = ("weighted", "rigid")
"""Starts after the first four: a weighted start descends the team's cost from the best
equilibrium found so far (an iterated local search), a rigid one draws another formation route."""


def _start_plan(kind: str, model: CostModel, settings: SolverSettings, rng: np.random.Generator,
                runner: SwarmRunner, progress: Progress | None,
                best: np.ndarray | None = None) -> tuple[np.ndarray, int, np.ndarray | None]:
    """The ``(N, K, 3)`` allocation a start begins from, the path evaluations it cost and the
    seed swarm's per-UAV record ``(iterations + 1, N)`` (``None`` if it has none). Every kind
    spends ``settings.particles * (settings.iterations + 1) * N`` evaluations but ``random``
    (one draw, one evaluation per UAV):

    - ``rigid``: the rigid-formation plan (:mod:`staghunt.solvers.rigid`): feasible, in formation;
    - ``independent``: every UAV's own ``J_s`` optimum alone (the hares; may collide);
    - ``weighted``: the team's summed cost, all paths jointly, warm-started from ``best`` (the
      best equilibrium so far, if any) and :data:`LOCAL_SHARE` of perturbations of it;
    - ``random``: one uniform draw of every UAV's path in its spherical search space."""
    K, vf, N = settings.waypoints, settings.velocity_fraction, model.n_uavs
    if kind == "rigid":
        out = runner(rigid_problem(model, K, vf), settings, rng, progress)
        return np.array(out.best_waypoints), out.path_evaluations, out.record_history
    if kind == "independent":
        plan = np.empty((N, K, 3))
        spent = 0
        for n in range(N):
            out = runner(team_problem(solo_model(model, n), K, vf), settings, rng, None)
            plan[n] = out.best_waypoints[0]
            spent += out.path_evaluations
        return plan, spent, None
    if kind == "weighted":
        problem = team_problem(model, K, vf, "sum")
        warm = None
        if best is not None:  # descend the team's sum from the best equilibrium so far (and near it)
            enc = encode(best[None], problem.starts, problem.space)  # (1, N, K, 3)
            lo, hi = problem.space.lower[None, :, None, :], problem.space.upper[None, :, None, :]
            local = int(LOCAL_SHARE * settings.particles)
            noise = rng.normal(0.0, LOCAL_SPREAD, size=(local, *enc.shape[1:])) * (hi - lo)
            warm = np.concatenate([enc, np.clip(enc + noise, lo, hi)])[: settings.particles]
        out = runner(problem, settings, rng, None, warm)
        return np.array(out.best_waypoints), out.path_evaluations, out.record_history
    problem = team_problem(model, K, vf)
    return problem.team_waypoints(problem.space.sample(rng, 1, K))[0], N, None


def _start_kind(s: int) -> str:
    return START_KINDS[s] if s < len(START_KINDS) else MORE_STARTS[(s - len(START_KINDS)) % len(MORE_STARTS)]



@register("game", "stag-hunt game solved to an equilibrium: best-response rounds from several starts, "
          "payoff-dominant selection (default)")
def solve_game(run: MethodRun) -> SolverOutput:
    """Best-response rounds from ``settings.starts`` starts (:data:`START_KINDS` in order), each
    with an equal share of the budget left; the best equilibrium is selected
    (:mod:`staghunt.solvers.selection`).

    With one start this is the single-start method (the rigid seed, then rounds until
    convergence or the budget). With several (docs/model.md section 6.1), the rigid seed runs
    at least :data:`RIGID_MIN_ITERATIONS`; each start is first team-refined
    (:func:`team_refine`: slide, polish, block shifts; no UAV worse off) and, if already
    certified, a candidate of its own; its rounds then stop as soon as their plan is a certified
    equilibrium (``run.certify``; without certificates, on the rounds' own rule), so the budget
    a start does not need goes to the next ones. A plan that a certified candidate dominates is
    not certified (it can be neither selected nor needed to judge payoff dominance). At the end
    (:func:`~staghunt.solvers.finish.finish`) the selected plan is team-refined and the best
    plan that failed its certificate repaired from it; the selection is made again. What a
    search with several starts leaves unspent is left (``unspent_evaluations``): the time saved
    is the point."""
    scenario, settings, rng, progress = run.scenario, run.settings, run.rng, run.progress
    runner, engine = run.runner, run.engine
    model = CostModel.from_scenario(scenario)
    N, P, I, S = model.n_uavs, settings.particles, settings.iterations, settings.starts
    budget = P * (I + 1) * N
    history = np.full((I + 1, N), np.nan)
    unit = P * N  # evaluations per row of history
    rigid_iters, extra = max(0, int(SEED_SHARE * (I + 1)) - 1), 0
    if S > 1 and (I + 1) // 3 >= RIGID_MIN_ITERATIONS:  # the rigid seed of several starts in a run of
        # 300 iterations or more: at least RIGID_MIN_ITERATIONS (less one if that is more than a third
        # of the run's), the iterations beyond its share added to the first start's (its rounds keep theirs)
        extra = max(0, min(RIGID_MIN_ITERATIONS, (I + 1) // 3 - 1) - rigid_iters)
        rigid_iters, extra = rigid_iters + extra, extra * unit
    seed_settings = settings.with_(iterations=max(0, int(SEED_SHARE * (I + 1) / S) - 1))
    state = {"row": 0}

    def record(spent_now: int, J_now: np.ndarray) -> None:
        last = min(I + 1, spent_now // unit)
        history[state["row"]:last] = J_now
        state["row"] = max(state["row"], last)
        if progress is not None:
            progress(min(I, max(0, last - 1)), I, J_now.copy())

    def certificate(plan: np.ndarray, searched: tuple[LocalSearch, ...] = ()) -> Certificate | None:
        """``run.certify``'s, stopped at its first refutation (only the verdict matters here)."""
        return run.certify(plan, searched=searched, refute=True) if run.certify is not None else None

    def needed(J: np.ndarray) -> bool:
        """Whether a certificate of a feasible plan with costs ``J`` ``(N,)`` can matter: not if a
        certified candidate Pareto-dominates it (then it is neither selected nor needed to judge
        payoff dominance)."""
        return not any(c.certified and bool(dominates(c.J, 0.0, J, 0.0)) for c in candidates)

    # A single start keeps its stopping rule (the run's); several stop at their first certified plan.
    explore_stop = run.certified if S == 1 else (
        (lambda wp, searched=(): needed(evaluate(model, wp[None]).total[0]) and certificate(wp, searched).is_equilibrium)
        if run.certify is not None else None)
    # stop="certified" (run.certified): the run itself ends at its first certified equilibrium,
    # with the starts after it left unsearched.
    first_certified = run.certified is not None and S > 1
    spent = 0
    candidates: list[Candidate] = []
    starts: list[dict[str, Any]] = []
    # Several starts keep the finish its evaluations where it can make the Powell descent (solvers/finish.py).
    reserve = int(FINISH_SHARE * budget)
    reserve = reserve if S > 1 and descent_fits(reserve, N) else 0
    for s in range(S):
        kind = _start_kind(s)
        cap = spent + (budget - reserve - spent) // (S - s) + (extra if s == 0 else 0)
        before = spent
        seed_progress = _Rows(progress, I) if progress is not None and s == 0 else None
        best = candidates[select(candidates, EPSILON).chosen].plan if candidates else None
        # The rigid seed keeps the single-start method's share of the whole budget: the team's
        # payoff-dominant equilibria tend to lie on the best formation routes it searches.
        kind_settings = settings.with_(iterations=rigid_iters) if kind == "rigid" else seed_settings
        start, used, seed_history = _start_plan(kind, model, kind_settings, rng, runner, seed_progress, best)
        spent += used
        if s == 0:
            seed_evaluations = int(used)
        if s == 0 and seed_history is not None:
            history[: rigid_iters + 1] = seed_history
            state["row"] = rigid_iters + 1
        else:
            record(spent, evaluate(model, start[None]).total[0])
        if S > 1:
            start, used = team_refine(model, start, int(TEAM_POLISH_SHARE * budget), cap - spent, engine)
            spent += used
            # The start itself may already be an equilibrium (the rigid plan often is): a candidate
            # of its own, whatever equilibrium the rounds then reach from it.
            c = evaluate(model, start[None])
            cert = certificate(start) if c.total_violation[0] == 0 and needed(c.total[0]) else None
            if cert is not None and cert.is_equilibrium:
                candidates.append(Candidate(kind + " (start)", start, c.total[0], 0.0, cert, spent - before))
                if first_certified:
                    starts.append({"start": kind, "rounds": [], "accepted_replies": 0, "converged": True,
                                   "evaluations": int(spent - before)})
                    break
        out = best_response_rounds(model, start, settings, rng, runner, engine, cap, spent, record,
                                   repair=kind != "rigid", certified=explore_stop, workers=run.workers)
        spent = out.evaluations
        c = evaluate(model, out.plan[None])
        cert = certificate(out.plan) if c.total_violation[0] == 0 and needed(c.total[0]) else None
        candidates.append(Candidate(kind, out.plan, c.total[0], float(c.total_violation[0]), cert, spent - before))
        starts.append({"start": kind, "rounds": out.rounds, "accepted_replies": out.accepted,
                       "converged": out.converged, "evaluations": int(spent - before)})
        if first_certified and cert is not None and cert.is_equilibrium:
            break

    chosen = candidates[select(candidates, EPSILON).chosen]
    stopped = first_certified and chosen.certificate is not None and chosen.certificate.is_equilibrium
    if S > 1 and not stopped:
        # The selected plan down to the lower edge of its family, and the plan that would beat
        # it repaired from its certificate (solvers/finish.py): more candidates.
        used = finish(model, candidates, certificate, engine, int(TEAM_POLISH_SHARE * budget), budget - spent, EPSILON)
        spent += used
        starts.append({"start": "polish", "rounds": [], "accepted_replies": 0, "converged": True,
                       "evaluations": int(used)})
    selection = select(candidates, EPSILON)
    plan, J = candidates[selection.chosen].plan, candidates[selection.chosen].J
    row = state["row"]
    history[row:] = J
    if progress is not None:
        progress(I, I, J.copy())
    first = starts[0]
    details: dict[str, Any] = {
        "seed": "rigid",
        "seed_evaluations": seed_evaluations,
        "rounds": first["rounds"],
        "accepted_replies": first["accepted_replies"],
        "converged": first["converged"],
        "unspent_evaluations": int(budget - spent),
    }
    if S > 1:
        details["starts"] = starts
        details["equilibria"] = [
            {**_summary(candidates[i]), "dominated": d, "selected": i == selection.chosen,
             "same": [j for j, home in enumerate(selection.same_as) if home == i and j != i]}
            for i, d in zip(selection.equilibria, selection.dominated)]
        details["candidates"] = [_summary(c) for c in candidates]
        # A run stopped at its first certified equilibrium compared it with nothing: no claim.
        rule = ("first certified equilibrium (stop='certified'): the starts after it were not searched"
                if stopped else selection.rule)
        details["selection"] = {"payoff_dominant": selection.payoff_dominant and not stopped, "rule": rule,
                                "found": len(selection.equilibria), "starts": S,
                                "starts_searched": sum(st["start"] != "polish" for st in starts),
                                "stopped_at_first_certified": bool(stopped),
                                "selected_start": candidates[selection.chosen].start}
    return SolverOutput(
        waypoints=plan,
        history=history,
        objective_history=history.copy(),
        evaluations=int(spent),
        details=details,
    )
