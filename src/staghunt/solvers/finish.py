"""The end of ``game``'s search with several starts (docs/model.md section 6.1, step 4): the
selected plan taken down to the lower edge of its family, and the one plan that would beat it,
had it passed its certificate, repaired from what its certificate found.

1. **Polish.** The selected equilibrium gets a team refine
   (:func:`~staghunt.solvers.team_search.team_refine`: slide, polish and block shifts, no UAV
   worse off), then, in a run large enough, a Powell descent of the team's route
   (:func:`~staghunt.solvers.team_search.team_powell`, :data:`POWELL_PLANS` plans); the result
   is one more candidate, certified (it dominates the one it came from).
2. **Repair.** The candidate the selection would prefer to the one it has, the feasible plan
   with the least ``sum_n ln J_n`` below the selected one's (any, if no candidate is certified)
   that has failed its certificate (often the polished plan of step 1: lower on the family, but
   one UAV now has a better reply),
   is repaired: the better replies its certificate found are adopted in turn (largest gap first,
   each kept if it still gains more than ``epsilon`` with those already kept and the plan stays
   feasible), the team refine follows, and the result is certified again; up to
   :data:`REPAIR_ROUNDS` times, while it fails. Each certified result is one more candidate.

The certificates may stop at their first refutation (``certify_plan``'s ``refute``): a failed
one's better replies are those found until then (the replies of the UAVs searched). On the 80
three-start runs of ``benchmarks/equilibria.py`` (both budgets, 2026-11-27) every plan selected
was the same as with full certificates. Every step asks only certificates; the selection among the candidates is
:func:`staghunt.solvers.selection.select`'s.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from staghunt.costs import CostEngine, CostModel
from staghunt.solvers.dominance import preference
from staghunt.solvers.response import Certificate
from staghunt.solvers.selection import Candidate, select
from staghunt.solvers.team_search import team_powell, team_refine

REPAIR_ROUNDS = 2
"""Most certificates of the repair (each after adopting the last one's better replies)."""
POWELL_PLANS = 10_000
"""Plans the Powell descent of the selected plan may evaluate (:func:`team_powell`, ``N`` path
evaluations each): it runs only if the finish has at least twice that left of the run's budget
(the rest is the repair's), so in runs of at least ``2 * POWELL_PLANS / FINISH_SHARE`` team
evaluations (:data:`staghunt.solvers.game.FINISH_SHARE`; the paper's budget, not 500 x 300)."""


def descent_fits(evaluations: int, n_uavs: int) -> bool:
    """Whether ``evaluations`` left for the finish make room for the Powell descent of a team of
    ``n_uavs``: twice its :data:`POWELL_PLANS` plans (the rest is the repair's)."""
    return evaluations >= 2 * POWELL_PLANS * n_uavs


def adopt_replies(model: CostModel, plan: np.ndarray, cert: Certificate,
                  engine: CostEngine) -> tuple[np.ndarray | None, int, int]:
    """``plan`` ``(N, K, 3)`` with the better replies of its failed ``cert`` adopted in turn
    (largest relative gap first), each kept if the plan stays feasible and the UAV gains more than
    the certificate's ``epsilon`` with the replies already kept. Returns the plan (``None`` if
    none is kept), the replies kept and the path evaluations spent (``N`` per plan judged).
    Moving each UAV half way towards its reply first, a damped best response, was tried in the
    flight's certify-and-improve rounds and not kept (benchmarks/JOURNAL.md, "Closed loop: half
    steps towards the replies, not kept")."""
    N = plan.shape[0]
    team, J = plan.copy(), engine.evaluate(model, plan[None]).total[0]
    spent, taken = N, 0
    for n in sorted(range(N), key=lambda m: -cert.uavs[m].relative):
        u = cert.uavs[n]
        if u.relative <= cert.epsilon or u.deviation is None:
            continue
        candidate = team.copy()
        candidate[n] = u.deviation
        c = engine.evaluate(model, candidate[None])
        spent += N
        if c.total_violation[0] == 0 and c.total[0][n] < (1.0 - cert.epsilon) * J[n]:
            team, J, taken = candidate, c.total[0], taken + 1
    return (team if taken else None), taken, spent


def _logs(J: np.ndarray) -> float:
    """``sum_n ln J_n`` of a feasible plan's costs ``(N,)`` (the selection's tie-break key)."""
    return float(preference(J, np.float64(0.0))[0])


def finish(model: CostModel, candidates: list[Candidate], certificate: Callable[[np.ndarray], Certificate | None],
           engine: CostEngine, each: int, left: int, epsilon: float) -> int:
    """Steps 1-2 of the module docstring on ``candidates`` (appended to in place); ``certificate``
    certifies a plan (``None``: no certificates, then only step 1, uncertified); the team refines
    spend at most ``each`` per search and everything at most ``left`` path evaluations. Returns
    the evaluations spent."""
    spent = 0
    chosen = candidates[select(candidates, epsilon).chosen]

    def add(name: str, plan: np.ndarray, cert: Certificate | None, used: int) -> Candidate:
        c = engine.evaluate(model, plan[None])
        candidate = Candidate(name, plan, c.total[0], float(c.total_violation[0]), cert, used)
        candidates.append(candidate)
        return candidate

    polished, used = team_refine(model, chosen.plan, each, left, engine)
    spent += used
    if descent_fits(left - spent, model.n_uavs):
        polished, more = team_powell(model, polished, POWELL_PLANS * model.n_uavs, engine)
        spent, used = spent + more, used + more
    if polished is not chosen.plan:
        add(chosen.start + " (polished)", polished, certificate(polished), used)
    chosen = candidates[select(candidates, epsilon).chosen]
    bound = _logs(chosen.J) if chosen.certified else np.inf  # none certified: any failed one
    below = [c for c in candidates if c.violation == 0 and c.certificate is not None
             and not c.certified and _logs(c.J) < bound]
    if not below:
        return spent
    target = min(below, key=lambda c: _logs(c.J))
    plan, cert, name = target.plan, target.certificate, target.start + " (repaired)"
    before = spent
    for _ in range(REPAIR_ROUNDS):
        assert cert is not None
        adopted, _, used = adopt_replies(model, plan, cert, engine)
        spent += used
        if adopted is None or spent >= left:
            break
        plan, used = team_refine(model, adopted, each, left - spent, engine)
        spent += used
        cert = certificate(plan)
        if cert is None:
            break
        if cert.is_equilibrium:
            add(name, plan, cert, spent - before)
            break
    return spent
