"""What every method returns to :func:`staghunt.plan`, and the registry of methods."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from staghunt.costs import NUMPY_COSTS, CostEngine
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.requests import RequestError, check_seed  # noqa: F401  (re-exported)
from staghunt.solvers.swarm import Progress, SwarmRunner, run_swarm

if TYPE_CHECKING:  # annotations only
    from staghunt.solvers.response import Certificate


@dataclass(frozen=True, eq=False)
class SolverOutput:
    """``waypoints``: ``(N, K, 3)`` ``(x, y, h)``; ``history``: ``(I + 1, N)`` per-UAV ``J_n`` of
    the best allocation; ``objective_history``: ``(I + 1, C)``; ``evaluations``: single-UAV path
    evaluations (summed ``SwarmOutcome.path_evaluations``); ``leader_path``: virtual leader's
    absolute ``(K + 2, 3)`` path, if any; ``details``: what the method wants recorded about its search (plain JSON-able data)."""

    waypoints: np.ndarray
    history: np.ndarray
    objective_history: np.ndarray
    evaluations: int
    leader_path: np.ndarray | None = None
    details: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class MethodRun:
    """What a method is given: the ``scenario``, the ``settings`` (its budget), the run's one
    seeded ``rng``, an optional ``progress`` callback, and the engine: ``runner`` runs a
    :class:`~staghunt.solvers.problem.SwarmProblem` (:func:`~staghunt.solvers.swarm.run_swarm`,
    the NumPy reference, or an engine's ``run_swarm``), so every engine runs every method;
    ``engine`` is the engine itself through the part of its contract the solvers use
    (:class:`staghunt.costs.CostEngine`: its ``evaluate`` scores batches of given plans, its
    ``team_search`` and ``deviations`` make ``game``'s local searches in one call where it has
    them; default: the NumPy reference). ``certified``: if given,
    a method that can stop early (``game``) asks it whether an intermediate plan ``(N, K, 3)`` is
    already a certified equilibrium and stops when it is (``None``: the usual stopping rule).
    ``certify``: if given (the run is certified), the certificate of a plan ``(N, K, 3)``, made
    with the run's certificate options and not counted in the budget (``game`` certifies each
    start's equilibrium to select among them); ``None``: no certificates. Both take, after the
    plan, the local searches already made from it (:class:`~staghunt.solvers.local.LocalSearch`,
    ``searched=``), which the certificate takes instead of making them again; ``certify`` also
    takes ``refute=True``: a certificate that may stop at its first refutation
    (:func:`~staghunt.solvers.response.certify_plan`), completed if asked for in full later. ``workers``:
    independent searches (``game``'s local check) that may run side by side, one thread each
    (``engine`` is then thread-safe)."""

    scenario: Scenario
    settings: SolverSettings
    rng: np.random.Generator
    progress: Progress | None = None
    runner: SwarmRunner = run_swarm
    engine: CostEngine = NUMPY_COSTS
    certified: Callable[..., bool] | None = None
    certify: Callable[..., Certificate] | None = None
    workers: int = 1


Method = Callable[[MethodRun], SolverOutput]
"""A planning method: ``MethodRun -> SolverOutput``."""


METHODS: dict[str, Method] = {}
DESCRIPTIONS: dict[str, str] = {}


def register(name: str, description: str) -> Callable[[Any], Any]:
    """Decorator adding a method to the registry under ``name``."""

    def wrap(fn: Any) -> Any:
        METHODS[name] = fn
        DESCRIPTIONS[name] = description
        return fn

    return wrap
