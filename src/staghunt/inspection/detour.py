"""A UAV's own hop between two captures when the straight line is blocked: the shortest way
round (a visibility graph in the plane, at the hop's height, round every obstacle it would meet
grown by the body radius, the clearance and a margin; Dijkstra's shortest path by SciPy), or over
the buildings in the way when that is shorter and the height band and ceiling allow it.

The game's spherical-vector encoding cannot find these detours: its step is at most twice the
straight distance over the number of waypoints, so a hop of 40 m from one side of a building to
a courtyard on the other has no room to go round (measured on the built-in site: 0 feasible of
6 runs up to 400 x 200, K = 8).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import unary_union

from staghunt.acquisition.clearance import Keepout

__all__ = ["detour"]

MARGIN = 2.0
"""Extra distance (m) kept from an obstacle beyond the body radius and the clearance."""


def _blockers(keep: Keepout, z_lo: float, z_hi: float, margin: float) -> list[Polygon]:
    """Footprints of the obstacles a body between heights ``z_lo`` and ``z_hi`` meets, grown by
    radius + clearance + ``margin``."""
    world = keep.scenario.world
    grow = keep.radius + keep.clearance + margin
    out = [Point(c.x, c.y).buffer(c.radius + grow, quad_segs=4) for c in world.cylinders]
    for p in world.prisms:
        if p.base - grow < z_hi and p.top + grow > z_lo:
            out.append(Polygon(p.polygon).buffer(grow, join_style="mitre", mitre_limit=2.0))
    return out


def _around(keep: Keepout, a: np.ndarray, b: np.ndarray, margin: float) -> np.ndarray | None:
    """The shortest way round in the plane, ``margin`` from every obstacle but where an end is
    nearer than that (a viewpoint by a crane's jib): the hops from and to the ends keep only the
    required clearance (and 0.25 m)."""
    lo, hi = min(a[2], b[2]), max(a[2], b[2])
    obstacles = _blockers(keep, lo, hi, margin)
    if not obstacles:
        return None
    union = unary_union(obstacles)
    strict = unary_union(_blockers(keep, lo, hi, 0.25))
    if strict.contains(Point(a[:2])) or strict.contains(Point(b[:2])):
        return None
    inner = union.buffer(-0.01)  # an edge may run along an outline, not through it
    inner_strict = strict.buffer(-0.01)
    shapely.prepare(inner)
    shapely.prepare(inner_strict)
    nodes = [a[:2], b[:2]]
    for poly in getattr(union, "geoms", [union]):
        nodes.extend(np.asarray(poly.exterior.coords)[:-1])
    nodes = np.array(nodes)
    n = len(nodes)
    i, j = np.triu_indices(n, k=1)
    lines = shapely.linestrings(np.stack([nodes[i], nodes[j]], axis=1))  # every pair at once
    end = i < 2
    free = np.where(end, ~shapely.intersects(inner_strict, lines), ~shapely.intersects(inner, lines))
    i, j = i[free], j[free]
    d = np.hypot(*(nodes[j] - nodes[i]).T)
    rows, cols, vals = np.concatenate([i, j]), np.concatenate([j, i]), np.concatenate([d, d])
    graph = csr_matrix((vals, (rows, cols)), shape=(n, n))
    dist, pred = dijkstra(graph, indices=0, return_predecessors=True)
    if not np.isfinite(dist[1]):
        return None
    path = [1]
    while path[-1] != 0:
        path.append(int(pred[path[-1]]))
    xy = nodes[path[::-1]]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    z = a[2] + (b[2] - a[2]) * s / max(s[-1], 1e-9)
    # never lower than the site's minimum height above the ground under a corner (hills)
    b_ = keep.scenario.world.bounds
    g = np.asarray(keep.scenario.world.terrain.height(xy[:, 0], xy[:, 1]), dtype=float)
    z[1:-1] = np.maximum(z[1:-1], g[1:-1] + b_.hmin + 1.0)
    return np.column_stack([xy, z])


def _over(keep: Keepout, a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    grow = keep.radius + keep.clearance + MARGIN
    line = LineString([a[:2], b[:2]]).buffer(grow)
    tops = [p.top for p in keep.scenario.world.prisms if Polygon(p.polygon).intersects(line)]
    if not tops or not np.isfinite(max(tops)):
        return None
    z = max(max(tops) + grow, a[2], b[2])
    return np.array([a, [a[0], a[1], z], [b[0], b[1], z], b])


def detour(keep: Keepout, a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """The shorter safe way from ``a`` to ``b`` (absolute) round or over what blocks the straight
    line: points ``(M, 3)``, or ``None`` if neither is safe."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    best = None
    for path in (_around(keep, a, b, MARGIN), _over(keep, a, b)):
        if path is None or not keep.segment_ok(path).all() or not keep.point_ok(path).all():
            continue
        length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        if best is None or length < best[0]:
            best = (length, path)
    return None if best is None else best[1]
