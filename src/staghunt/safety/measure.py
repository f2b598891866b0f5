"""Measures of the team's positions at the same instant: distances between UAVs and clearance
to the obstacles where they are at that instant (fixed, appeared, moving); judged by
:mod:`staghunt.safety.judge`.

Conventions are the planner's (docs/model.md): cylinders are infinitely tall (clearance = the
horizontal distance to the axis ``- R - r``); a prism, a no-fly zone or a jib counts where the
UAV's height is within ``(base - r, top + r)`` (clearance = horizontal distance to the footprint
``- r``, 0 inside it); a negative clearance is a collision. Shapes: ``N`` UAVs, ``T`` instants.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from staghunt.world.geometry import point_segment_distance
from staghunt.world import Cylinder, Prism
from staghunt.world.dynamic import Dynamics


def moving_clearance(dyn: Dynamics, pos: np.ndarray, t: np.ndarray, radius: np.ndarray,
                     names: set[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Clearance of UAVs to the known motions at the same instants.

    ``pos``: ``(N, T, 3)`` absolute positions at times ``t`` ``(T,)``; ``radius``: ``(N,)``.
    Returns ``(N, T)`` the least clearance (m) to any moving cylinder (horizontal distance to
    its axis ``- R - r``) or jib (horizontal distance to its footprint ``- r`` where the UAV's
    height is within ``(base - r, top + r)``; ``inf`` above or below it), and ``(N, T)`` the
    index of the nearest obstacle (moving cylinders first, then jibs; ``-1``: none).
    ``names``: only these obstacles. Obstacles that have disappeared (events) are skipped from
    their event's time on."""
    N, T = pos.shape[:2]
    best = np.full((N, T), np.inf)
    which = np.full((N, T), -1, dtype=int)
    gone = {e.name: e.time for e in dyn.events if e.kind == "disappear"}
    r = np.asarray(radius, dtype=float)[:, None]
    for i, m in enumerate(dyn.moving):
        if names is not None and m.name not in names:
            continue
        c = m.xy(t)  # (T, 2)
        d = np.hypot(pos[..., 0] - c[None, :, 0], pos[..., 1] - c[None, :, 1]) - m.radius - r
        d = np.where(t[None] >= gone.get(m.name, np.inf), np.inf, d)
        better = d < best
        best, which = np.where(better, d, best), np.where(better, i, which)
    for j, jib in enumerate(dyn.jibs):
        if names is not None and jib.name not in names:
            continue
        polys = jib.polygons(t)  # (T, 4, 2)
        edges = np.concatenate([polys, np.roll(polys, -1, axis=1)], axis=-1)  # (T, 4, 4)
        d = point_polygon_distance(pos[..., 0], pos[..., 1], edges[None])
        z = pos[..., 2]
        band = (z > jib.base - r) & (z < jib.top + r)
        d = np.where(band & (t[None] < gone.get(jib.name, np.inf)), d - r, np.inf)
        better = d < best
        best, which = np.where(better, d, best), np.where(better, len(dyn.moving) + j, which)
    return best, which



