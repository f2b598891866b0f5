"""Formation cost (docs/model.md eqs. (5)-(7)) and inter-UAV separation, on whole populations.

Shapes: ``P`` particles, ``N`` UAVs, ``K`` free waypoints, ``M`` edges, ``S = K + 1`` segments.
"""

from __future__ import annotations

import numpy as np


def formation_errors(
    positions: np.ndarray, heads: np.ndarray, tails: np.ndarray, ref_diff: np.ndarray, mu: np.ndarray
) -> np.ndarray:
    """Eq. (5a) of docs/model.md, the edge form. ``positions``: ``(P, N, K, 3)`` absolute.
    Returns ``E`` ``(P, N, K)`` (no collision test)."""
    dev = positions[:, heads] - positions[:, tails] - ref_diff[None, :, None, :]  # (P, M, K, 3)
    sq = np.einsum("pmkc,pmkc->pmk", dev, dev)
    return np.einsum("pmk,nm->pnk", sq, mu)


def nearest_waypoint_distance(positions: np.ndarray) -> np.ndarray:
    """``(P, N, K, 3)`` -> ``(P, N, K)`` distance from each UAV to its nearest team-mate (``inf`` if alone)."""
    diff = positions[:, :, None] - positions[:, None, :]  # (P, N, N, K, 3)
    d = np.sqrt(np.einsum("pabkc,pabkc->pabk", diff, diff))
    n = positions.shape[1]
    d[:, np.arange(n), np.arange(n)] = np.inf
    return d.min(axis=2)


def nearest_segment_distance(path: np.ndarray) -> np.ndarray:
    """Closest approach to the nearest team-mate along each synchronised segment.

    ``path``: ``(P, N, K+2, 3)`` absolute; waypoint ``k`` of every UAV is reached at the same time
    and UAVs move linearly in between. Returns ``(P, N, S)`` (``inf`` if alone).
    """
    rel = path[:, :, None] - path[:, None, :]  # (P, N, N, K+2, 3)
    r0 = rel[..., :-1, :]
    dr = rel[..., 1:, :] - r0
    dd = np.einsum("...c,...c->...", dr, dr)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(-np.einsum("...c,...c->...", r0, dr) / dd, 0.0, 1.0)
    t = np.where(dd > 0, t, 0.0)
    closest = r0 + t[..., None] * dr
    d = np.sqrt(np.einsum("...c,...c->...", closest, closest))
    n = path.shape[1]
    d[:, np.arange(n), np.arange(n)] = np.inf
    return d.min(axis=2)
