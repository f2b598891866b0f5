"""``J_n = J_s + beta_n J_f`` (docs/model.md eq. (4)) for whole populations of team paths (NumPy
reference engine); violations as in eq. (15)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from staghunt.costs.formation import (
    formation_errors,
    nearest_segment_distance,
    nearest_waypoint_distance,
)
from staghunt.costs.model import CostModel, full_paths, to_absolute
from staghunt.costs.prisms import ceiling_cost, prism_distance, prism_threat
from staghunt.costs.single import (
    altitude_cost,
    path_length,
    segment_axis_distance,
    smoothness_terms,
    threat_cost,
    weighted_sum,
)

TERM_NAMES = ("length", "threat", "altitude", "turning", "climb")
VIOLATION_NAMES = ("obstacle", "ground", "separation")


@dataclass(frozen=True, eq=False)
class Costs:
    """Costs of ``P`` team allocations of ``N`` UAVs.

    - ``terms``: ``(P, N, 5)`` unweighted J_s terms (length, threat, altitude, turning, climb).
    - ``single``: ``(P, N)`` ``J_s``; ``formation``: ``(P, N)`` ``J_f``; ``total``: ``(P, N)`` ``J_n``.
    - ``violation``: ``(P, N, 3)`` constraint violation (obstacle penetration, depth below ground,
      separation deficit), metres; all zero iff every cost is finite.
    """

    terms: np.ndarray
    single: np.ndarray
    formation: np.ndarray
    total: np.ndarray
    violation: np.ndarray

    @property
    def total_violation(self) -> np.ndarray:
        """``(P,)`` summed violation of each allocation; 0 means feasible."""
        return self.violation.sum(axis=(1, 2))


def formation_cost(model: CostModel, abs_path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``J_f`` ``(P, N)`` and separation deficit ``(P, N)`` for absolute full paths ``(P, N, K+2, 3)``.

    ``E_n(k)`` is ``inf`` at a free waypoint where UAV ``n``'s nearest team-mate is within
    ``d_s + 2 r_n`` (docs/model.md eq. (6a)). With ``continuous_separation`` (eq. (6b)), ``J_f`` is also ``inf`` when that
    happens anywhere along a segment (closest approach of the synchronised motion).
    """
    wp = abs_path[:, :, 1:-1]
    E = formation_errors(wp, model.heads, model.tails, model.ref_diff, model.mu)
    limit = (model.safe_distance + 2.0 * model.radius)[None, :, None]  # (1, N, 1)
    near = nearest_waypoint_distance(wp)  # (P, N, K)
    hit = near <= limit
    # A touch (distance == limit) violates too: the deficit gets a positive floor.
    deficit = np.where(hit, np.maximum(limit - near, 1e-9), 0.0).sum(axis=-1)
    if model.continuous_separation:
        seg = nearest_segment_distance(abs_path)  # (P, N, K+1)
        seg_hit = seg <= limit
        hit = hit | seg_hit[..., :-1] | seg_hit[..., 1:]
        deficit = deficit + np.where(seg_hit, np.maximum(limit - seg, 1e-9), 0.0).sum(axis=-1)
    E = np.where(hit, np.inf, E)
    return E.sum(axis=-1), deficit


Evaluator = Callable[[CostModel, np.ndarray], Costs]
"""What scores a batch of plans: :func:`evaluate` (the NumPy reference) or an engine's ``evaluate``."""


def evaluate(model: CostModel, waypoints: np.ndarray) -> Costs:
    """Costs of a population of team allocations.

    ``waypoints``: ``(P, N, K, 3)`` free waypoints as ``(x, y, h)``. Returns :class:`Costs`.
    """
    path = full_paths(model, waypoints)  # (P, N, K+2, 3) x, y, h
    abs_path = to_absolute(model.terrain, path)
    length = path_length(abs_path)
    dist = segment_axis_distance(path[..., :2], model.cylinders)
    threat, obstacle_depth = threat_cost(dist, model.cylinders, model.radius, model.danger_margin,
                                          model.min_clearance)
    if model.prisms.shape[0]:
        pd = prism_distance(abs_path, model.prisms, model.prism_edges, model.radius, model.min_clearance)
        p_cost, p_depth = prism_threat(pd, model.radius, model.danger_margin, model.min_clearance)
        threat = threat + p_cost
        obstacle_depth = obstacle_depth + p_depth
    if np.isfinite(model.ceiling):
        c_cost, c_depth = ceiling_cost(abs_path, model.ceiling)
        threat = threat + c_cost
        obstacle_depth = obstacle_depth + c_depth
    altitude, ground_depth = altitude_cost(waypoints[..., 2], model.h_ref)
    turning, climb = smoothness_terms(
        abs_path, model.turning_threshold_deg, model.climb_threshold_deg
    )
    terms = np.stack([length, threat, altitude, turning, climb], axis=-1)
    single = weighted_sum(model.weights, terms)
    jf, sep_deficit = formation_cost(model, abs_path)
    with np.errstate(invalid="ignore"):
        total = single + np.where(model.beta == 0, 0.0, model.beta * jf)
    violation = np.stack([obstacle_depth, ground_depth, sep_deficit], axis=-1)
    return Costs(terms=terms, single=single, formation=jf, total=total, violation=violation)
