"""Threat of vertical prisms (buildings, cranes, boxes, no-fly zones) and of an altitude ceiling,
on whole populations (NumPy reference twin of the compiled kernel).

Shapes: ``P`` particles, ``N`` UAVs, ``K`` free waypoints, ``S = K + 1`` segments, ``Q`` prisms,
``E_q`` edges of prism ``q``. A prism is judged on the part of a segment whose altitude lies
strictly between ``base - r - c`` and ``top + r + c`` (``r`` body radius, ``c`` hard minimum
clearance): ``d`` is the horizontal distance from that part to the footprint polygon (0 when
it crosses or lies inside the footprint, ``inf`` when no part of the segment is in that
altitude band). Then, as for cylinders with ``R = 0``: infeasible strictly inside ``r + c``,
``(r + Delta) - d`` up to ``r + Delta``, free beyond. See ``docs/model.md``.
"""

from __future__ import annotations

import numpy as np

from staghunt.costs.single import band_threat
from staghunt.world.geometry import (  # noqa: F401 (re-exported: the cost model's geometry)
    clip_to_band,
    point_segment_distance,
    prism_distance,
    segment_polygon_distance,
)


def prism_threat(dist: np.ndarray, radius: np.ndarray, margin: float, clearance: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Threat sums ``(P, N)`` and penetration depths ``(P, N)`` of ``r + c`` from
    :func:`prism_distance` ``(P, N, S, Q)``: per segment and prism ``inf`` strictly inside
    ``r + c``, 0 beyond ``r + Delta``, else ``r + Delta - d``."""
    return band_threat(dist, radius[:, None, None], margin, clearance)


def ceiling_cost(abs_path: np.ndarray, ceiling: float) -> tuple[np.ndarray, np.ndarray]:
    """Altitude ceiling (absolute site ``z``): ``(P, N)`` term (``inf`` where any point of the
    full path ``(P, N, K+2, 3)`` is strictly above it, else 0) and summed excess height."""
    over = abs_path[..., 2] - ceiling
    cost = np.where((over > 0.0).any(axis=-1), np.inf, 0.0)
    return cost, np.maximum(over, 0.0).sum(axis=-1)
