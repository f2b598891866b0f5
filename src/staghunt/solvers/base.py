"""What every method returns to :func:`staghunt.plan`, and the registry of methods."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Protocol

import numpy as np

from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.swarm import Progress

if TYPE_CHECKING:
    from staghunt.engine import Engine


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


class Method(Protocol):
    """A method: ``(scenario, settings, rng, progress, *, engine, threads) -> SolverOutput``.

    ``engine``: what runs its swarm loops: ``None`` (the NumPy reference loop), an engine or an
    engine name for :func:`staghunt.engine.get_engine` (with ``threads``); every method is a
    :class:`~staghunt.solvers.problem.SwarmProblem`, so every engine runs every method.
    """

    def __call__(
        self,
        scenario: Scenario,
        settings: SolverSettings,
        rng: np.random.Generator,
        progress: Progress | None = None,
        *,
        engine: "Engine | str | None" = None,
        threads: int | None = None,
    ) -> SolverOutput: ...


METHODS: dict[str, Method] = {}
DESCRIPTIONS: dict[str, str] = {}


def register(name: str, description: str) -> Callable[[Any], Any]:
    """Decorator adding a method to the registry under ``name``."""

    def wrap(fn: Any) -> Any:
        METHODS[name] = fn
        DESCRIPTIONS[name] = description
        return fn

    return wrap
