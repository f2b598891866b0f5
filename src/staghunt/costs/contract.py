"""What the solvers may ask of an engine: the cost side of the engine's contract.

:class:`CostEngine` declares every capability a solver uses, and :class:`NumpyCosts` is the
NumPy reference's answer to each: ``name`` (whose arithmetic: two searches in the same
arithmetic make the same decisions), ``prepare`` (compile or load; the seconds it took),
``evaluate`` (:func:`staghunt.costs.evaluate`'s contract), ``team_search`` (the team's slide or
polish in one call) and ``deviations`` (one UAV's deviation costs, with its polish in one call).
``None`` from ``team_search`` or ``deviations`` means "no shortcut here": the solver runs its
Python loop, the reference, which makes the same decisions. The engines (:mod:`staghunt.engine`)
add ``run_swarm``; this part sits below the solvers, which receive an engine through it.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from staghunt.costs.evaluate import Costs, evaluate
from staghunt.costs.model import CostModel


class Deviation(Protocol):
    """UAV ``n``'s deviations from a feasible plan ``(N, K, 3)``, the others' paths fixed
    (the compiled one: :class:`staghunt.engine.deviations.Deviations`)."""

    def __call__(self, paths: np.ndarray) -> np.ndarray:
        """``(Q,)`` ``J_n`` of UAV ``n`` flying each of ``paths`` ``(Q, K, 3)``; ``inf`` where the
        plan is then infeasible (bit-identical to the full evaluation's)."""
        ...

    def polish(self, J: float, max_evaluations: int, step: float, min_step: float) -> tuple[np.ndarray, float, int]:
        """:func:`staghunt.solvers.local.polish` of UAV ``n``'s path (cost ``J``), with the same
        decisions: the ``(K, 3)`` path reached, its ``J_n`` and the evaluations spent."""
        ...


@runtime_checkable
class CostEngine(Protocol):
    """The capabilities a solver may use of an engine (module docstring); :class:`NumpyCosts`
    is the reference's answer to each."""

    name: str

    def prepare(self) -> float:
        """Compile or load what a run needs now; the seconds it took (0.0: nothing to do)."""
        ...

    def evaluate(self, model: CostModel, waypoints: np.ndarray) -> Costs:
        """Costs of ``(P, N, K, 3)`` team plans: the contract of :func:`staghunt.costs.evaluate`."""
        ...

    def team_search(self, model: CostModel, plan: np.ndarray, costs: np.ndarray, max_evaluations: int, spent: int,
                    fractions: tuple[float, ...] = (), step: float = 0.0,
                    min_step: float = 0.0) -> tuple[np.ndarray, int] | None:
        """:func:`staghunt.solvers.team_search.team_slide` (by ``fractions``, if any) or
        :func:`~staghunt.solvers.team_search.team_polish` (``step`` down to ``min_step``) of the
        feasible ``plan`` ``(N, K, 3)`` with costs ``costs`` ``(N,)`` and ``spent`` evaluations so
        far, in one call: the ``(N, K, 3)`` plan reached and the evaluations spent in all;
        ``None``: no such shortcut now (the caller's loop makes the same decisions)."""
        ...

    def deviations(self, model: CostModel, plan: np.ndarray, n: int, costs: Costs | None = None) -> Deviation | None:
        """UAV ``n``'s deviation evaluator from the feasible ``plan`` ``(N, K, 3)`` (``costs``:
        this engine's :meth:`evaluate` of ``plan[None]``, if the caller has it); ``None``: none
        (the caller evaluates whole plans)."""
        ...


class NumpyCosts:
    """The NumPy reference's answers (:class:`CostEngine`): ``name`` ``"numpy"``, ``evaluate`` is
    :func:`staghunt.costs.evaluate` itself, nothing to prepare (0.0 s), and no shortcuts
    (``team_search`` and ``deviations`` answer ``None``: the solvers' loops are the reference)."""

    name = "numpy"
    evaluate = staticmethod(evaluate)

    def prepare(self) -> float:
        return 0.0

    def team_search(self, model: CostModel, plan: np.ndarray, costs: np.ndarray, max_evaluations: int, spent: int,
                    fractions: tuple[float, ...] = (), step: float = 0.0,
                    min_step: float = 0.0) -> tuple[np.ndarray, int] | None:
        return None

    def deviations(self, model: CostModel, plan: np.ndarray, n: int, costs: Costs | None = None) -> Deviation | None:
        return None

    def __repr__(self) -> str:
        return "NumpyCosts()"


NUMPY_COSTS = NumpyCosts()
"""The reference, the solvers' default engine."""
