"""``weighted``: the centralised cooperative baseline of docs/model.md section 6.

One optimiser over all paths: ``S = N`` swarms move jointly (joint particle ``i`` = particle
``i`` of every swarm = all ``N`` paths) and the single compared objective is the team's summed
cost ``sum_n J_n`` (plain single-objective SPSO, ``C = 1``, with the feasibility-first rule of
:mod:`staghunt.solvers.dominance`). It differs from ``game`` only in what is compared: a sum
instead of Pareto dominance, so one UAV may be made worse off if the team gains.

Output: ``history``: ``(I + 1, N)`` each UAV's ``J_n`` of the best allocation;
``objective_history``: ``(I + 1, 1)`` its ``sum_n J_n``.
"""

from __future__ import annotations

from staghunt.solvers.base import MethodRun, SolverOutput, register
from staghunt.solvers.paper import solve_team


@register("weighted", "centralised weighted sum: one swarm over all paths minimising sum_n J_n (baseline)")
def solve_weighted(run: MethodRun) -> SolverOutput:
    return solve_team(run, "sum")
