"""``rigid``: the rigid-formation baseline (Chen et al. 2015), docs/model.md section 6.

A virtual leader flies from the centroid of the starts to the centroid of the goals (SPSO, one
swarm); the members keep the reference shape rigidly around it: member ``n``'s free waypoint
``k`` is the leader's plus the fixed offset ``o_n = P_r,n - mean(P_r)`` (in ``(x, y, h)``). The
leader's box is shrunk by the offsets so that every member stays inside the site. The swarm
minimises the team's summed cost ``sum_n J_n`` of the member paths, so every member, not only
the centre, must clear the obstacles; that sum is what the paper calls the virtual UAV's cost.
"""

from __future__ import annotations

import numpy as np

from staghunt.costs import CostModel, to_absolute
from staghunt.encoding import decode, search_space
from staghunt.solvers.base import MethodRun, SolverOutput, register
from staghunt.solvers.problem import SwarmProblem


class FormationTooLarge(ValueError):
    """The reference shape does not fit in the site box."""


def formation_offsets(model: CostModel) -> np.ndarray:
    """``(N, 3)`` offsets of the members from the virtual leader in ``(x, y, h)``."""
    return model.reference - model.reference.mean(axis=0)


@register("rigid", "rigid formation: one virtual leader, members at fixed offsets (baseline)")
def solve_rigid(run: MethodRun) -> SolverOutput:
    scenario, settings, rng, progress, runner = run.scenario, run.settings, run.rng, run.progress, run.runner
    model = CostModel.from_scenario(scenario)
    problem = rigid_problem(model, settings.waypoints, settings.velocity_fraction)
    out = runner(problem, settings, rng, progress)
    leader = decode(out.best[None], problem.starts, problem.lower, problem.upper)[0, 0]  # (K, 3)
    goal = model.goals.mean(axis=0, keepdims=True)
    leader_full = np.concatenate([problem.starts, leader, goal], axis=0)
    return SolverOutput(
        waypoints=out.best_waypoints,
        history=out.record_history,
        objective_history=out.history,
        evaluations=out.path_evaluations,
        leader_path=to_absolute(model.terrain, leader_full),
    )


def rigid_problem(model: CostModel, waypoints: int, velocity_fraction: float) -> SwarmProblem:
    """One swarm for the virtual leader; every member follows it at its fixed offset."""
    off = formation_offsets(model)
    lower = model.lower - off.min(axis=0)
    upper = model.upper - off.max(axis=0)
    if np.any(lower > upper):
        raise FormationTooLarge("the reference formation is larger than the site box")
    start = model.starts.mean(axis=0, keepdims=True)
    goal = model.goals.mean(axis=0, keepdims=True)
    return SwarmProblem(
        model=model,
        space=search_space(start, goal, waypoints, velocity_fraction),
        starts=start,
        lower=lower[None],
        upper=upper[None],
        member_of=np.zeros(model.n_uavs, dtype=np.intp),
        offsets=off,
        objective="sum",
        players=tuple(range(model.n_uavs)),
    )
