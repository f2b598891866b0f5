"""Small compiled helpers of the kernels: filling a block's row, the players of a deviation,
Pareto dominance of two columns, the ground under a point, and the distances from a segment to
a cylinder's axis and to a prism, in NumPy's arithmetic (the reference is named in each).
Each is compiled on its own and linked into the entries that call it."""

from __future__ import annotations

import math

import numpy as np

from staghunt.engine.fastmath import DECISION_TOL
from staghunt.engine.jit import subroutine
from staghunt.engine.layout import (
    P_CELL,
    P_OX,
    P_OY,
    P_TERRAIN,
)


@subroutine
def fill(row: np.ndarray, nb: int, value: float) -> None:
    for b in range(nb):
        row[b] = value


@subroutine
def is_player(players: np.ndarray, n: int) -> bool:
    for c in range(players.shape[0]):
        if players[c] == n:
            return True
    return False


@subroutine
def rows_kept(solo: bool, every: bool, players: np.ndarray, n: int) -> bool:
    """Whether :func:`staghunt.engine.team_kernel._team_terms` makes UAV ``n``'s collisions and ``J`` (and so its formation
    error and nearest-distance rows): every UAV's, unless ``solo`` without ``every``, then the
    players' only."""
    return not solo or every or is_player(players, n)


@subroutine
def ground_z(x: float, y: float, h: float, grid: np.ndarray, par: np.ndarray) -> float:
    """Absolute altitude ``h + g(x, y)`` exactly as :meth:`staghunt.world.Terrain.absolute`
    (MATLAB rounding for the nearest cell, float32 sums for a float32 grid, or bilinear)."""
    mode = par[P_TERRAIN]
    if mode == 0.0:
        return h + 0.0
    rows, cols = grid.shape
    u = (x - par[P_OX]) / par[P_CELL]
    v = (y - par[P_OY]) / par[P_CELL]
    if mode != 3.0:
        au = abs(u)
        fu = math.floor(au)
        ru = (1.0 if u > 0.0 else (-1.0 if u < 0.0 else 0.0)) * (fu + (1.0 if au - fu >= 0.5 else 0.0))
        av = abs(v)
        fv = math.floor(av)
        rv = (1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)) * (fv + (1.0 if av - fv >= 0.5 else 0.0))
        g = grid[int(min(max(rv, 0.0), rows - 1.0)), int(min(max(ru, 0.0), cols - 1.0))]
        if mode == 2.0:
            return np.float64(np.float32(h) + np.float32(g))
        return h + g
    return bilinear_z(x, y, h, grid, par[P_OX], par[P_OY], par[P_CELL])


@subroutine
def bilinear_z(x: float, y: float, h: float, grid: np.ndarray, ox: float, oy: float, cell: float) -> float:
    """:func:`ground_z` on a bilinear grid (``P_TERRAIN`` 3) with origin ``ox, oy`` and cell
    size ``cell``. Branch-free, so a loop over lanes that calls it vectorises (gathers): call it
    directly in such loops (about 4x faster than through ``ground_z``'s branches)."""
    rows, cols = grid.shape
    u = min(max((x - ox) / cell, 0.0), cols - 1.0)
    v = min(max((y - oy) / cell, 0.0), rows - 1.0)
    j0 = min(max(int(u), 0), max(cols - 2, 0))  # u >= 0: truncation is the floor
    i0 = min(max(int(v), 0), max(rows - 2, 0))
    j1 = min(j0 + 1, cols - 1)
    i1 = min(i0 + 1, rows - 1)
    fu = u - j0
    fv = v - i0
    top = grid[i0, j0] * (1 - fu) + grid[i0, j1] * fu
    bottom = grid[i1, j0] * (1 - fu) + grid[i1, j1] * fu
    return h + (top * (1 - fv) + bottom * fv)


