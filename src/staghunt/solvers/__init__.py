"""Solvers: every method is a function ``(scenario, settings, rng, progress) -> SolverOutput``
registered in :data:`METHODS`."""

from staghunt.solvers import game, independent, paper, rigid, weighted  # noqa: F401  (registers the methods)  # noqa: F401  (registers the baselines)
from staghunt.solvers.base import DESCRIPTIONS, METHODS, SolverOutput, register

__all__ = ["DESCRIPTIONS", "METHODS", "SolverOutput", "register"]
