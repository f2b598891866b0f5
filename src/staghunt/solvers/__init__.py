"""Solvers: every method is a function ``MethodRun -> SolverOutput`` (:mod:`staghunt.solvers.base`:
the scenario, settings, the run's one seeded generator, progress and the engine, its runner and
the part of its contract the solvers use, :class:`staghunt.costs.CostEngine`, in one
:class:`~staghunt.solvers.base.MethodRun`), registered in :data:`METHODS` with :func:`register`."""

from staghunt.solvers import game, independent, paper, rigid, weighted  # noqa: F401  (registers the methods)
from staghunt.solvers.base import DESCRIPTIONS, METHODS, SolverOutput, register

__all__ = ["DESCRIPTIONS", "METHODS", "SolverOutput", "register"]
