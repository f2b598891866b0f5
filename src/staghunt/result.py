"""The immutable outcome of a planning run."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from staghunt.checks import Metrics
from staghunt.costs import Costs
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.response import Certificate


class Status(str, Enum):
    """What a plan is worth.

    - ``FEASIBLE``: every hard constraint holds (obstacles, ground, separation along segments);
      all costs are finite.
    - ``INFEASIBLE``: the best plan found violates a hard constraint; ``message`` says which.
    """

    FEASIBLE = "feasible"
    INFEASIBLE = "infeasible"


@dataclass(frozen=True, eq=False)
class PlanResult:
    """A plan for ``N`` UAVs with ``K`` free waypoints.

    - ``waypoints``: ``(N, K, 3)`` free waypoints ``(x, y, h)``, ``h`` above ground.
    - ``paths``: ``(N, K + 2, 3)`` absolute ``(x, y, z)`` from start to goal.
    - ``heights``: ``(N, K + 2)`` height above ground along the path.
    - ``costs``: :class:`~staghunt.costs.Costs` of this allocation with ``P = 1``.
    - ``history``: ``(iterations + 1, N)`` each UAV's ``J_n`` of the best allocation after
      initialisation and after each iteration.
    - ``objective_history``: ``(iterations + 1, C)`` what the solver compared (``C = N`` for the
      game; ``C = 1``, the team's summed cost, for single-objective methods).
    - ``evaluations``: single-UAV path evaluations spent (a joint evaluation of ``N`` paths counts ``N``).
    - ``leader_path``: ``(K + 2, 3)`` absolute path of the virtual leader (``rigid`` only, else ``None``).
    - ``certificate``: the equilibrium certificate (each UAV's Nash gap and the verdict), if
      the plan was certified; ``wall_time_s`` times the search alone, ``certificate_time_s``
      the certificate and ``compile_time_s`` a one-time compilation of the engine before it.
    - ``details``: what the method recorded about its search (``game``: rounds, accepted
      replies, reply budgets, convergence), plain JSON-able data.
    - ``engine``: the engine that ran the swarms (``"numpy"`` or ``"numba"``); the engines draw
      different random streams, so a plan is reproduced by the same seed *and* engine.
    """

    method: str
    seed: int
    status: Status
    message: str
    scenario: Scenario
    settings: SolverSettings
    waypoints: np.ndarray
    paths: np.ndarray
    heights: np.ndarray
    costs: Costs
    metrics: Metrics
    history: np.ndarray
    objective_history: np.ndarray
    evaluations: int
    wall_time_s: float
    leader_path: np.ndarray | None = None
    engine: str = "numpy"
    details: Mapping[str, Any] = field(default_factory=dict)
    certificate: Certificate | None = None
    compile_time_s: float = 0.0
    certificate_time_s: float = 0.0

    @property
    def feasible(self) -> bool:
        return self.status is Status.FEASIBLE

    @property
    def uav_names(self) -> list[str]:
        return [u.name for u in self.scenario.team]
