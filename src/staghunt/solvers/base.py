"""What every method returns to :func:`staghunt.plan`, and the registry of methods."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.swarm import Progress


@dataclass(frozen=True, eq=False)
class SolverOutput:
    """``waypoints``: ``(N, K, 3)`` ``(x, y, h)``; ``history``: ``(I + 1, N)`` per-UAV ``J_n`` of
    the best allocation; ``objective_history``: ``(I + 1, C)``; ``evaluations``: single-UAV path
    evaluations; ``leader_path``: virtual leader's absolute ``(K + 2, 3)`` path, if any."""

    waypoints: np.ndarray
    history: np.ndarray
    objective_history: np.ndarray
    evaluations: int
    leader_path: np.ndarray | None = None


Method = Callable[[Scenario, SolverSettings, np.random.Generator, "Progress | None"], SolverOutput]

METHODS: dict[str, Method] = {}
DESCRIPTIONS: dict[str, str] = {}


def register(name: str, description: str) -> Callable[[Method], Method]:
    """Decorator adding a method to the registry under ``name``."""

    def wrap(fn: Method) -> Method:
        METHODS[name] = fn
        DESCRIPTIONS[name] = description
        return fn

    return wrap
