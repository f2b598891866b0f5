"""Batched costs: single-UAV terms (eq. 2), formation cost (eqs. 5-7) and ``J_n`` (eq. 4)."""

from staghunt.costs.contract import NUMPY_COSTS, CostEngine, Deviation, NumpyCosts
from staghunt.costs.evaluate import TERM_NAMES, VIOLATION_NAMES, Costs, Evaluator, evaluate, formation_cost
from staghunt.costs.model import CostModel, full_paths, to_absolute

__all__ = [
    "CostEngine",
    "Deviation",
    "NUMPY_COSTS",
    "NumpyCosts",
    "Evaluator",
    "TERM_NAMES",
    "VIOLATION_NAMES",
    "CostModel",
    "Costs",
    "evaluate",
    "formation_cost",
    "full_paths",
    "to_absolute",
]
