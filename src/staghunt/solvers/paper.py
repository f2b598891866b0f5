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

import numpy as np

from staghunt.costs import CostModel, Evaluator, evaluate
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.base import SolverOutput, register
from staghunt.solvers.problem import team_problem
from staghunt.solvers.swarm import Progress, SwarmRunner, run_swarm


def solve_team(
    scenario: Scenario,
    settings: SolverSettings,
    rng: np.random.Generator,
    progress: Progress | None,
    runner: SwarmRunner,
    objective: Literal["players", "sum"],
) -> SolverOutput:
    """One swarm per UAV moving jointly; ``objective`` ``"players"`` (the game: Pareto dominance
    over the ``J_n``) or ``"sum"`` (centralised: ``sum_n J_n``)."""
    model = CostModel.from_scenario(scenario)
    problem = team_problem(model, settings.waypoints, settings.velocity_fraction, objective)
    out = runner(problem, settings, rng, progress)
    return SolverOutput(
        waypoints=out.best_waypoints,
        history=out.record_history,
        objective_history=out.history,
        evaluations=out.path_evaluations,
    )


@register("paper", "the paper's Algorithm 1: one swarm per UAV, Pareto-dominance bests (no equilibrium guarantee)")
def solve_paper(
    scenario: Scenario,
    settings: SolverSettings,
    rng: np.random.Generator,
    progress: Progress | None = None,
    *,
    runner: SwarmRunner = run_swarm,
    evaluator: Evaluator = evaluate,
) -> SolverOutput:
    return solve_team(scenario, settings, rng, progress, runner, "players")
