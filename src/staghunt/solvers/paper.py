"""``paper``: the stag-hunt game-based SPSO of the paper (Algorithm 1), unchanged.

One swarm per UAV; particle ``i`` of every swarm forms joint allocation ``i``; each allocation is
scored by every player's ``J_n = J_s + beta_n J_f``; personal and global bests move only to
Pareto-dominating allocations. The paper expects this to drive the team to a payoff-dominant
equilibrium; it does not: no UAV ever best-responds, so the search stops at allocations that no
*team* move improves for all at once, which are neither equilibria nor better than the rigid
baseline (docs/compare.md). Kept to reproduce the paper; the default method is ``game``
(:mod:`staghunt.solvers.game`).
"""

from __future__ import annotations

from typing import Literal

from staghunt.costs import CostModel
from staghunt.solvers.base import MethodRun, SolverOutput, register
from staghunt.solvers.problem import team_problem


def solve_team(run: MethodRun, objective: Literal["players", "sum"]) -> SolverOutput:
    """One swarm per UAV moving jointly; ``objective`` ``"players"`` (the game: Pareto dominance
    over the ``J_n``) or ``"sum"`` (centralised: ``sum_n J_n``)."""
    model = CostModel.from_scenario(run.scenario)
    s = run.settings
    problem = team_problem(model, s.waypoints, s.velocity_fraction, objective)
    out = run.runner(problem, s, run.rng, run.progress)
    return SolverOutput(
        waypoints=out.best_waypoints,
        history=out.record_history,
        objective_history=out.history,
        evaluations=out.path_evaluations,
    )


@register("paper", "the paper's Algorithm 1: one swarm per UAV, Pareto-dominance bests (no equilibrium guarantee)")
def solve_paper(run: MethodRun) -> SolverOutput:
    return solve_team(run, "players")
