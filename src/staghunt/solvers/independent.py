"""``independent``: the "hare" strategy of docs/model.md section 6.

Every UAV minimises its own single-UAV cost ``J_s`` alone, ignoring the team: no formation term
and no team-mates (so no separation constraint either). That is ``N`` separate single-UAV SPSO
runs, one after the other, each with ``settings.particles`` particles and ``settings.iterations``
iterations, all drawing from the one generator of the run (UAV 1's run first). Each run works on
a one-UAV cost model cut out of the team's (:func:`solo_model`).

The plan is then scored by :func:`staghunt.plan` with the *team's* ``J_n`` like every other
method, so it may well be infeasible (two hares colliding) and pay a large formation cost: that
is the point of the baseline.

Output, with ``I`` iterations and ``N`` UAVs:

- ``objective_history``: ``(I + 1, N)``; column ``n`` is UAV ``n``'s own best ``J_s`` after
  initialisation and after each iteration of its own run (what that run compared).
- ``history``: ``(I + 1, N)``; rows ``0 .. I - 1`` are the same own ``J_s`` values, and the last
  row is the team's ``J_n`` of the final allocation, evaluated once at the end (so that, as for
  every method, ``history[-1]`` equals the plan's ``J_n``). The jump in the last row is the
  formation cost (and any collision) the hares did not look at.
- ``evaluations``: ``N * particles * (I + 1)`` single-UAV path evaluations (one path varies per
  particle), the same budget as a joint method's ``particles * (I + 1)`` joint evaluations of
  ``N`` paths each.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from staghunt.costs import CostModel, evaluate
from staghunt.solvers.base import MethodRun, SolverOutput, register
from staghunt.solvers.problem import team_problem
from staghunt.solvers.swarm import Progress


def solo_model(model: CostModel, n: int) -> CostModel:
    """The one-UAV cost model of UAV ``n`` alone: its start, goal, radius and weights, the same
    world, no formation edges (``N x 0`` incidence) and ``beta = 0``, so ``J = J_s``."""
    one = slice(n, n + 1)
    no_edges = np.zeros((1, 0))
    arrays = {
        "starts": model.starts[one],
        "goals": model.goals[one],
        "start_abs": model.start_abs[one],
        "goal_abs": model.goal_abs[one],
        "radius": model.radius[one],
        "beta": np.zeros(1),
        "weights": model.weights[one],
        "heads": np.zeros(0, dtype=np.intp),
        "tails": np.zeros(0, dtype=np.intp),
        "mu": no_edges,
        "ref_diff": np.zeros((0, 3)),
        "reference": model.reference[one],
    }
    frozen = {}
    for key, value in arrays.items():
        a = np.array(value, copy=True)
        a.setflags(write=False)
        frozen[key] = a
    return dataclasses.replace(model, **frozen)


class _Offset:
    """Progress of UAV ``n``'s run reported as part of the ``N`` runs in a row."""

    def __init__(self, progress: Progress, n: int, n_uavs: int, iterations: int) -> None:
        self.progress, self.n, self.n_uavs, self.iterations = progress, n, n_uavs, iterations

    def __call__(self, iteration: int, total: int, best_cost: np.ndarray) -> None:
        self.progress(self.n * self.iterations + iteration, self.n_uavs * self.iterations, best_cost)


@register("independent", "hare strategy: each UAV minimises its own J_s alone, ignoring the team (baseline)")
def solve_independent(run: MethodRun) -> SolverOutput:
    scenario, settings, rng, progress, runner = run.scenario, run.settings, run.rng, run.progress, run.runner
    model = CostModel.from_scenario(scenario)
    N, K = model.n_uavs, settings.waypoints
    waypoints = np.empty((N, K, 3))
    own = np.empty((settings.iterations + 1, N))
    evaluations = 0
    for n in range(N):
        problem = team_problem(solo_model(model, n), K, settings.velocity_fraction, "players")
        report = None if progress is None else _Offset(progress, n, N, settings.iterations)
        out = runner(problem, settings, rng, report)
        waypoints[n] = out.best_waypoints[0]
        own[:, n] = out.history[:, 0]
        evaluations += out.path_evaluations
    history = own.copy()
    history[-1] = evaluate(model, waypoints[None]).total[0]
    return SolverOutput(
        waypoints=waypoints,
        history=history,
        objective_history=own,
        evaluations=evaluations,
    )
