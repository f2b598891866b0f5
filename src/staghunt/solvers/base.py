"""What every method returns to :func:`staghunt.plan`, and the registry of methods."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol

import numpy as np

from staghunt.costs import Evaluator, evaluate

from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.swarm import Progress, SwarmRunner, run_swarm


@dataclass(frozen=True, eq=False)
class SolverOutput:
    """``waypoints``: ``(N, K, 3)`` ``(x, y, h)``; ``history``: ``(I + 1, N)`` per-UAV ``J_n`` of
    the best allocation; ``objective_history``: ``(I + 1, C)``; ``evaluations``: single-UAV path
    evaluations (summed ``SwarmOutcome.path_evaluations``); ``leader_path``: virtual leader's absolute ``(K + 2, 3)`` path, if any;
    ``details``: what the method wants recorded about its search (plain JSON-able data)."""

    waypoints: np.ndarray
    history: np.ndarray
    objective_history: np.ndarray
    evaluations: int
    leader_path: np.ndarray | None = None
    details: Mapping[str, Any] = field(default_factory=dict)


class Method(Protocol):
    """A method: ``(scenario, settings, rng, progress, *, runner) -> SolverOutput``.

    ``evaluator`` (an engine's ``evaluate``, contract of :func:`staghunt.costs.evaluate`) scores
    batches of given plans, for methods that search outside a swarm (``game``'s polish).
    Every method builds one or more :class:`~staghunt.solvers.problem.SwarmProblem` and hands
    them to ``runner`` (:func:`~staghunt.solvers.swarm.run_swarm`, the NumPy reference, or an
    engine's ``run_swarm``), so every engine runs every method.
    """

    def __call__(
        self,
        scenario: Scenario,
        settings: SolverSettings,
        rng: np.random.Generator,
        progress: Progress | None = None,
        *,
        runner: SwarmRunner = run_swarm,
        evaluator: Evaluator = evaluate,
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
