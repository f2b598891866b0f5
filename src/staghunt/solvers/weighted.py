"""``weighted``: the centralised cooperative baseline of MODEL.md section 6.

One optimiser over all paths: ``S = N`` swarms move jointly (joint particle ``i`` = particle
``i`` of every swarm = all ``N`` paths) and the single compared objective is the team's summed
cost ``sum_n J_n`` (plain single-objective SPSO, ``C = 1``, with the feasibility-first rule of
:mod:`staghunt.solvers.dominance`). It differs from ``game`` only in what is compared: a sum
instead of Pareto dominance, so one UAV may be made worse off if the team gains.

Output: ``history``: ``(I + 1, N)`` each UAV's ``J_n`` of the best allocation;
``objective_history``: ``(I + 1, 1)`` its ``sum_n J_n``; ``evaluations``: ``particles * (I + 1)``
joint evaluations of ``N`` paths each, counted as ``N`` single-UAV path evaluations each.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from staghunt.costs import CostModel
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.base import SolverOutput, register
from staghunt.solvers.problem import team_problem
from staghunt.solvers.swarm import Progress, run_swarm


@register("weighted", "centralised weighted sum: one swarm over all paths minimising sum_n J_n (baseline)")
def solve_weighted(
    scenario: Scenario,
    settings: SolverSettings,
    rng: np.random.Generator,
    progress: Progress | None = None,
    *,
    engine: Any = None,
    threads: int | None = None,
) -> SolverOutput:
    """``engine``: ``None`` for the NumPy reference loop, else an engine or engine name for
    :func:`staghunt.engine.get_engine` (with ``threads``)."""
    model = CostModel.from_scenario(scenario)
    problem = team_problem(model, settings.waypoints, settings.velocity_fraction, "sum")
    out = _runner(engine, threads)(problem, settings, rng, progress)
    return SolverOutput(
        waypoints=problem.team_waypoints(out.best[None])[0],
        history=out.record_history,
        objective_history=out.history,
        evaluations=out.particle_evaluations * model.n_uavs,  # N paths vary per joint particle
    )


def _runner(engine: Any, threads: int | None) -> Any:
    """The ``run_swarm`` of the requested engine (``None``: the NumPy reference loop)."""
    if engine is None:
        return run_swarm
    from staghunt.engine import get_engine  # imported here: staghunt.engine imports the solvers

    return get_engine(engine, threads).run_swarm