@subroutine
def axis_distance(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    """Horizontal distance from the axis ``(cx, cy)`` to segment ``a b`` with exactly the
    arithmetic of :func:`staghunt.costs.single.segment_axis_distance` (``hypot`` from libm)."""
    abx = bx - ax
    aby = by - ay
    axx = cx - ax
    axy = cy - ay
    if abx == 0.0 and aby == 0.0:
        return math.hypot(axx, axy)
    bxx = cx - bx
    bxy = cy - by
    if ((-abx * bxx) + (-aby * bxy)) * ((abx * axx) + (aby * axy)) >= 0:
        return abs(abx * axy - aby * axx) / math.hypot(abx, aby)
    return min(math.hypot(axx, axy), math.hypot(bxx, bxy))


@subroutine
def dominates_at(cost_a: np.ndarray, ia: int, va: float, cost_b: np.ndarray, ib: int, vb: float) -> bool:
    """:func:`staghunt.solvers.dominance.dominates` for columns ``ia`` of ``cost_a`` and ``ib`` of
    ``cost_b`` (``(C, P)`` arrays)."""
    if va == 0.0 and vb == 0.0:
        all_le = True
        any_lt = False
        for c in range(cost_a.shape[0]):
            x = cost_a[c, ia]
            y = cost_b[c, ib]
            if not (x <= y):
                all_le = False
            if x < y:
                any_lt = True
        return all_le and any_lt
    return va < vb


@subroutine
def threats_exact(b, xn, yn, seg, cyl, radius, margin, clear, acc, dep) -> None:  # noqa: ANN001
    """Lane ``b``: the obstacle pairs that the vectorised pass left out (fast distance within
    DECISION_TOL of ``R + r + c`` or ``R + r + Delta``), with NumPy's exact arithmetic."""
    S = xn.shape[0] - 1
    for t in range(cyl.shape[0]):
        cx = cyl[t, 0]
        cy = cyl[t, 1]
        inner = cyl[t, 2] + radius + clear
        outer = cyl[t, 2] + radius + margin
        for j in range(S):
            ax = xn[j, b]
            ay = yn[j, b]
            bx = xn[j + 1, b]
            by = yn[j + 1, b]
            abx = seg[0, j, b]
            aby = seg[1, j, b]
            axx = cx - ax
            axy = cy - ay
            bxx = cx - bx
            bxy = cy - by
            d2a = axx * axx + axy * axy
            d2b = bxx * bxx + bxy * bxy
            zero = abx == 0.0 and aby == 0.0
            on = ((-abx * bxx) + (-aby * bxy)) * ((abx * axx) + (aby * axy)) >= 0
            perp = abs(abx * axy - aby * axx) * seg[4, j, b]
            d = perp if (on and not zero) else math.sqrt(d2a if zero else min(d2a, d2b))
            if abs(d - inner) <= DECISION_TOL or abs(d - outer) <= DECISION_TOL:
                d = axis_distance(ax, ay, bx, by, cx, cy)
                acc[b] += np.inf if d < inner else (0.0 if d > outer else outer - d)
                depth = inner - d
                dep[b] += depth if depth >= 0.0 else 0.0


@subroutine
def point_segment_distance(px: float, py: float, cx: float, cy: float, dx: float, dy: float) -> float:
    """:func:`staghunt.costs.prisms.point_segment_distance` for one point and one segment."""
    ex = dx - cx
    ey = dy - cy
    l2 = ex * ex + ey * ey
    t = 0.0
    if l2 > 0.0:
        t = min(max(((px - cx) * ex + (py - cy) * ey) / l2, 0.0), 1.0)
    return math.hypot(px - (cx + t * ex), py - (cy + t * ey))


@subroutine
def prism_segment_distance(xa: float, ya: float, za: float, xb: float, yb: float, zb: float,
                           q: int, prm: np.ndarray, pedge: np.ndarray, grow: float) -> float:
    """:func:`staghunt.costs.prisms.prism_distance` of one segment and prism ``q`` (same
    arithmetic): horizontal distance from the segment's part strictly within ``(base - grow,
    top + grow)`` to the footprint; ``inf`` if there is no such part."""
    lo = prm[q, 0] - grow
    hi = prm[q, 1] + grow
    dz = zb - za
    if dz == 0.0:
        if not (lo < za and za < hi):
            return np.inf
        t0 = 0.0
        t1 = 1.0
    else:
        tl = (lo - za) / dz
        th = (hi - za) / dz
        t0 = max(min(tl, th), 0.0)
        t1 = min(max(tl, th), 1.0)
        if not (t0 < t1):
            return np.inf
    ex = xb - xa
    ey = yb - ya
    ax = xa + t0 * ex
    ay = ya + t0 * ey
    bx = xa + t1 * ex
    by = ya + t1 * ey
    e0 = int(prm[q, 2])
    d = np.inf
    inside = False
    for e in range(e0, e0 + int(prm[q, 3])):
        cx = pedge[e, 0]
        cy = pedge[e, 1]
        dx = pedge[e, 2]
        dy = pedge[e, 3]
        o1 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        o2 = (bx - ax) * (dy - ay) - (by - ay) * (dx - ax)
        o3 = (dx - cx) * (ay - cy) - (dy - cy) * (ax - cx)
        o4 = (dx - cx) * (by - cy) - (dy - cy) * (bx - cx)
        if o1 * o2 < 0.0 and o3 * o4 < 0.0:
            return 0.0
        if (cy > ay) != (dy > ay):
            if ax < (dx - cx) * (ay - cy) / (dy - cy) + cx:
                inside = not inside
        d = min(d, min(min(point_segment_distance(ax, ay, cx, cy, dx, dy), point_segment_distance(bx, by, cx, cy, dx, dy)),
                       min(point_segment_distance(cx, cy, ax, ay, bx, by), point_segment_distance(dx, dy, ax, ay, bx, by))))
    return 0.0 if inside else d


@subroutine
def prism_threats(nb, xn, yn, zn, prm, pedge, radius, margin, clear, ceiling, acc, dep) -> None:  # noqa: ANN001
    """Add prism threats and the ceiling (:mod:`staghunt.costs.prisms`) of one UAV's lanes to
    ``acc`` (cost) and ``dep`` (violation). A pair whose bounding boxes are farther apart than
    both ``r + c`` and ``r + Delta`` (with a 1e-6 m guard) costs exactly 0 and is skipped."""
    S = xn.shape[0] - 1
    inner = radius + clear
    outer = radius + margin
    reach = max(inner, outer) + 1e-6
    has_ceiling = ceiling < np.inf
    for b in range(nb):
        for j in range(S):
            xa = xn[j, b]
            ya = yn[j, b]
            za = zn[j, b]
            xb = xn[j + 1, b]
            yb = yn[j + 1, b]
            zb = zn[j + 1, b]
            sx0 = min(xa, xb)
            sx1 = max(xa, xb)
            sy0 = min(ya, yb)
            sy1 = max(ya, yb)
            for q in range(prm.shape[0]):
                gx = max(max(prm[q, 4] - sx1, sx0 - prm[q, 5]), 0.0)
                gy = max(max(prm[q, 6] - sy1, sy0 - prm[q, 7]), 0.0)
                if gx > reach or gy > reach:
                    continue
                d = prism_segment_distance(xa, ya, za, xb, yb, zb, q, prm, pedge, inner)
                acc[b] += np.inf if d < inner else (0.0 if d > outer else outer - d)
                depth = inner - d
                dep[b] += depth if depth >= 0.0 else 0.0
        if has_ceiling:
            hit = False
            for j in range(S + 1):
                over = zn[j, b] - ceiling
                if over > 0.0:
                    hit = True
                    dep[b] += over
            if hit:
                acc[b] += np.inf
