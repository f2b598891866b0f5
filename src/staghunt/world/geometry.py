"""Plane geometry of the site's shapes, on whole arrays: the distance from points to segments,
from segments to polygons, and from path segments to vertical prisms (the part of a segment
within a prism's altitude band, to its footprint).

Used by the cost model (:mod:`staghunt.costs.prisms`), the scenario's checks of starts and goals
and the flight's safety checks: geometry belongs to the world, which every layer above may use.
Shapes: ``P`` particles, ``N`` UAVs, ``S`` segments, ``Q`` prisms, ``E_q`` edges of prism ``q``.
"""

from __future__ import annotations

import numpy as np


def point_segment_distance(px: np.ndarray, py: np.ndarray, cx: np.ndarray, cy: np.ndarray,
                           dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """Distance from points ``(px, py)`` to segments ``(cx, cy)-(dx, dy)`` (broadcast shapes)."""
    ex = dx - cx
    ey = dy - cy
    l2 = ex * ex + ey * ey
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((px - cx) * ex + (py - cy) * ey) / l2
    t = np.where(l2 > 0.0, np.minimum(np.maximum(t, 0.0), 1.0), 0.0)
    return np.hypot(px - (cx + t * ex), py - (cy + t * ey))


def clip_to_band(za: np.ndarray, zb: np.ndarray, lo: np.ndarray, hi: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parameter interval ``[t0, t1]`` of a segment ``z(t) = za + t (zb - za)`` where
    ``lo < z < hi`` strictly, and whether it is non-empty (``t0 < t1``, or ``za`` inside the band
    for a level segment). Broadcast shapes."""
    dz = zb - za
    level = dz == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        tl = (lo - za) / dz
        th = (hi - za) / dz
    t0 = np.maximum(np.minimum(tl, th), 0.0)
    t1 = np.minimum(np.maximum(tl, th), 1.0)
    inside_level = (lo < za) & (za < hi)
    ok = np.where(level, inside_level, t0 < t1)
    t0 = np.where(level, 0.0, t0)
    t1 = np.where(level, 1.0, t1)
    return t0, t1, ok


def segment_polygon_distance(ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray,
                             edges: np.ndarray) -> np.ndarray:
    """Horizontal distance from segments ``a b`` (any shape ``X``) to one polygon given by its
    ``(E, 4)`` edges: 0 when the segment crosses an edge or starts inside, else the least of the
    four end-point-to-segment distances over the edges. Returns shape ``X``."""
    a_x, a_y, b_x, b_y = (v[..., None] for v in (ax, ay, bx, by))  # (..., 1)
    cx, cy, dx, dy = edges[:, 0], edges[:, 1], edges[:, 2], edges[:, 3]  # (E,)
    d = np.minimum(
        np.minimum(point_segment_distance(a_x, a_y, cx, cy, dx, dy),
                   point_segment_distance(b_x, b_y, cx, cy, dx, dy)),
        np.minimum(point_segment_distance(cx, cy, a_x, a_y, b_x, b_y),
                   point_segment_distance(dx, dy, a_x, a_y, b_x, b_y)),
    ).min(axis=-1)
    o1 = (b_x - a_x) * (cy - a_y) - (b_y - a_y) * (cx - a_x)
    o2 = (b_x - a_x) * (dy - a_y) - (b_y - a_y) * (dx - a_x)
    o3 = (dx - cx) * (a_y - cy) - (dy - cy) * (a_x - cx)
    o4 = (dx - cx) * (b_y - cy) - (dy - cy) * (b_x - cx)
    crosses = ((o1 * o2 < 0.0) & (o3 * o4 < 0.0)).any(axis=-1)
    straddle = (cy > a_y) != (dy > a_y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xcross = (dx - cx) * (a_y - cy) / (dy - cy) + cx
    inside = (np.count_nonzero(straddle & (a_x < xcross), axis=-1) % 2) == 1
    return np.where(crosses | inside, 0.0, d)


def prism_distance(abs_path: np.ndarray, prm: np.ndarray, edges: np.ndarray, radius: np.ndarray,
                   clearance: float) -> np.ndarray:
    """``(P, N, S, Q)`` horizontal distance from each segment's part within prism ``q``'s
    altitude band ``(base - r - c, top + r + c)`` to its footprint (``inf``: no such part).

    ``abs_path``: ``(P, N, K+2, 3)`` absolute; ``prm (Q, 8)``, ``edges (E, 4)`` from
    :func:`staghunt.world.prism_arrays`; ``radius``: ``(N,)``."""
    P, N, K2, _ = abs_path.shape
    Q = prm.shape[0]
    out = np.full((P, N, K2 - 1, Q), np.inf)
    a = abs_path[:, :, :-1]
    b = abs_path[:, :, 1:]
    grow = (radius + clearance)[None, :, None]  # (1, N, 1)
    for q in range(Q):
        base, top, e0, ne = prm[q, 0], prm[q, 1], int(prm[q, 2]), int(prm[q, 3])
        t0, t1, ok = clip_to_band(a[..., 2], b[..., 2], base - grow, top + grow)
        ex = b[..., 0] - a[..., 0]
        ey = b[..., 1] - a[..., 1]
        ax = a[..., 0] + t0 * ex
        ay = a[..., 1] + t0 * ey
        bx = a[..., 0] + t1 * ex
        by = a[..., 1] + t1 * ey
        d = segment_polygon_distance(ax, ay, bx, by, edges[e0:e0 + ne])
        out[..., q] = np.where(ok, d, np.inf)
    return out
