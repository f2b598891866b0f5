"""Pareto dominance between joint allocations, with a feasibility-first rule for ``inf`` costs.

Shapes: ``C`` players (objectives). ``cost``: ``(..., C)``; ``violation``: ``(...,)`` total
constraint violation (0 = feasible).

Rule (docs/model.md section 5, eq. (9b)): a feasible allocation has finite costs; an infeasible one has some
``inf``. Then ``a`` dominates ``b`` when

- both are feasible and ``cost_a <= cost_b`` everywhere and ``<`` somewhere (paper eq. 9); or
- ``b`` is infeasible and ``a`` violates less (``violation_a < violation_b``; a feasible ``a``
  has 0). Infeasible allocations are thus never compared on their ``inf`` costs, so they cannot
  drift the bests around, and a swarm with no feasible particle is still pulled towards
  feasibility.

Ties among several dominating candidates for the global best are broken by
:func:`preference`: the least violation, then the smallest ``sum_n log J_n`` (the geometric
mean of the players' costs: scale-free, so a player with large costs does not decide alone),
then the lowest particle index.
"""

from __future__ import annotations

import numpy as np

_TINY = 1e-300


def dominates(
    cost_a: np.ndarray, viol_a: np.ndarray, cost_b: np.ndarray, viol_b: np.ndarray
) -> np.ndarray:
    """Whether allocation ``a`` dominates ``b`` (broadcasting over leading axes)."""
    feasible_both = (viol_a == 0) & (viol_b == 0)
    with np.errstate(invalid="ignore"):
        pareto = np.all(cost_a <= cost_b, axis=-1) & np.any(cost_a < cost_b, axis=-1)
    return np.where(feasible_both, pareto, viol_a < viol_b)


def preference(cost: np.ndarray, violation: np.ndarray) -> np.ndarray:
    """``(P,)`` tie-break key, lower is better: violation first (infeasible sorts after all
    feasible), then ``sum_n log J_n``."""
    with np.errstate(divide="ignore"):
        logs = np.log(np.maximum(cost, _TINY)).sum(axis=-1)
    return np.where(violation > 0, np.inf, logs), violation


def best_index(cost: np.ndarray, violation: np.ndarray, mask: np.ndarray | None = None) -> int:
    """Index of the preferred allocation among ``mask`` (all if ``None``); ``-1`` if none."""
    key, viol = preference(cost, violation)
    if mask is not None:
        if not mask.any():
            return -1
        key = np.where(mask, key, np.inf)
        viol = np.where(mask, viol, np.inf)
    if np.isfinite(key).any():
        return int(np.argmin(key))
    return int(np.argmin(viol))