def point_polygon_distance(x: np.ndarray, y: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Horizontal distance from points ``(x, y)`` (shape ``X``) to polygons whose ``(E, 4)``
    edges ``(x0, y0, x1, y1)`` broadcast against ``X`` (``edges`` shape ``X + (E, 4)``); 0 inside."""
    px, py = x[..., None], y[..., None]
    cx, cy, dx, dy = (edges[..., i] for i in range(4))
    d = point_segment_distance(px, py, cx, cy, dx, dy).min(axis=-1)
    straddle = (cy > py) != (dy > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xcross = (dx - cx) * (py - cy) / (dy - cy) + cx
    inside = (np.count_nonzero(straddle & (px < xcross), axis=-1) % 2) == 1
    return np.where(inside, 0.0, d)


def static_clearance(cylinders: Sequence[Cylinder], prisms: Sequence[Prism], pos: np.ndarray,
                     radius: np.ndarray) -> np.ndarray:
    """``(N, T)`` least clearance of positions ``pos`` ``(N, T, 3)`` (absolute) to fixed
    cylinders and prisms (``inf`` without any)."""
    return static_nearest(cylinders, prisms, pos, radius)[0]


def static_nearest(cylinders: Sequence[Cylinder], prisms: Sequence[Prism], pos: np.ndarray,
                   radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`static_clearance` and ``(N, T)`` the index of the nearest obstacle (cylinders
    first, then prisms; ``-1``: none)."""
    N, T = pos.shape[:2]
    r = np.asarray(radius, dtype=float)[:, None]
    best = np.full((N, T), np.inf)
    which = np.full((N, T), -1, dtype=int)
    for i, c in enumerate(cylinders):
        d = np.hypot(pos[..., 0] - c.x, pos[..., 1] - c.y) - c.radius - r
        better = d < best
        best, which = np.where(better, d, best), np.where(better, i, which)
    x, y, z = pos[..., 0], pos[..., 1], pos[..., 2]
    boxes = [np.asarray(p.polygon, dtype=float) for p in prisms]
    # Nearest boxes first: a prism is measured only at the instants where its bounding box (a
    # lower bound of its distance) comes closer than the least clearance found so far there,
    # and in its height band; elsewhere it cannot be the least. The same array, far fewer
    # point-to-edge distances on a site with several buildings.
    lower = [np.hypot(np.maximum(np.maximum(v[:, 0].min() - x, x - v[:, 0].max()), 0.0),
                      np.maximum(np.maximum(v[:, 1].min() - y, y - v[:, 1].max()), 0.0)) - r for v in boxes]
    for i in np.argsort([float(lb.min(initial=np.inf)) for lb in lower]):
        p, v = prisms[i], boxes[i]
        near = (lower[i] < best) & (z > p.base - r) & (z < p.top + r)  # (N, T)
        if not near.any():
            continue
        n, k = np.nonzero(near)
        edges = np.concatenate([v, np.roll(v, -1, axis=0)], axis=1)
        d = point_polygon_distance(x[n, k], y[n, k], edges) - r[n, 0]
        better = d < best[n, k]
        best[n[better], k[better]] = d[better]
        which[n[better], k[better]] = len(cylinders) + i
    return best, which


def separations(pos: np.ndarray) -> np.ndarray:
    """``(N, T)`` each UAV's distance to its nearest team-mate at the same instant (``inf`` alone)."""
    N = pos.shape[0]
    if N < 2:
        return np.full(pos.shape[:2], np.inf)
    rel = pos[:, None] - pos[None, :]  # (N, N, T, 3)
    d2 = (rel[..., 0] * rel[..., 0] + rel[..., 1] * rel[..., 1]) + rel[..., 2] * rel[..., 2]
    d2[np.arange(N), np.arange(N)] = np.inf
    return np.sqrt(d2.min(axis=1))  # the root of the least square: the least distance, as a norm gives it


def nearest_mates(pos: np.ndarray, radius: np.ndarray, active: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Each UAV's nearest team-mate at the same instant, by the gap between their bodies:
    ``(N, T)`` the centre distance to the team-mate whose surface is nearest (``inf`` alone)
    and ``(N, T)`` that team-mate's index (``-1`` alone). ``radius``: ``(N,)``; ``active``
    ``(N, T)``: the instants a UAV counts (not: no team-mate for anybody)."""
    N, T = pos.shape[:2]
    if N < 2:
        return np.full((N, T), np.inf), np.full((N, T), -1, dtype=int)
    rel = pos[:, None] - pos[None, :]  # (N, N, T, 3)
    d = np.sqrt((rel[..., 0] * rel[..., 0] + rel[..., 1] * rel[..., 1]) + rel[..., 2] * rel[..., 2])
    r = np.asarray(radius, dtype=float)
    gap = d - (r[:, None] + r[None, :])[..., None]
    gap[np.arange(N), np.arange(N)] = np.inf
    if active is not None:
        gap = np.where(active[:, None] & active[None, :], gap, np.inf)
    mate = np.argmin(gap, axis=1)  # (N, T)
    near = np.take_along_axis(d, mate[:, None], axis=1)[:, 0]
    alone = ~np.isfinite(np.take_along_axis(gap, mate[:, None], axis=1)[:, 0])
    return np.where(alone, np.inf, near), np.where(alone, -1, mate)
