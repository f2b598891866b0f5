"""The five single-UAV cost terms of paper eq. 2, as the SPSO reference computes them
(docs/model.md eqs. (2a)-(2e)).

Every function takes whole populations. Shapes: ``P`` particles, ``N`` UAVs, ``K`` free
waypoints, ``S = K + 1`` segments, ``T`` cylinders. A full path has ``K + 2`` points.
Terms are returned unweighted; ``inf`` marks a violated hard constraint.
"""

from __future__ import annotations

import numpy as np


def path_length(abs_path: np.ndarray) -> np.ndarray:
    """``(P, N, K+2, 3)`` absolute path -> ``(P, N)`` total 3-D length (start and goal segments included)."""
    d = np.diff(abs_path, axis=-2)
    return np.sqrt(np.einsum("...c,...c->...", d, d)).sum(axis=-1)


def segment_axis_distance(xy: np.ndarray, cylinders: np.ndarray) -> np.ndarray:
    """Horizontal distance from each cylinder axis to each path segment.

    ``xy``: ``(P, N, K+2, 2)``; ``cylinders``: ``(T, 3)``. Returns ``(P, N, S, T)``.
    Same arithmetic as the reference's point-to-segment distance: the perpendicular distance
    ``|det(b - a, x - a)| / |b - a|`` when the foot falls on the segment, else the nearer end;
    a zero-length segment's distance is the distance to its point.
    """
    a = xy[..., :-1, None, :]  # (P, N, S, 1, 2)
    b = xy[..., 1:, None, :]
    x = cylinders[:, :2]  # (T, 2)
    ab = b - a
    d_ab = np.hypot(ab[..., 0], ab[..., 1])  # (P, N, S, 1)
    ax = x - a
    bx = x - b
    d_ax = np.hypot(ax[..., 0], ax[..., 1])  # (P, N, S, T)
    d_bx = np.hypot(bx[..., 0], bx[..., 1])
    on_segment = ((-ab * bx).sum(-1)) * ((ab * ax).sum(-1)) >= 0
    det = ab[..., 0] * ax[..., 1] - ab[..., 1] * ax[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        perp = np.abs(det) / d_ab
    dist = np.where(on_segment, perp, np.minimum(d_ax, d_bx))
    return np.where(d_ab != 0, dist, d_ax)


def threat_cost(
    dist: np.ndarray, cylinders: np.ndarray, radius: np.ndarray, margin: float,
    clearance: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Threat term and obstacle violation.

    ``dist``: ``(P, N, S, T)`` from :func:`segment_axis_distance`; ``radius``: ``(N,)`` body radii;
    ``clearance``: the hard minimum clearance ``c`` (m). Per segment and cylinder: ``inf``
    strictly inside ``R + r + c``, else 0 beyond ``R + r + Delta``, else ``R + r + Delta - d``.
    Returns ``(P, N)`` sums and ``(P, N)`` total penetration depth of ``R + r + c``.
    """
    return band_threat(dist, cylinders[:, 2] + radius[:, None, None], margin, clearance)  # body (N, 1, T)


def band_threat(dist: np.ndarray, body: np.ndarray, margin: float, clearance: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """The threat of an obstacle ``body`` metres from its axis or footprint, a horizontal
    distance ``dist`` ``(P, N, S, Q)`` away (``body`` broadcasts to it: ``R + r`` for a cylinder,
    ``r`` for a prism): per segment and obstacle ``inf`` strictly inside ``body + c``, 0 beyond
    ``body + Delta``, else ``body + Delta - d``. Returns the ``(P, N)`` sums and the ``(P, N)``
    total penetration depth of ``body + c``."""
    inner = body + clearance
    outer = body + margin
    cost = np.where(dist < inner, np.inf, np.where(dist > outer, 0.0, outer - dist))
    depth = np.maximum(inner - dist, 0.0)
    return cost.sum(axis=(-2, -1)), depth.sum(axis=(-2, -1))


def altitude_cost(h: np.ndarray, h_ref: float) -> tuple[np.ndarray, np.ndarray]:
    """``h``: ``(P, N, K)`` heights above ground of the free waypoints.

    Returns the term ``sum |h - h_ref|`` (``inf`` if any ``h < 0``) and the depth below ground, both ``(P, N)``.
    """
    cost = np.where(h < 0, np.inf, np.abs(h - h_ref)).sum(axis=-1)
    return cost, np.maximum(-h, 0.0).sum(axis=-1)


def smoothness_terms(
    abs_path: np.ndarray, turning_threshold_deg: float, climb_threshold_deg: float
) -> tuple[np.ndarray, np.ndarray]:
    """Turning and climbing terms, in degrees, ``(P, N)`` each.

    ``abs_path``: ``(P, N, K+2, 3)``. At every interior vertex, the turning angle between the x-y
    projections of the segments before and after it; a zero-length projection is replaced by the
    nearest non-zero one on its side (none: the zero segment stays). The climb angle of a segment is
    ``atan2(dz, |dxy|)`` with ``dz`` of the real segment and ``|dxy|`` of the substituted one. An
    angle (or climb-angle change) counts whole, only where strictly above its threshold.
    """
    proj = np.diff(abs_path[..., :2], axis=-2)  # (P, N, S, 2)
    dz = np.diff(abs_path[..., 2], axis=-1)  # (P, N, S)
    S = proj.shape[-2]
    idx = np.arange(S)
    nonzero = np.any(proj != 0, axis=-1)  # (P, N, S)
    # Last non-zero projection at or before i (none -> 0), first at or after i (none -> S - 1).
    back = np.maximum.accumulate(np.where(nonzero, idx, -1), axis=-1).clip(min=0)
    fwd = np.flip(np.minimum.accumulate(np.flip(np.where(nonzero, idx, S), -1), axis=-1), -1)
    fwd = fwd.clip(max=S - 1)
    s1_idx = back[..., :-1]  # segment before vertex i+1, i = 0..S-2
    s2_idx = fwd[..., 1:]
    s1 = np.take_along_axis(proj, s1_idx[..., None], axis=-2)
    s2 = np.take_along_axis(proj, s2_idx[..., None], axis=-2)
    cross = s1[..., 0] * s2[..., 1] - s1[..., 1] * s2[..., 0]
    # "+ 0.0" turns a -0.0 into +0.0, as the reference's 3-D dot (z components +0) does: with a
    # zero projection on one side, (0, 0).(-a, -b) = -0.0 and atan2(0, -0.0) would be 180, not 0.
    dot = s1[..., 0] * s2[..., 0] + s1[..., 1] * s2[..., 1] + 0.0
    turning = np.degrees(np.arctan2(np.abs(cross), dot))
    climb1 = np.degrees(np.arctan2(dz[..., :-1], np.hypot(s1[..., 0], s1[..., 1])))
    climb2 = np.degrees(np.arctan2(dz[..., 1:], np.hypot(s2[..., 0], s2[..., 1])))
    change = np.abs(climb2 - climb1)
    turn_term = np.where(np.abs(turning) > turning_threshold_deg, np.abs(turning), 0.0).sum(-1)
    climb_term = np.where(change > climb_threshold_deg, change, 0.0).sum(-1)
    return turn_term, climb_term


def weighted_sum(weights: np.ndarray, terms: np.ndarray) -> np.ndarray:
    """``sum_i w_i * t_i`` over the last axis with ``0 * inf = 0`` (a zero weight drops a term, never a constraint)."""
    with np.errstate(invalid="ignore"):
        prod = weights * terms
    return np.where(weights == 0, 0.0, prod).sum(axis=-1)
