"""The compiled hot path: one fused pass per iteration over a block of particles.

Two entry points run one block of ``nb <= B`` particles, in this order:

- :func:`uav_pass`: PSO step (or the uniform initial draw), decoding of the spherical particles
  and assembly of the team paths (or, in ``MODE_EVALUATE``, loading given waypoints), then
  every UAV's single-path cost terms (eq. 2);
- :func:`team_pass`: formation cost and separation (eqs. 5-7), ``J_n``, then the personal bests
  (or, in ``MODE_EVALUATE``, the outputs of the twin of :func:`staghunt.costs.evaluate`).

:func:`select_global` then picks the global best. :func:`iterate` runs stretches of a swarm's
iterations in one call (both entries over all blocks through :func:`_block`, serially or in a
``prange`` over the blocks, then the global best), so a small swarm pays no per-block dispatch
from Python and no Python-level barrier per iteration. Intermediate results stay in the block's
scratch arrays (:class:`staghunt.engine.scratch.Scratch`). Callers bind the arrays by these
kernels' parameter names (:func:`staghunt.engine.arrays.kernel_args`), so each definition below is
the one place that spells its argument order. The parts of each entry are
:func:`~staghunt.engine.jit.subroutine` s, compiled only as part of it; the two entries are
compiled in parallel processes the first time (see :func:`staghunt.engine.numba_engine.prepare`).

Layout: the particle index is innermost, so the loops over a block's lanes vectorise.

- Swarm state: ``X``, ``V``, ``PB``: ``(S, K, 3, P)``; ``gbest``: ``(S, K, 3)``;
  ``cost``, ``pcost``: ``(C, P)``; ``viol``, ``pviol``: ``(P,)``; ``J``: ``(N, P)`` per-UAV ``J_n``.
- Model arrays (:mod:`staghunt.engine.arrays`): ``uav (N, U_COLUMNS)`` = start ``(x, y, h)``,
  goal ``(x, y, h)``, start ``z``, goal ``z``, radius, ``beta``, separation limit ``d_s + 2 r``
  (columns ``U_*`` below);
  ``weights (N, 5)``; ``cyl (T, 3)``; ``prm (Q, 8)`` prisms = base, top, first edge, edge
  count, bounding box; ``pedge (E, 4)`` footprint edges (:func:`staghunt.world.prism_arrays`);
  ``heads``, ``tails (M,)``; ``mu (N, M)``; ``ref_diff (M, 3)``;
  ``grid (R, Cg)``; ``par`` (see ``P_*`` indices below).
- Swarm arrays: ``sw (S, SW_COLUMNS)`` = decoding start ``(x, y, h)``, decoding box low, high,
  search range low, high, velocity limit (each 3, over ``(rho, psi, phi)`` for the last three),
  then a flag (1: ``|psi| <= pi/4`` and ``|phi - c| <= pi/4``), ``c``, ``sin c``, ``cos c``
  (columns ``SW_*`` below);
  ``member (N,)``; ``offsets (N, 3)``; ``fixed (N, K, 3)``; ``players (C,)``.

Semantics are those of the NumPy reference (``staghunt.costs``, ``staghunt.solvers.swarm``),
with NumPy's arithmetic order wherever a result decides anything; see
:mod:`staghunt.engine.fastmath` for the approximations and how threshold decisions stay exact.
Loops are written so that LLVM vectorises them over the lanes: few output rows per loop, plain
indexing (1-D row views only in the PSO step and decoding, where they measured faster).
"""

from __future__ import annotations

import math

import numpy as np
from numba import get_thread_id, njit, prange

from staghunt.engine.jit import entry_call, subroutine

from staghunt.engine.fastmath import (
    DECISION_TOL,
    RAD2DEG,
    atan2,
    counter_hash,
    pairwise_lanes,
    sincos,
    sincos_small,
    unit_bits,
    unit_bits_pair,
)

# Indices into ``par``.
P_MARGIN = 0
P_SAFE = 1  # d_s (informational: the limits d_s + 2 r are in ``uav[:, U_LIMIT]``)
P_THR_TURN = 2
P_THR_CLIMB = 3
P_HREF = 4
P_CONTINUOUS = 5
P_TERRAIN = 6  # 0 flat, 1 nearest (float64 grid), 2 nearest (float32 arithmetic), 3 bilinear
P_OX = 7
P_OY = 8
P_CELL = 9
P_C1 = 10
P_C2 = 11
P_SUM = 12  # 1: the objective is the team sum, else the players' J
P_CLEAR = 13  # hard minimum clearance c: infeasible strictly inside R + r + c
P_CEIL = 14  # altitude ceiling (absolute z; inf = none)
N_PAR = 15
SOLO_STRIDE = 7
"""A problem with fixed paths (a unilateral deviation: :func:`staghunt.solvers.problem.solo_problem`)
appends, per UAV ``n``, its constant unweighted ``J_s`` terms (5) and obstacle and ground
violations (2) to ``par`` at ``N_PAR + SOLO_STRIDE * n``. Then only the swarm-following UAVs'
``J_s`` terms are computed, only pairs with a player are checked, the violation is the players'
own, and ``J`` of the other UAVs is NaN (as :meth:`SwarmProblem.evaluate`)."""

PRUNE_MIN_UAVS = 4  # separation pairs are pruned by boxes over a block's lanes for N above this
PRUNE_GUARD = 1e-6  # m added to a pair's limit before a box gap counts as clear

# Columns of ``uav (N, U_COLUMNS)`` (:func:`staghunt.engine.arrays.model_arrays`). Module-level
# integers: Numba freezes them as compile-time constants, so naming them costs nothing.
U_START = 0  # start (x, y, h): columns 0, 1, 2
U_GOAL = 3  # goal (x, y, h): columns 3, 4, 5
U_START_Z = 6  # start's absolute z
U_GOAL_Z = 7  # goal's absolute z
U_RADIUS = 8  # the UAV's radius r
U_BETA = 9  # its formation weight beta
U_LIMIT = 10  # its separation limit d_s + 2 r
U_COLUMNS = 11

# Columns of ``sw (S, SW_COLUMNS)`` (:func:`staghunt.engine.arrays.swarm_arrays`); the blocks of
# three run over (x, y, h) for the decoding box, over (rho, psi, phi) for the search range.
SW_START = 0  # decoding start (x, y, h)
SW_LOW = 3  # decoding box, low
SW_HIGH = 6  # decoding box, high
SW_RANGE_LOW = 9  # search range, low
SW_RANGE_HIGH = 12  # search range, high
SW_VMAX = 15  # velocity limit
SW_SMALL = 18  # 1.0: |psi| <= pi/4 and |phi - c| <= pi/4 (the decoder's fast path)
SW_CENTRE = 19  # c, the centre of phi's range
SW_SIN = 20  # sin c
SW_COS = 21  # cos c
SW_COLUMNS = 22

MODE_INIT = 0  # draw uniform positions, evaluate, personal bests = positions
MODE_STEP = 1  # PSO step, evaluate, personal bests by dominance
MODE_EVALUATE = 2  # evaluate the waypoints ``wp`` (no swarm state touched)
MODE_DEVIATE = 3  # evaluate ``wp`` as deviations of the ``players`` from fixed paths (see team_pass)


def block_size(n_uavs: int, waypoints: int) -> int:
    """Lanes per block: a multiple of 8 in ``[64, 256]`` keeping a block's paths in cache where
    that leaves 64 lanes or more. Large teams get 64 even so: with fewer lanes the loops over a
    block's lanes (the pair check's above all) measured slower than a larger block's cache
    misses (N = 24, K = 20: 24 lanes before; benchmarks/README.md)."""
    b = (16384 // max(1, n_uavs * (waypoints + 2))) // 8 * 8
    return max(64, min(256, b))


@njit(cache=True, nogil=True, error_model="numpy")
def _fill(row: np.ndarray, nb: int, value: float) -> None:
    for b in range(nb):
        row[b] = value


@njit(cache=True, nogil=True, error_model="numpy")
def _is_player(players: np.ndarray, n: int) -> bool:
    for c in range(players.shape[0]):
        if players[c] == n:
            return True
    return False


@njit(cache=True, nogil=True, error_model="numpy")
def _kept(solo: bool, every: bool, players: np.ndarray, n: int) -> bool:
    """Whether :func:`_team_terms` makes UAV ``n``'s collisions and ``J`` (and so its formation
    error and nearest-distance rows): every UAV's, unless ``solo`` without ``every``, then the
    players' only."""
    return not solo or every or _is_player(players, n)


@njit(cache=True, nogil=True, error_model="numpy")
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


@njit(cache=True, nogil=True, error_model="numpy")
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


@njit(cache=True, nogil=True, error_model="numpy")
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


@njit(cache=True, nogil=True, error_model="numpy")
def _dominates(cost_a: np.ndarray, ia: int, va: float, cost_b: np.ndarray, ib: int, vb: float) -> bool:
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


@njit(cache=True, nogil=True, error_model="numpy")
def _threats_exact(b, xn, yn, seg, cyl, radius, margin, clear, acc, dep) -> None:  # noqa: ANN001
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


@njit(cache=True, nogil=True, error_model="numpy")
def _psd(px: float, py: float, cx: float, cy: float, dx: float, dy: float) -> float:
    """:func:`staghunt.costs.prisms.point_segment_distance` for one point and one segment."""
    ex = dx - cx
    ey = dy - cy
    l2 = ex * ex + ey * ey
    t = 0.0
    if l2 > 0.0:
        t = min(max(((px - cx) * ex + (py - cy) * ey) / l2, 0.0), 1.0)
    return math.hypot(px - (cx + t * ex), py - (cy + t * ey))


@njit(cache=True, nogil=True, error_model="numpy")
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
        d = min(d, min(min(_psd(ax, ay, cx, cy, dx, dy), _psd(bx, by, cx, cy, dx, dy)),
                       min(_psd(cx, cy, ax, ay, bx, by), _psd(dx, dy, ax, ay, bx, by))))
    return 0.0 if inside else d


@njit(cache=True, nogil=True, error_model="numpy")
def _prism_threats(nb, xn, yn, zn, prm, pedge, radius, margin, clear, ceiling, acc, dep) -> None:  # noqa: ANN001
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


@subroutine
def _uav_terms(nb, n, px, py, pz, ph, uav, cyl, prm, pedge, par, seg, sub, ang, tmp, acc, acc2, flag,  # noqa: ANN001
               terms, vio) -> None:
    """The five unweighted ``J_s`` terms of UAV ``n`` (:mod:`staghunt.costs.single`) into
    ``terms[n]`` and its obstacle and ground violations into ``vio[n, 0:2]``.

    Scratch: ``seg (5, S, B)`` = ``dx, dy, dz, |dxy|, 1/|dxy|`` per segment; ``sub (6, S, B)`` =
    nearest non-zero projection at or before / at or after each segment (``x, y, |.|``);
    ``ang (2, S, B)`` climb angles; ``tmp (>= S, B)``; ``acc``, ``acc2``, ``flag`` ``(B,)``.
    """
    xn, yn, zn, hn = px[n], py[n], pz[n], ph[n]  # (K+2, B), heights (K, B)
    K = hn.shape[0]
    S = K + 1
    radius = uav[n, U_RADIUS]
    margin = par[P_MARGIN]
    clear = par[P_CLEAR]

    # Segments and the 3-D length (pairwise sum, as NumPy).
    for j in range(S):
        for b in range(nb):
            seg[0, j, b] = xn[j + 1, b] - xn[j, b]
        for b in range(nb):
            seg[1, j, b] = yn[j + 1, b] - yn[j, b]
        for b in range(nb):
            seg[2, j, b] = zn[j + 1, b] - zn[j, b]
        for b in range(nb):
            xy2 = seg[0, j, b] * seg[0, j, b] + seg[1, j, b] * seg[1, j, b]
            seg[3, j, b] = math.sqrt(xy2)
            tmp[j, b] = math.sqrt(xy2 + seg[2, j, b] * seg[2, j, b])
        for b in range(nb):
            seg[4, j, b] = 1.0 / seg[3, j, b] if seg[3, j, b] > 0.0 else 0.0
    pairwise_lanes(tmp, S, nb, acc)
    for b in range(nb):
        terms[n, 0, b] = acc[b]

    # Threats. Branch-free over the lanes: one square root per pair, |det| / |ab| through the
    # reciprocal length. Pairs within DECISION_TOL of R + r or R + r + Delta are left out,
    # counted in ``flag`` and redone exactly. (Skipping far pairs by bounding boxes, per row or
    # per group of lanes, measured slower: the branch-free pass is cheap.)
    for b in range(nb):
        acc[b] = 0.0
        acc2[b] = 0.0
        flag[b] = 0.0
    for t in range(cyl.shape[0]):
        cx = cyl[t, 0]
        cy = cyl[t, 1]
        inner = cyl[t, 2] + radius + clear
        outer = cyl[t, 2] + radius + margin
        for j in range(S):
            for b in range(nb):
                abx = seg[0, j, b]
                aby = seg[1, j, b]
                axx = cx - xn[j, b]
                axy = cy - yn[j, b]
                bxx = cx - xn[j + 1, b]
                bxy = cy - yn[j + 1, b]
                d2a = axx * axx + axy * axy
                d2b = bxx * bxx + bxy * bxy
                zero = abx == 0.0 and aby == 0.0
                on = ((-abx * bxx) + (-aby * bxy)) * ((abx * axx) + (aby * axy)) >= 0
                perp = abs(abx * axy - aby * axx) * seg[4, j, b]
                d = perp if (on and not zero) else math.sqrt(d2a if zero else min(d2a, d2b))
                redo = abs(d - inner) <= DECISION_TOL or abs(d - outer) <= DECISION_TOL
                c = np.inf if d < inner else (0.0 if d > outer else outer - d)
                depth = inner - d
                depth = depth if depth >= 0.0 else 0.0
                acc[b] += 0.0 if redo else c
                acc2[b] += 0.0 if redo else depth
                flag[b] += 1.0 if redo else 0.0
    for b in range(nb):
        if flag[b] != 0.0:
            _threats_exact(b, xn, yn, seg, cyl, radius, margin, clear, acc, acc2)
    if prm.shape[0] > 0 or par[P_CEIL] < np.inf:
        _prism_threats(nb, xn, yn, zn, prm, pedge, radius, margin, clear, par[P_CEIL], acc, acc2)
    for b in range(nb):
        terms[n, 1, b] = acc[b]
        vio[n, 0, b] = acc2[b]

    # Altitude and depth below ground.
    href = par[P_HREF]
    for k in range(K):
        for b in range(nb):
            tmp[k, b] = np.inf if hn[k, b] < 0 else abs(hn[k, b] - href)
    pairwise_lanes(tmp, K, nb, acc)
    for k in range(K):
        for b in range(nb):
            tmp[k, b] = -hn[k, b] if -hn[k, b] >= 0.0 else 0.0
    pairwise_lanes(tmp, K, nb, acc2)
    for b in range(nb):
        terms[n, 2, b] = acc[b]
        vio[n, 1, b] = acc2[b]

    # Substituted projections: before (none: the first segment's), after (none: the last's).
    for j in range(S):
        q = max(j - 1, 0)
        for b in range(nb):
            keep = j == 0 or seg[0, j, b] != 0.0 or seg[1, j, b] != 0.0
            sub[0, j, b] = seg[0, j, b] if keep else sub[0, q, b]
            sub[1, j, b] = seg[1, j, b] if keep else sub[1, q, b]
            sub[2, j, b] = seg[3, j, b] if keep else sub[2, q, b]
    for j in range(S - 1, -1, -1):
        q = min(j + 1, S - 1)
        for b in range(nb):
            keep = j == S - 1 or seg[0, j, b] != 0.0 or seg[1, j, b] != 0.0
            sub[3, j, b] = seg[0, j, b] if keep else sub[3, q, b]
            sub[4, j, b] = seg[1, j, b] if keep else sub[4, q, b]
            sub[5, j, b] = seg[3, j, b] if keep else sub[5, q, b]

    # Turning angle at vertex i between s1[i] and s2[i + 1], degrees. A decision flip at a
    # threshold <= DECISION_TOL changes the term by less than that: no exact re-check then.
    thr = par[P_THR_TURN]
    for i in range(K):
        for b in range(nb):
            ux = sub[0, i, b]
            uy = sub[1, i, b]
            vx = sub[3, i + 1, b]
            vy = sub[4, i + 1, b]
            tmp[i, b] = atan2(abs(ux * vy - uy * vx), ux * vx + uy * vy) * RAD2DEG
    if thr > DECISION_TOL:
        for i in range(K):
            for b in range(nb):
                if abs(tmp[i, b] - thr) <= DECISION_TOL:
                    ux = sub[0, i, b]
                    uy = sub[1, i, b]
                    vx = sub[3, i + 1, b]
                    vy = sub[4, i + 1, b]
                    tmp[i, b] = math.atan2(abs(ux * vy - uy * vx), ux * vx + uy * vy) * RAD2DEG
    for i in range(K):
        for b in range(nb):
            tmp[i, b] = abs(tmp[i, b]) if abs(tmp[i, b]) > thr else 0.0
    pairwise_lanes(tmp, K, nb, acc)
    for b in range(nb):
        terms[n, 3, b] = acc[b]

    # Climb angles (real dz over the substituted horizontal length of each side), their changes.
    thr = par[P_THR_CLIMB]
    for j in range(S):
        for b in range(nb):
            ang[0, j, b] = atan2(seg[2, j, b], sub[2, j, b]) * RAD2DEG
        differ = 0.0
        for b in range(nb):
            ang[1, j, b] = ang[0, j, b]
            differ += 1.0 if sub[5, j, b] != sub[2, j, b] else 0.0
        if differ != 0.0:  # rare: a zero projection substituted differently on each side
            for b in range(nb):
                if sub[5, j, b] != sub[2, j, b]:
                    ang[1, j, b] = atan2(seg[2, j, b], sub[5, j, b]) * RAD2DEG
    for i in range(K):
        for b in range(nb):
            tmp[i, b] = abs(ang[1, i + 1, b] - ang[0, i, b])
    if thr > DECISION_TOL:
        for i in range(K):
            for b in range(nb):
                if abs(tmp[i, b] - thr) <= DECISION_TOL:
                    c1 = math.atan2(seg[2, i, b], math.hypot(sub[0, i, b], sub[1, i, b])) * RAD2DEG
                    c2 = math.atan2(seg[2, i + 1, b], math.hypot(sub[3, i + 1, b], sub[4, i + 1, b])) * RAD2DEG
                    tmp[i, b] = abs(c2 - c1)
    for i in range(K):
        for b in range(nb):
            tmp[i, b] = tmp[i, b] if tmp[i, b] > thr else 0.0
    pairwise_lanes(tmp, K, nb, acc)
    for b in range(nb):
        terms[n, 4, b] = acc[b]


@njit(inline="always", error_model="numpy")
def _pair_segment(x0: float, y0: float, z0: float, x1: float, y1: float, z1: float) -> tuple[float, float]:
    """One segment of a pair, from the relative positions ``p_a - p_c`` at its ends: the squared
    distance at its end and the least squared distance along it (closest approach, ``t``
    clamped to ``[0, 1]``)."""
    drx = x1 - x0
    dry = y1 - y0
    drz = z1 - z0
    dd = (drx * drx + dry * dry) + drz * drz
    t = (-((x0 * drx + y0 * dry) + z0 * drz)) / dd
    t = min(max(t, 0.0), 1.0) if dd > 0.0 else 0.0
    clx = x0 + t * drx
    cly = y0 + t * dry
    clz = z0 + t * drz
    return (x1 * x1 + y1 * y1) + z1 * z1, (clx * clx + cly * cly) + clz * clz


@subroutine
def _team_terms(nb, px, py, pz, uav, weights, heads, tails, mu, ref_diff, par, solo, every, players,  # noqa: ANN001
                form, hit, tmp, acc, acc2, flag, terms, vio, res) -> None:
    """Formation cost and separation for the whole team (:mod:`staghunt.costs.formation`), then
    ``J_s``, ``J_f``, ``J_n`` (:func:`staghunt.costs.evaluate`).

    Writes ``vio[:, 2]`` (separation deficit) and ``res (3, N, B)`` = ``J_f``, ``J_s``, ``J_n``.
    Scratch: ``form (3, N, S, B)`` = ``E`` (eq. 5), nearest squared distance at the waypoints,
    along the segments; ``hit (2, S, B)`` collisions at waypoints / along segments;
    ``tmp (>= S, B)``; ``acc``, ``acc2``, ``flag`` ``(B,)``. For ``N > PRUNE_MIN_UAVS`` a
    pair's segments along which its relative position stays, in every lane of the block,
    farther than its separation limit on some axis are skipped (exact; see the comment in
    the body). With ``solo`` (a problem with fixed paths), only the pairs and the
    collisions, ``J_f`` and ``J_n`` of ``players`` (``every``: the collisions of all UAVs,
    from those pairs), and pairs are pruned at any N.
    """
    N = px.shape[0]
    K = px.shape[1] - 2
    S = K + 1
    continuous = par[P_CONTINUOUS] != 0.0
    E, near2, seg2 = form[0], form[1], form[2]

    # Formation error, edge form, at the free waypoints. With ``solo`` and not ``every`` only
    # the players' collisions and J are made (below): the other UAVs' rows are left unwritten.
    for n in range(N):
        if not _kept(solo, every, players, n):
            continue
        for k in range(K):
            _fill(E[n, k], nb, 0.0)
    for m in range(heads.shape[0]):
        if solo:
            used = False
            for c in range(players.shape[0]):
                used = used or mu[players[c], m] != 0.0
            if not used:
                continue
        hd = heads[m]
        tl = tails[m]
        r0 = ref_diff[m, 0]
        r1 = ref_diff[m, 1]
        r2 = ref_diff[m, 2]
        for k in range(K):
            for b in range(nb):
                d0 = (px[hd, k + 1, b] - px[tl, k + 1, b]) - r0
                d1 = (py[hd, k + 1, b] - py[tl, k + 1, b]) - r1
                d2 = (pz[hd, k + 1, b] - pz[tl, k + 1, b]) - r2
                tmp[k, b] = (d0 * d0 + d1 * d1) + d2 * d2
        for n in range(N):
            w = mu[n, m]
            if w != 0.0 and not (solo and not _is_player(players, n)):
                for k in range(K):
                    for b in range(nb):
                        E[n, k, b] += w * tmp[k, b]

    # Nearest team-mate, squared, at the waypoints and along the synchronised segments.
    for n in range(N):
        if not _kept(solo, every, players, n):
            continue
        for j in range(S):
            _fill(near2[n, j], nb, np.inf)
            _fill(seg2[n, j], nb, np.inf)
    # Pruning past small N: per UAV and waypoint, the bounding box of its position over the
    # block's lanes. In every lane, the relative position p_a - p_c of a pair at waypoint i
    # (as the kernel rounds it: rounding is monotone) lies in the box's difference,
    # [lo_a - hi_c, hi_a - lo_c] per axis, so along segment j it stays in the union of the
    # differences at its ends. Where that union lies farther than the pair's separation limit
    # (plus a guard, far above the rounding of the closest approach) from 0 on some axis, the
    # pair is farther apart than the limit all along the segment and at its end waypoint in
    # every lane: its distances there cannot make a collision or a deficit and are skipped
    # (an entry of ``near2``/``seg2`` may then stay above its true value, but only where both
    # exceed every limit, which decides nothing). Exact: the same collisions, deficits and
    # J_f. The union of differences is tighter than the gap between the two UAVs' boxes of
    # the segment: the team moves together along a segment, which those boxes ignore.
    prune = N > PRUNE_MIN_UAVS or solo
    box = np.empty((6, N, K + 2)) if prune else np.empty((6, 1, 1))  # lo, hi of x, y, z
    near = np.ones(S, dtype=np.int64)
    if prune:
        for n in range(N):
            # With ``solo`` a UAV other than the players has one fixed path in every lane.
            lanes = nb if not solo or _is_player(players, n) else min(nb, 1)
            for i in range(K + 2):
                x0 = np.inf
                x1 = -np.inf
                y0 = np.inf
                y1 = -np.inf
                z0 = np.inf
                z1 = -np.inf
                for b in range(lanes):
                    x0 = min(x0, px[n, i, b])
                    x1 = max(x1, px[n, i, b])
                    y0 = min(y0, py[n, i, b])
                    y1 = max(y1, py[n, i, b])
                    z0 = min(z0, pz[n, i, b])
                    z1 = max(z1, pz[n, i, b])
                box[0, n, i] = x0
                box[1, n, i] = x1
                box[2, n, i] = y0
                box[3, n, i] = y1
                box[4, n, i] = z0
                box[5, n, i] = z1
    dw = tmp[0]  # a pair's squared distances on one segment: at its end waypoint, along it
    ds = tmp[1]
    for a in range(N):
        for c in range(a + 1, N):
            if solo and not (_is_player(players, a) or _is_player(players, c)):
                continue
            keep_a = _kept(solo, every, players, a)  # the UAVs whose rows are read
            keep_c = _kept(solo, every, players, c)
            if prune:
                reach = max(uav[a, U_LIMIT], uav[c, U_LIMIT]) + PRUNE_GUARD
                n_near = 0
                for j in range(S):
                    g = -np.inf  # the largest distance of the union from 0 over the axes
                    for q in range(0, 6, 2):
                        lo = min(box[q, a, j] - box[q + 1, c, j], box[q, a, j + 1] - box[q + 1, c, j + 1])
                        hi = max(box[q + 1, a, j] - box[q, c, j], box[q + 1, a, j + 1] - box[q, c, j + 1])
                        g = max(g, max(lo, -hi))
                    k = 0 if g > reach else 1
                    near[j] = k
                    n_near += k
                if n_near == 0:
                    continue
            # Segment j of the pair, lane by lane: the relative positions p_a - p_c (NumPy's
            # ``rel``) at its ends, the squared distance at its end (free waypoint j + 1, for
            # j < K) and, with ``continuous``, along it; one pass, no stored relative positions.
            # With ``solo`` a fixed UAV has the same path in every lane: its coordinates are read
            # once per segment instead of in every lane (the same numbers).
            fixed_a = solo and not _is_player(players, a)
            fixed_c = solo and not _is_player(players, c)
            for j in range(S):
                if near[j] == 0 or not (continuous or j < K):
                    continue
                if fixed_c:
                    cx0, cy0, cz0 = px[c, j, 0], py[c, j, 0], pz[c, j, 0]
                    cx1, cy1, cz1 = px[c, j + 1, 0], py[c, j + 1, 0], pz[c, j + 1, 0]
                    for b in range(nb):
                        dw[b], ds[b] = _pair_segment(px[a, j, b] - cx0, py[a, j, b] - cy0, pz[a, j, b] - cz0,
                                                     px[a, j + 1, b] - cx1, py[a, j + 1, b] - cy1,
                                                     pz[a, j + 1, b] - cz1)
                elif fixed_a:
                    ax0, ay0, az0 = px[a, j, 0], py[a, j, 0], pz[a, j, 0]
                    ax1, ay1, az1 = px[a, j + 1, 0], py[a, j + 1, 0], pz[a, j + 1, 0]
                    for b in range(nb):
                        dw[b], ds[b] = _pair_segment(ax0 - px[c, j, b], ay0 - py[c, j, b], az0 - pz[c, j, b],
                                                     ax1 - px[c, j + 1, b], ay1 - py[c, j + 1, b],
                                                     az1 - pz[c, j + 1, b])
                else:
                    for b in range(nb):
                        dw[b], ds[b] = _pair_segment(px[a, j, b] - px[c, j, b], py[a, j, b] - py[c, j, b],
                                                     pz[a, j, b] - pz[c, j, b], px[a, j + 1, b] - px[c, j + 1, b],
                                                     py[a, j + 1, b] - py[c, j + 1, b],
                                                     pz[a, j + 1, b] - pz[c, j + 1, b])
                for side in range(2):  # the pair's two UAVs, those whose rows are read
                    n = a if side == 0 else c
                    if not (keep_a if side == 0 else keep_c):
                        continue
                    if j < K:
                        for b in range(nb):
                            near2[n, j, b] = min(near2[n, j, b], dw[b])
                    if continuous:
                        for b in range(nb):
                            seg2[n, j, b] = min(seg2[n, j, b], ds[b])

    # Collisions (eq. 6: distance <= d_s + 2 r), deficit, J_f (eq. 7), then J_s and J_n.
    for n in range(N):
        if not _kept(solo, every, players, n):
            continue
        limit = uav[n, U_LIMIT]
        for k in range(K):
            for b in range(nb):
                d = math.sqrt(near2[n, k, b])
                hit[0, k, b] = 1.0 if d <= limit else 0.0
                tmp[k, b] = max(limit - d, 1e-9) if d <= limit else 0.0
        pairwise_lanes(tmp, K, nb, acc2)
        if continuous:
            for j in range(S):
                for b in range(nb):
                    d = math.sqrt(seg2[n, j, b])
                    hit[1, j, b] = 1.0 if d <= limit else 0.0
                    tmp[j, b] = max(limit - d, 1e-9) if d <= limit else 0.0
            pairwise_lanes(tmp, S, nb, acc)
            for b in range(nb):
                acc2[b] = acc2[b] + acc[b]
            for k in range(K):
                for b in range(nb):
                    h = hit[0, k, b] != 0.0 or hit[1, k, b] != 0.0 or hit[1, k + 1, b] != 0.0
                    hit[0, k, b] = 1.0 if h else 0.0
        for k in range(K):
            for b in range(nb):
                tmp[k, b] = np.inf if hit[0, k, b] != 0.0 else E[n, k, b]
        pairwise_lanes(tmp, K, nb, acc)
        beta = uav[n, U_BETA]
        for b in range(nb):
            vio[n, 2, b] = acc2[b]
            jf = acc[b]
            single = 0.0
            for i in range(5):
                w = weights[n, i]
                single += 0.0 if w == 0.0 else w * terms[n, i, b]
            res[0, n, b] = jf
            res[1, n, b] = single
            res[2, n, b] = single + (0.0 if beta == 0.0 else beta * jf)


@subroutine
def _advance(mode, q0, nb, it, key, inertia, X, V, PB, gbest, initial, sw, member, offsets, fixed,  # noqa: ANN001
             par, sww, px, py, ph, stx, sty, sth, prev, bits1, bits2, kept) -> None:
    """Move particles ``q0 .. q0+nb`` and build their team waypoints.

    ``MODE_INIT``: uniform draw in the search ranges (``initial`` ``(W, S, K, 3)``: warm
    particles ``0 .. W-1``, replacing their draws); ``MODE_STEP``: velocity and position step (paper eq. 10 corrected, clamp and
    mirror) in :func:`staghunt.solvers.pso.velocity_step`'s arithmetic order. Draws come from
    the counter-based stream of ``key`` indexed by ``(it, s, k, c, p)``.
    Then decode (:func:`staghunt.encoding.decode`: steps from each swarm's start, clamped to its
    box after every step) into ``sww (S, 3, K, B)`` and assemble the team
    (:meth:`~staghunt.solvers.problem.SwarmProblem.team_waypoints`) into ``px``, ``py``
    (columns ``1..K``) and ``ph``; with ``kept`` (see :func:`uav_pass`) a fixed path's rows
    (``member[n] < 0``) are left as :func:`_fixed_rows` filled them. Scratch: ``stx``,
    ``sty``, ``sth`` ``(B,)`` steps, ``prev`` ``(3, B)``; ``bits1``, ``bits2`` ``(B,)`` uint64.
    """
    S, K, _, P = X.shape
    u1 = bits1.view(np.float64)
    u2 = bits2.view(np.float64)
    c1 = par[P_C1]
    c2 = par[P_C2]
    for s in range(S):
        for k in range(K):
            for c in range(3):
                lo = sw[s, SW_RANGE_LOW + c]
                hi = sw[s, SW_RANGE_HIGH + c]
                vm = sw[s, SW_VMAX + c]
                g = gbest[s, k, c]
                base = np.uint64((((it * S + s) * K + k) * 3 + c)) * np.uint64(P) + np.uint64(q0)
                xr, vr, pr = X[s, k, c, q0:q0 + nb], V[s, k, c, q0:q0 + nb], PB[s, k, c, q0:q0 + nb]
                if mode == MODE_INIT:
                    for b in range(nb):
                        bits1[b] = unit_bits(counter_hash(key, base + np.uint64(b)))
                    for b in range(nb):
                        xr[b] = lo + (u1[b] - 1.0) * (hi - lo)
                    for b in range(min(nb, initial.shape[0] - q0)):
                        xr[b] = initial[q0 + b, s, k, c]
                    continue
                for b in range(nb):
                    bits1[b], bits2[b] = unit_bits_pair(counter_hash(key, base + np.uint64(b)))
                for b in range(nb):
                    x = xr[b]
                    v = (inertia * vr[b] + c1 * (u1[b] - 1.0) * (pr[b] - x)) + c2 * (u2[b] - 1.0) * (g - x)
                    v = min(max(v, -vm), vm)
                    x = x + v
                    vr[b] = -v if (x < lo or x > hi) else v
                    xr[b] = min(max(x, lo), hi)

    for s in range(S):
        small = sw[s, SW_SMALL] != 0.0
        ctr, s0, c0 = sw[s, SW_CENTRE], sw[s, SW_SIN], sw[s, SW_COS]
        for c in range(3):
            _fill(prev[c], nb, sw[s, SW_START + c])
        for k in range(K):
            rr, pr, fr = X[s, k, 0, q0:q0 + nb], X[s, k, 1, q0:q0 + nb], X[s, k, 2, q0:q0 + nb]
            if small:  # psi within pi/4 of 0, phi within pi/4 of ctr: no range reduction
                for b in range(nb):
                    sp, cp = sincos_small(pr[b])
                    sd, cd = sincos_small(fr[b] - ctr)
                    rc = rr[b] * cp
                    stx[b] = rc * (c0 * cd - s0 * sd)
                    sty[b] = rc * (s0 * cd + c0 * sd)
                    sth[b] = rr[b] * sp
            else:
                for b in range(nb):
                    sp, cp = sincos(pr[b])
                    sf, cf = sincos(fr[b])
                    rc = rr[b] * cp
                    stx[b] = rc * cf
                    sty[b] = rc * sf
                    sth[b] = rr[b] * sp
            for c in range(3):
                st = stx if c == 0 else (sty if c == 1 else sth)
                lo = sw[s, SW_LOW + c]
                hi = sw[s, SW_HIGH + c]
                for b in range(nb):
                    prev[c, b] = min(max(prev[c, b] + st[b], lo), hi)
                for b in range(nb):
                    sww[s, c, k, b] = prev[c, b]

    for n in range(member.shape[0]):
        m = member[n]
        if m < 0 and kept:
            continue
        for k in range(K):
            if m < 0:
                _fill(px[n, k + 1], nb, fixed[n, k, 0])
                _fill(py[n, k + 1], nb, fixed[n, k, 1])
                _fill(ph[n, k], nb, fixed[n, k, 2])
            else:
                ox, oy, oh = offsets[n, 0], offsets[n, 1], offsets[n, 2]
                for b in range(nb):
                    px[n, k + 1, b] = sww[m, 0, k, b] + ox
                for b in range(nb):
                    py[n, k + 1, b] = sww[m, 1, k, b] + oy
                for b in range(nb):
                    ph[n, k, b] = sww[m, 2, k, b] + oh


@subroutine
def _absolute_z(nb, px, py, ph, pz, uav, grid, par, member, solo, kept) -> None:  # noqa: ANN001
    """Start and goal columns of the full paths, and absolute ``z`` of the free waypoints.
    With ``solo`` (fixed paths: a deviation search or ``MODE_DEVIATE``) a UAV with
    ``member[n] < 0`` has the same path in every lane: its ground is looked up in lane 0 only
    and copied (the same numbers; on a DEM site the lookups of the fixed team-mates were most
    of a deviation's cost); with ``kept`` its rows are left as :func:`_fixed_rows` filled them."""
    N, K = ph.shape[0], ph.shape[1]
    flat = par[P_TERRAIN] == 0.0
    bilinear = par[P_TERRAIN] == 3.0
    ox, oy, cell = par[P_OX], par[P_OY], par[P_CELL]
    for n in range(N):
        if kept and member[n] < 0:
            continue
        _fill(px[n, 0], nb, uav[n, U_START])
        _fill(py[n, 0], nb, uav[n, U_START + 1])
        _fill(pz[n, 0], nb, uav[n, U_START_Z])
        _fill(px[n, K + 1], nb, uav[n, U_GOAL])
        _fill(py[n, K + 1], nb, uav[n, U_GOAL + 1])
        _fill(pz[n, K + 1], nb, uav[n, U_GOAL_Z])
        same = solo and member[n] < 0
        for k in range(K):
            if flat:
                for b in range(nb):
                    pz[n, k + 1, b] = ph[n, k, b] + 0.0
            elif same:
                _fill(pz[n, k + 1], nb, ground_z(px[n, k + 1, 0], py[n, k + 1, 0], ph[n, k, 0], grid, par))
            elif bilinear:
                for b in range(nb):
                    pz[n, k + 1, b] = bilinear_z(px[n, k + 1, b], py[n, k + 1, b], ph[n, k, b], grid, ox, oy, cell)
            else:
                for b in range(nb):
                    pz[n, k + 1, b] = ground_z(px[n, k + 1, b], py[n, k + 1, b], ph[n, k, b], grid, par)


@subroutine
def _bests(mode, q0, nb, X, PB, pcost, pviol, cost, viol, J, players, par, solo, vio, res, tmp, acc, better) -> None:  # noqa: ANN001
    """Compared costs ``(C, P)`` (players' ``J`` or the team sum), total violation (NumPy's
    summation order; with ``solo`` the players' own), per-UAV ``J``, and the personal bests
    of particles ``q0 .. q0+nb``."""
    S, K = X.shape[0], X.shape[1]
    N = vio.shape[0]
    C = cost.shape[0]
    rows = C if solo else N
    for r in range(rows):
        n = players[r] if solo else r
        for i in range(3):
            for b in range(nb):
                tmp[3 * r + i, b] = vio[n, i, b]
    pairwise_lanes(tmp, 3 * rows, nb, acc)
    for b in range(nb):
        viol[q0 + b] = acc[b]
    for n in range(N):
        own = not solo or _is_player(players, n)
        for b in range(nb):
            J[n, q0 + b] = res[2, n, b] if own else np.nan
    if par[P_SUM] != 0.0:
        for n in range(N):
            for b in range(nb):
                tmp[n, b] = res[2, n, b]
        pairwise_lanes(tmp, N, nb, acc)
        for b in range(nb):
            cost[0, q0 + b] = acc[b]
    else:
        for c in range(C):
            pl = players[c]
            for b in range(nb):
                cost[c, q0 + b] = res[2, pl, b]
    for b in range(nb):
        p = q0 + b
        better[b] = 1.0 if (mode == MODE_INIT or _dominates(cost, p, viol[p], pcost, p, pviol[p])) else 0.0
    for c in range(C):
        for b in range(nb):
            if better[b] != 0.0:
                pcost[c, q0 + b] = cost[c, q0 + b]
    for b in range(nb):
        if better[b] != 0.0:
            pviol[q0 + b] = viol[q0 + b]
    for s in range(S):
        for k in range(K):
            for c in range(3):
                for b in range(nb):
                    if better[b] != 0.0:
                        PB[s, k, c, q0 + b] = X[s, k, c, q0 + b]


@subroutine
def _load(q0, nb, wp, px, py, ph) -> None:  # noqa: ANN001
    """``MODE_EVALUATE``: free waypoints ``wp[q0 .. q0+nb]`` ``(P, N, K, 3)`` into ``px``, ``py``, ``ph``."""
    N, K = ph.shape[0], ph.shape[1]
    for n in range(N):
        for k in range(K):
            for b in range(nb):
                px[n, k + 1, b] = wp[q0 + b, n, k, 0]
                py[n, k + 1, b] = wp[q0 + b, n, k, 1]
                ph[n, k, b] = wp[q0 + b, n, k, 2]


@subroutine
def _store(q0, nb, terms, vio, res, terms_out, vio_out, res_out) -> None:  # noqa: ANN001
    """``MODE_EVALUATE``: a block's results into ``terms_out (P, N, 5)``, ``vio_out (P, N, 3)``,
    ``res_out (P, 3, N)``."""
    N = terms.shape[0]
    for b in range(nb):
        for n in range(N):
            for i in range(5):
                terms_out[q0 + b, n, i] = terms[n, i, b]
            for i in range(3):
                vio_out[q0 + b, n, i] = vio[n, i, b]
                res_out[q0 + b, i, n] = res[i, n, b]


@njit(cache=True, nogil=True, error_model="numpy")
def uav_pass(mode, q0, nb, it, key, inertia, X, V, PB, gbest, initial, sw, member, offsets, fixed,  # noqa: ANN001
             par, wp, uav, cyl, prm, pedge, grid, sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2,
             seg, sub, ang, tmp, acc, acc2, flag, terms, vio) -> None:
    """Entry 1: particles ``q0 .. q0+nb`` moved (``MODE_INIT``, ``MODE_STEP``) and decoded into
    team paths, or (``MODE_EVALUATE``) waypoints ``wp`` loaded; absolute altitudes into
    ``px``, ``py``, ``pz`` ``(N, K+2, B)`` and ``ph`` ``(N, K, B)``; then every UAV's ``J_s``
    terms ``terms (N, 5, B)`` and obstacle/ground violations ``vio[:, 0:2]``. In ``MODE_STEP``
    (only ever run by :func:`iterate`) a fixed path's rows of all these are not written: they
    are the same in every lane and iteration, and :func:`iterate` fills them once per call
    (:func:`_fixed_rows`); a deviation swarm wrote them again in every block, 53 rows of the
    block's width per team-mate for 10 waypoints."""
    solo = par.shape[0] > N_PAR and mode != MODE_EVALUATE
    kept = solo and mode == MODE_STEP  # the fixed paths' rows: filled once per call by iterate
    if mode >= MODE_EVALUATE:
        _load(q0, nb, wp, px, py, ph)
    else:
        _advance(mode, q0, nb, it, key, inertia, X, V, PB, gbest, initial, sw, member, offsets,
                 fixed, par, sww, px, py, ph, stx, sty, sth, prev, bits1, bits2, kept)
    _absolute_z(nb, px, py, ph, pz, uav, grid, par, member, solo, kept)
    for n in range(uav.shape[0]):
        if kept and member[n] < 0:
            continue
        if solo and member[n] < 0:  # a fixed path: its constant terms (see SOLO_STRIDE)
            base = N_PAR + SOLO_STRIDE * n
            for i in range(5):
                _fill(terms[n, i], nb, par[base + i])
            for i in range(2):
                _fill(vio[n, i], nb, par[base + 5 + i])
        else:
            _uav_terms(nb, n, px, py, pz, ph, uav, cyl, prm, pedge, par, seg, sub, ang, tmp, acc, acc2, flag, terms, vio)


@njit(cache=True, nogil=True, error_model="numpy")
def team_pass(mode, q0, nb, px, py, pz, uav, weights, heads, tails, mu, ref_diff, par,  # noqa: ANN001
               form, hit, tmp, acc, acc2, flag, better, terms, vio, res,
               X, PB, pcost, pviol, cost, viol, J, players, terms_out, vio_out, res_out) -> None:
    """Entry 2: formation cost, separation, ``J_n`` for a block; then the compared costs and
    personal bests of particles ``q0 .. q0+nb`` (``MODE_INIT``, ``MODE_STEP``) or the twin's
    outputs (``MODE_EVALUATE``). ``MODE_DEVIATE`` (``par`` with the fixed paths' constants,
    ``member[n] < 0`` for them): the outputs of the ``players``' deviations, pairs with a player
    only; every UAV's collisions are still counted (a fixed UAV's separation deficit against the
    players, so that, with fixed paths clear of each other, the total violation is zero exactly
    when the full evaluation's is), but only the players' ``J`` are meaningful."""
    solo = par.shape[0] > N_PAR and mode != MODE_EVALUATE
    _team_terms(nb, px, py, pz, uav, weights, heads, tails, mu, ref_diff, par, solo, mode == MODE_DEVIATE,
                players, form, hit, tmp, acc, acc2, flag, terms, vio, res)
    if mode >= MODE_EVALUATE:
        _store(q0, nb, terms, vio, res, terms_out, vio_out, res_out)
    else:
        _bests(mode, q0, nb, X, PB, pcost, pviol, cost, viol, J, players, par, solo, vio, res, tmp, acc, better)


_uav_pass = entry_call(uav_pass)
_team_pass = entry_call(team_pass)
"""The two entries as :func:`iterate` and :func:`polish` call them: through their addresses in
``uav_entries`` and ``team_entries`` (:func:`staghunt.engine.jit.entry_call`), so that neither
caller compiles them again inside itself."""


@njit(cache=True, nogil=True, error_model="numpy")
def select_global(cost: np.ndarray, viol: np.ndarray, gcost: np.ndarray, gviol: float, masked: bool) -> int:
    """The new global best among the allocations that dominate ``(gcost, gviol)`` (all if not
    ``masked``), or ``-1``: :func:`staghunt.solvers.dominance.best_index` (least violation, then
    smallest ``sum log J``, then lowest index). ``cost``: ``(C, P)``; ``gcost``: ``(C, 1)``."""
    C, P = cost.shape
    best_key = np.inf
    best_i = -1
    best_v = np.inf
    best_vi = -1
    for i in range(P):
        v = viol[i]
        if masked and not _dominates(cost, i, v, gcost, 0, gviol):
            continue
        if best_vi < 0 or v < best_v:
            best_v = v
            best_vi = i
        if v > 0.0:
            continue
        key = 0.0
        for c in range(C):
            key += math.log(max(cost[c, i], 1e-300))
        if key < best_key:
            best_key = key
            best_i = i
    return best_i if best_i >= 0 else best_vi


@njit(cache=True, nogil=True, error_model="numpy")
def _global(it, state, X, gbest, cost, viol, J, gcost, history, rhistory, hviol) -> None:  # noqa: ANN001
    """After iteration ``it``'s blocks: the global best (:func:`select_global`), the histories
    and the inertia's damping (``state`` = ``[inertia, global violation, damping]``)."""
    S, K = X.shape[0], X.shape[1]
    g = select_global(cost, viol, gcost, state[1], it != 0)
    if g >= 0:
        for s in range(S):
            for k in range(K):
                for c in range(3):
                    gbest[s, k, c] = X[s, k, c, g]
        for c in range(cost.shape[0]):
            gcost[c, 0] = cost[c, g]
        state[1] = viol[g]
        for n in range(J.shape[0]):
            rhistory[it, n] = J[n, g]
    else:
        for n in range(J.shape[0]):
            rhistory[it, n] = rhistory[it - 1, n]
    for c in range(cost.shape[0]):
        history[it, c] = gcost[c, 0]
    hviol[it] = state[1]
    if it != 0:
        state[0] = state[0] * state[2]


@subroutine
def _block(mode, q0, nb, it, key, inertia, t, shared, scratch, probe) -> None:  # noqa: ANN001
    """Both entries on particles ``q0 .. q0+nb`` of :func:`iterate`'s swarm, on thread ``t``'s
    scratch: the one place where ``iterate`` spells their arguments (``shared``: the run's,
    model's and swarm's arrays; ``scratch``: the per-thread arrays, thread axis first, in the
    order :func:`iterate` packs them). With ``probe``, only check that ``shared``'s entry tables
    hold both entries' code (else ``RuntimeError``)."""
    (X, V, PB, gbest, initial, sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, weights,
     heads, tails, mu, ref_diff, players, pcost, pviol, cost, viol, J, terms_out, vio_out, res_out, uav_entries,
     team_entries) = shared
    (sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, seg, sub, ang, tmp, acc, acc2, flag,
     terms, vio, form, hit, better, res) = scratch
    _uav_pass(uav_entries, probe, mode, q0, nb, it, key, inertia, X, V, PB, gbest, initial, sw, member,
              offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, sww[t], px[t], py[t], pz[t], ph[t], stx[t],
              sty[t], sth[t], prev[t], bits1[t], bits2[t], seg[t], sub[t], ang[t], tmp[t], acc[t], acc2[t],
              flag[t], terms[t], vio[t])
    _team_pass(team_entries, probe, mode, q0, nb, px[t], py[t], pz[t], uav, weights, heads, tails, mu, ref_diff,
               par, form[t], hit[t], tmp[t], acc[t], acc2[t], flag[t], better[t],
               terms[t], vio[t], res[t], X, PB, pcost, pviol, cost, viol, J, players, terms_out,
               vio_out, res_out)


@subroutine
def _fixed_rows(member, fixed, uav, grid, par, px, py, pz, ph, terms, vio) -> None:  # noqa: ANN001
    """In every thread's scratch (the leading axis of ``px .. vio``) and on all of its lanes,
    the rows of the fixed paths (``member[n] < 0``) of a problem with fixed paths, as
    :func:`uav_pass` writes them in ``MODE_INIT``: waypoints, start and goal columns, absolute
    ``z`` and the constant terms and violations (see ``SOLO_STRIDE``); the same numbers."""
    if par.shape[0] <= N_PAR:
        return
    K, B = ph.shape[2], ph.shape[3]
    flat = par[P_TERRAIN] == 0.0
    for t in range(px.shape[0]):
        for n in range(member.shape[0]):
            if member[n] >= 0:
                continue
            for k in range(K):
                x, y, h = fixed[n, k, 0], fixed[n, k, 1], fixed[n, k, 2]
                _fill(px[t, n, k + 1], B, x)
                _fill(py[t, n, k + 1], B, y)
                _fill(ph[t, n, k], B, h)
                _fill(pz[t, n, k + 1], B, h + 0.0 if flat else ground_z(x, y, h, grid, par))
            _fill(px[t, n, 0], B, uav[n, U_START])
            _fill(py[t, n, 0], B, uav[n, U_START + 1])
            _fill(pz[t, n, 0], B, uav[n, U_START_Z])
            _fill(px[t, n, K + 1], B, uav[n, U_GOAL])
            _fill(py[t, n, K + 1], B, uav[n, U_GOAL + 1])
            _fill(pz[t, n, K + 1], B, uav[n, U_GOAL_Z])
            base = N_PAR + SOLO_STRIDE * n
            for i in range(5):
                _fill(terms[t, n, i], B, par[base + i])
            for i in range(2):
                _fill(vio[t, n, i], B, par[base + 5 + i])


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def iterate(it0, it1, bs, serial, key, state, X, V, PB, gbest, initial, sw, member, offsets, fixed,  # noqa: ANN001
            par, uav, cyl, prm, pedge, grid, weights, heads, tails, mu, ref_diff, players,
            pcost, pviol, cost, viol, J, gcost, history, rhistory, hviol,
            sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, seg, sub, ang, tmp, acc, acc2, flag,
            terms, vio, form, hit, better, res, wp, terms_out, vio_out, res_out, uav_entries,
            team_entries) -> None:
    """Iterations ``it0 .. it1-1`` of a swarm run in one call (iteration 0: the initial draw),
    each over all particles in blocks of ``bs``, then the global best, the histories
    ``history (I+1, C)``, ``rhistory (I+1, N)``, ``hviol (I+1,)`` and the inertia's damping
    (:func:`_global`; ``state`` = ``[inertia, global violation, damping]``, carried from call to
    call). The blocks run in a parallel loop (a block on thread ``get_thread_id()`` with that
    thread's scratch, the leading axis of ``sww .. res``) or, with ``serial``, in a plain loop
    on scratch 0 (no parallel launch per iteration). Every particle's work is its own and the
    global best is chosen after the loop, so results depend neither on the thread count nor on
    the block size. The fixed paths' rows of every thread's scratch are filled first
    (:func:`_fixed_rows`): blocks in ``MODE_STEP`` do not write them again."""
    P = X.shape[3]
    n_blocks = (P + bs - 1) // bs
    shared = (X, V, PB, gbest, initial, sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, weights,
              heads, tails, mu, ref_diff, players, pcost, pviol, cost, viol, J, terms_out, vio_out, res_out,
              uav_entries, team_entries)
    scratch = (sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, seg, sub, ang, tmp, acc, acc2, flag,
               terms, vio, form, hit, better, res)
    _block(MODE_STEP, 0, 0, it0, key, 0.0, 0, shared, scratch, True)  # raises here, not in the loop
    _fixed_rows(member, fixed, uav, grid, par, px, py, pz, ph, terms, vio)
    for it in range(it0, it1):
        mode = MODE_INIT if it == 0 else MODE_STEP
        inertia = state[0]
        if serial:
            for blk in range(n_blocks):
                _block(mode, blk * bs, min(bs, P - blk * bs), it, key, inertia, 0, shared, scratch, False)
        else:
            for blk in prange(n_blocks):
                _block(mode, blk * bs, min(bs, P - blk * bs), it, key, inertia, get_thread_id(), shared, scratch,
                       False)
        _global(it, state, X, gbest, cost, viol, J, gcost, history, rhistory, hviol)


@subroutine
def _candidate(best, i, sign, step, lower, upper, out) -> None:  # noqa: ANN001
    """Row ``out (K, 3)``: ``best (K, 3)`` with coordinate ``i`` (waypoint ``i // 3``, axis
    ``i % 3``) moved by ``sign * step`` (``sign`` 0: none), clamped to the site box, in NumPy's
    arithmetic (``clip(best + step * move, lower, upper)``)."""
    K = best.shape[0]
    for k in range(K):
        for c in range(3):
            m = sign if k * 3 + c == i else 0.0
            v = best[k, c] + step * m
            v = max(v, lower[c])
            out[k, c] = min(v, upper[c])


@njit(cache=True, nogil=True, error_model="numpy")
def polish(n, step, min_step, max_evaluations, J0, lower, upper, path,  # noqa: ANN001
           sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, weights, heads, tails, mu,
           ref_diff, players, X, V, PB, gbest, initial, pcost, pviol, cost, viol, J, terms_out, vio_out,
           res_out, sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, seg, sub, ang, tmp, acc, acc2,
           flag, terms, vio, form, hit, better, res, uav_entries, team_entries):
    """The twin of :func:`staghunt.solvers.local.polish` on UAV ``n``'s deviations in one call:
    a pattern search from ``path (K, 3)`` (cost ``J0``) that moves one coordinate by
    ``+-step`` per candidate (``6 K`` of them, rows ``0 .. 6K-1`` of ``wp``, whose other UAVs'
    rows hold the fixed paths), then the combination of every improving move (row ``6 K``),
    evaluated in ``MODE_DEVIATE`` (``inf`` where a candidate breaks a hard constraint); the
    best that lowers ``J_n`` by more than ``1e-9`` relative is taken, else ``step`` halves,
    down to ``min_step``, within ``max_evaluations``. The same decisions in the same order as
    the reference, so the same path. Writes the result into ``path``; returns ``(J_n, spent)``.

    Each pass of the loop evaluates rows ``r0 .. r1-1``: a sweep's candidates, or (``combine``)
    the combined move after a sweep that improved."""
    K = path.shape[0]
    M = 3 * K
    Q = 2 * M
    B = px.shape[2]
    best = path.copy()
    Jc = np.empty(Q)
    gain = np.empty(Q)
    Jn = J0
    spent = 0
    combine = False
    while combine or (step >= min_step and spent + Q + 1 <= max_evaluations):
        if combine:  # the combination of every improving move, clamped
            r0, r1 = Q, Q + 1
            for i in range(M):
                g0 = gain[i]
                g1 = gain[M + i]
                d = 1.0 if g0 >= g1 else -1.0
                v = best[i // 3, i % 3] + step * (d * (1.0 if max(g0, g1) > 0 else 0.0))
                wp[Q, n, i // 3, i % 3] = min(max(v, lower[i % 3]), upper[i % 3])
        else:  # a sweep: every coordinate moved by +-step
            r0, r1 = 0, Q
            for i in range(M):
                _candidate(best, i, 1.0, step, lower, upper, wp[i, n])
                _candidate(best, i, -1.0, step, lower, upper, wp[M + i, n])
        for q0 in range(r0, r1, B):
            nb = min(B, r1 - q0)
            _uav_pass(uav_entries, False, MODE_DEVIATE, q0, nb, 0, np.uint64(0), 0.0, X, V, PB, gbest, initial,
                      sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, sww, px, py, pz, ph, stx,
                      sty, sth, prev, bits1, bits2, seg, sub, ang, tmp, acc, acc2, flag, terms, vio)
            _team_pass(team_entries, False, MODE_DEVIATE, q0, nb, px, py, pz, uav, weights, heads, tails, mu,
                       ref_diff, par, form, hit, tmp, acc, acc2, flag, better, terms, vio, res, X, PB,
                       pcost, pviol, cost, viol, J, players, terms_out, vio_out, res_out)
        spent += r1 - r0
        if combine:  # the combination or the best single move, whichever is cheaper
            combine = False
            combined = _deviation_cost(Q, n, vio_out, res_out)
            i = int(np.argmax(gain))
            if combined < Jc[i]:
                best[:, :] = wp[Q, n]
                Jn = combined
            else:
                _candidate(best, i % M, 1.0 if i < M else -1.0, step, lower, upper, best)
                Jn = Jc[i]
            continue
        top = -np.inf
        for q in range(Q):
            Jc[q] = _deviation_cost(q, n, vio_out, res_out)
            gain[q] = Jn - Jc[q]
            if gain[q] > top:
                top = gain[q]
        if top > 1e-9 * Jn:
            combine = True
        else:
            step /= 2
    path[:, :] = best
    return Jn, spent


@njit(cache=True, nogil=True, error_model="numpy")
def team_search(slide, fractions, step, min_step, max_evaluations, spent, costs, lower, upper, ends,  # noqa: ANN001
                best, sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, weights, heads, tails,
                mu, ref_diff, players, X, V, PB, gbest, initial, pcost, pviol, cost, viol, J, terms_out,
                vio_out, res_out, sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, seg, sub, ang, tmp,
                acc, acc2, flag, terms, vio, form, hit, better, res, uav_entries, team_entries):
    """The twin of :func:`staghunt.solvers.game.team_slide` (``slide``) or
    :func:`~staghunt.solvers.game.team_polish` on the team plan ``best (N, K, 3)`` (costs
    ``costs (N,)``, ``spent`` evaluations already spent) in one call: each sweep writes its
    candidates to rows ``0 .. Q-1`` of ``wp`` (``Q`` = ``2 K`` slides of waypoint ``k`` of every
    UAV towards its waypoint ``k - 1``, then ``k + 1``, by the current fraction of ``fractions``,
    with ``ends (N, 2, 3)`` = start and goal at the ends; or ``6 K`` moves of one coordinate of
    every UAV by ``+step``, then ``-step``), clamped to ``lower``, ``upper``; evaluates them in
    ``MODE_EVALUATE`` and takes, among the feasible ones that Pareto-dominate ``costs`` (no UAV
    worse, one better by more than ``1e-9`` relative), the first with the least key (the slide:
    the product of ``J_n / costs_n``; the polish: the sum of ``J_n``; each in UAV order), else
    the next fraction or half the step (down to ``min_step``), within ``max_evaluations``
    (``N`` per candidate). The same candidates, costs and decisions as the Python loops, so the
    same plan. Writes the plan into ``best`` and its costs into ``costs``; returns ``spent``."""
    N = best.shape[0]
    K = best.shape[1]
    M = 3 * K
    Q = 2 * K if slide else 6 * K
    B = px.shape[2]
    f = 0
    while True:
        if slide:
            if f >= fractions.shape[0] or spent + N * Q > max_evaluations:
                break
            fraction = fractions[f]
            for q in range(Q):
                for n in range(N):
                    for k in range(K):
                        for c in range(3):
                            v = best[n, k, c]
                            if q == k:  # towards the waypoint before (the start for the first)
                                o = ends[n, 0, c] if k == 0 else best[n, k - 1, c]
                                v = v + fraction * (o - v)
                            elif q == K + k:  # towards the waypoint after (the goal for the last)
                                o = ends[n, 1, c] if k == K - 1 else best[n, k + 1, c]
                                v = v + fraction * (o - v)
                            wp[q, n, k, c] = min(max(v, lower[c]), upper[c])
        else:
            if not (step >= min_step and spent + N * Q <= max_evaluations):
                break
            for q in range(Q):
                i = q % M
                sign = 1.0 if q < M else -1.0
                for n in range(N):
                    for k in range(K):
                        for c in range(3):
                            m = sign if k * 3 + c == i else 0.0
                            v = best[n, k, c] + step * m
                            wp[q, n, k, c] = min(max(v, lower[c]), upper[c])
        # The rows in blocks, as in polish (a subroutine shared by both, taking their 60 arrays
        # at every pass, made polish 7 % slower).
        for q0 in range(0, Q, B):
            nb = min(B, Q - q0)
            _uav_pass(uav_entries, False, MODE_EVALUATE, q0, nb, 0, np.uint64(0), 0.0, X, V, PB, gbest, initial,
                      sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, sww, px, py, pz, ph, stx,
                      sty, sth, prev, bits1, bits2, seg, sub, ang, tmp, acc, acc2, flag, terms, vio)
            _team_pass(team_entries, False, MODE_EVALUATE, q0, nb, px, py, pz, uav, weights, heads, tails, mu,
                       ref_diff, par, form, hit, tmp, acc, acc2, flag, better, terms, vio, res, X, PB,
                       pcost, pviol, cost, viol, J, players, terms_out, vio_out, res_out)
        spent += N * Q
        chosen = -1
        least = np.inf
        for q in range(Q):
            if _deviation_cost(q, 0, vio_out, res_out) == np.inf:  # infeasible
                continue
            worse = False
            gain = False
            for n in range(N):
                t = res_out[q, 2, n]
                worse = worse or not (t <= costs[n])
                gain = gain or t < costs[n] * (1.0 - 1e-9)
            if worse or not gain:
                continue
            key = res_out[q, 2, 0] / costs[0] if slide else res_out[q, 2, 0]
            for n in range(1, N):
                key = key * (res_out[q, 2, n] / costs[n]) if slide else key + res_out[q, 2, n]
            if chosen < 0 or key < least:
                chosen = q
                least = key
        if chosen < 0:
            if slide:
                f += 1
            else:
                step /= 2
            continue
        best[:, :, :] = wp[chosen]
        for n in range(N):
            costs[n] = res_out[chosen, 2, n]
    return spent


@njit(cache=True, nogil=True, error_model="numpy")
def _deviation_cost(q, n, vio_out, res_out) -> float:  # noqa: ANN001
    """``J_n`` of evaluated row ``q``, ``inf`` if any of its violations is not zero."""
    for m in range(vio_out.shape[1]):
        for i in range(vio_out.shape[2]):
            if vio_out[q, m, i] != 0.0:
                return np.inf
    return res_out[q, 2, n]
