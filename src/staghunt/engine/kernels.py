"""The compiled hot path: one fused pass per iteration over a block of particles.

``swarm_block`` updates velocities and positions (PSO step, clamp and mirror), decodes the
spherical particles into team paths, evaluates every cost term and the formation cost, and
updates the personal bests, for particles ``p0 .. p1``; ``select_global`` then picks the global
best. ``evaluate_population`` runs the same evaluation on given waypoints (the twin of
:func:`staghunt.costs.evaluate`, used by the agreement tests).

Layout: the particle index is innermost, so the loops over a block's lanes vectorise.

- Swarm state: ``X``, ``V``, ``PB``: ``(S, K, 3, P)``; ``gbest``: ``(S, K, 3)``;
  ``cost``, ``pcost``: ``(C, P)``; ``viol``, ``pviol``: ``(P,)``; ``J``: ``(N, P)`` per-UAV ``J_n``.
- Model arrays (:mod:`staghunt.engine.arrays`): ``uav (N, 11)`` = start ``(x, y, h)``, goal
  ``(x, y, h)``, start ``z``, goal ``z``, radius, ``beta``, separation limit ``d_s + 2 r``;
  ``weights (N, 5)``; ``cyl (T, 3)``; ``heads``, ``tails (M,)``; ``mu (N, M)``; ``ref_diff (M, 3)``;
  ``grid (R, Cg)``; ``par`` (see ``P_*`` indices below).
- Swarm arrays: ``sw (S, 18)`` = decoding start ``(x, y, h)``, decoding box low, high, search
  range low, high, velocity limit (each 3, over ``(rho, psi, phi)`` for the last three);
  ``member (N,)``; ``offsets (N, 3)``; ``fixed (N, K, 3)``; ``players (C,)``.
- Block scratch (``B`` lanes): see :func:`alloc_scratch`.

Semantics are those of the NumPy reference (``staghunt.costs``, ``staghunt.solvers.swarm``),
arithmetic in the same order where it decides anything; see :mod:`staghunt.engine.fastmath`
for the approximations and how threshold decisions stay exact.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from staghunt.engine.fastmath import (
    DECISION_TOL,
    RAD2DEG,
    atan2,
    counter_hash,
    pairwise_lanes,
    sincos,
    uniform53,
    uniform_pair,
)

# Indices into ``par``.
P_MARGIN = 0
P_SAFE = 1
P_THR_TURN = 2
P_THR_CLIMB = 3
P_HREF = 4
P_CONTINUOUS = 5
P_TERRAIN = 6  # 0 flat, 1 nearest (float64 grid), 2 nearest (float32 arithmetic), 3 bilinear
P_OX = 7
P_OY = 8
P_CELL = 9
P_SEP_REJECT = 10  # pairs farther apart than this along one axis cannot collide
P_C1 = 11
P_C2 = 12
P_SUM = 13  # 1: the objective is the team sum, else the players' J
N_PAR = 14

_THREAT_SLACK = 1e-6  # metres; bounding-box rejection keeps this margin beyond R + r + Delta


@njit(cache=True, nogil=True, error_model="numpy")
def block_size(n_uavs: int, waypoints: int) -> int:
    """Lanes per block: a multiple of 8 in ``[8, 128]`` keeping a block's paths in cache."""
    b = (16384 // max(1, n_uavs * (waypoints + 2))) // 8 * 8
    return max(8, min(128, b))


@njit(cache=True, nogil=True, error_model="numpy")
def alloc_scratch(N: int, K: int, S_sw: int, B: int):  # noqa: ANN201 (a tuple of arrays)
    """Scratch of one block: paths ``(N, K+2, B)`` x3, team waypoints ``(N, 3, K, B)``, swarm
    paths ``(S_sw, 3, K, B)``, per-segment rows ``(12, K+1, B)``, per-UAV separation/formation
    ``(3, N, K+1, B)``, terms ``(N, 5, B)``, violations ``(N, 3, B)``, per-UAV results ``(3, N, B)``,
    a summation buffer ``(max(K+1, 3N), B)`` and lane vectors ``(4, B)``."""
    S = K + 1
    px = np.empty((N, K + 2, B))
    py = np.empty((N, K + 2, B))
    pz = np.empty((N, K + 2, B))
    tw = np.empty((N, 3, K, B))
    sww = np.empty((max(S_sw, 1), 3, K, B))
    rows = np.empty((12, S, B))
    form = np.empty((3, N, S, B))
    terms = np.empty((N, 5, B))
    vio = np.empty((N, 3, B))
    res = np.empty((3, N, B))
    tmp = np.empty((max(S, 3 * N, N, 8), B))
    lanes = np.empty((4, B))
    return px, py, pz, tw, sww, rows, form, terms, vio, res, tmp, lanes


@njit(cache=True, nogil=True, error_model="numpy")
def _round_half_away(v: float) -> float:
    a = abs(v)
    f = math.floor(a)
    up = 1.0 if a - f >= 0.5 else 0.0
    s = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
    return s * (f + up)


@njit(cache=True, nogil=True, error_model="numpy")
def ground_z(x: float, y: float, h: float, grid: np.ndarray, par: np.ndarray) -> float:
    """Absolute altitude ``h + g(x, y)`` exactly as :meth:`staghunt.world.Terrain.absolute`."""
    mode = par[P_TERRAIN]
    if mode == 0.0:
        return h + 0.0
    rows, cols = grid.shape
    u = (x - par[P_OX]) / par[P_CELL]
    v = (y - par[P_OY]) / par[P_CELL]
    if mode != 3.0:
        j = int(min(max(_round_half_away(u), 0.0), cols - 1.0))
        i = int(min(max(_round_half_away(v), 0.0), rows - 1.0))
        g = grid[i, j]
        if mode == 2.0:
            return np.float64(np.float32(h) + np.float32(g))
        return h + g
    u = min(max(u, 0.0), cols - 1.0)
    v = min(max(v, 0.0), rows - 1.0)
    j0 = min(max(int(math.floor(u)), 0), max(cols - 2, 0))
    i0 = min(max(int(math.floor(v)), 0), max(rows - 2, 0))
    j1 = min(j0 + 1, cols - 1)
    i1 = min(i0 + 1, rows - 1)
    fu = u - j0
    fv = v - i0
    top = grid[i0, j0] * (1 - fu) + grid[i0, j1] * fu
    bottom = grid[i1, j0] * (1 - fu) + grid[i1, j1] * fu
    return h + (top * (1 - fv) + bottom * fv)


@njit(cache=True, nogil=True, error_model="numpy")
def axis_distance(ax: float, ay: float, bx: float, by: float, cx: float, cy: float, exact: bool) -> float:
    """Horizontal distance from the axis ``(cx, cy)`` to segment ``a b``, with the arithmetic of
    :func:`staghunt.costs.single.segment_axis_distance`; ``exact=False`` uses ``sqrt(x*x + y*y)``
    (within an ulp or two) for ``hypot``."""
    abx = bx - ax
    aby = by - ay
    axx = cx - ax
    axy = cy - ay
    if abx == 0.0 and aby == 0.0:
        return math.hypot(axx, axy) if exact else math.sqrt(axx * axx + axy * axy)
    bxx = cx - bx
    bxy = cy - by
    on = ((-abx * bxx) + (-aby * bxy)) * ((abx * axx) + (aby * axy)) >= 0
    if on:
        det = abx * axy - aby * axx
        d_ab = math.hypot(abx, aby) if exact else math.sqrt(abx * abx + aby * aby)
        if d_ab == 0.0:  # underflow of the fast form
            d_ab = math.hypot(abx, aby)
        return abs(det) / d_ab
    if exact:
        return min(math.hypot(axx, axy), math.hypot(bxx, bxy))
    return min(math.sqrt(axx * axx + axy * axy), math.sqrt(bxx * bxx + bxy * bxy))


@njit(cache=True, nogil=True, error_model="numpy")
def evaluate_block(nb, tw, uav, weights, cyl, heads, tails, mu, ref_diff, grid, par,  # noqa: ANN001
                   px, py, pz, rows, form, terms, vio, res, tmp, lanes) -> None:
    """Costs of ``nb`` team allocations held in ``tw`` ``(N, 3, K, B)`` (``x, y, h`` free waypoints).

    Writes ``terms (N, 5, B)`` (unweighted length, threat, altitude, turning, climb),
    ``vio (N, 3, B)`` (obstacle, ground, separation violation) and ``res (3, N, B)`` =
    ``J_f``, ``J_s``, ``J_n``. Same definitions as :func:`staghunt.costs.evaluate`.
    """
    N = uav.shape[0]
    K = tw.shape[2]
    S = K + 1
    T = cyl.shape[0]
    M = heads.shape[0]
    margin = par[P_MARGIN]
    thr_t = par[P_THR_TURN]
    thr_c = par[P_THR_CLIMB]
    href = par[P_HREF]
    continuous = par[P_CONTINUOUS] != 0.0
    reject = par[P_SEP_REJECT]
    # A decision flip at a threshold <= DECISION_TOL changes a term by less than that, so the
    # exact re-check is needed only for positive thresholds (e.g. the reference's 45 degrees).
    exact_turn = thr_t > DECISION_TOL
    exact_climb = thr_c > DECISION_TOL
    sdx, sdy, sdz, shxy = rows[0], rows[1], rows[2], rows[3]
    s1x, s1y, s1h, s2x, s2y, s2h = rows[4], rows[5], rows[6], rows[7], rows[8], rows[9]
    cb, cf = rows[10], rows[11]
    acc = lanes[0]
    acc2 = lanes[1]

    # Full paths (start, free waypoints, goal): x, y and absolute z.
    for n in range(N):
        for b in range(nb):
            px[n, 0, b] = uav[n, 0]
            py[n, 0, b] = uav[n, 1]
            pz[n, 0, b] = uav[n, 6]
            px[n, K + 1, b] = uav[n, 3]
            py[n, K + 1, b] = uav[n, 4]
            pz[n, K + 1, b] = uav[n, 7]
        for k in range(K):
            if par[P_TERRAIN] == 0.0:
                for b in range(nb):
                    px[n, k + 1, b] = tw[n, 0, k, b]
                    py[n, k + 1, b] = tw[n, 1, k, b]
                    pz[n, k + 1, b] = tw[n, 2, k, b] + 0.0
            else:
                for b in range(nb):
                    x = tw[n, 0, k, b]
                    y = tw[n, 1, k, b]
                    px[n, k + 1, b] = x
                    py[n, k + 1, b] = y
                    pz[n, k + 1, b] = ground_z(x, y, tw[n, 2, k, b], grid, par)

    for n in range(N):
        radius = uav[n, 8]
        # Segments: projections, heights, lengths.
        for j in range(S):
            for b in range(nb):
                dx = px[n, j + 1, b] - px[n, j, b]
                dy = py[n, j + 1, b] - py[n, j, b]
                dz = pz[n, j + 1, b] - pz[n, j, b]
                sdx[j, b] = dx
                sdy[j, b] = dy
                sdz[j, b] = dz
                xy2 = dx * dx + dy * dy
                shxy[j, b] = math.sqrt(xy2)
                tmp[j, b] = math.sqrt(xy2 + dz * dz)
        pairwise_lanes(tmp, S, nb, acc)
        for b in range(nb):
            terms[n, 0, b] = acc[b]

        # Threats. Branch-free over the lanes (so it vectorises): one square root per pair,
        # ``|det| / |ab|`` via a per-segment reciprocal; lanes whose distance lies within
        # DECISION_TOL of R + r or R + r + Delta are left out here and redone exactly below.
        for j in range(S):
            for b in range(nb):
                h = shxy[j, b]
                cb[j, b] = 1.0 / h if h > 0.0 else 0.0
        for b in range(nb):
            acc[b] = 0.0
            acc2[b] = 0.0
            lanes[2, b] = 0.0
        for t in range(T):
            cx = cyl[t, 0]
            cy = cyl[t, 1]
            inner = cyl[t, 2] + radius
            outer = inner + margin
            for j in range(S):
                for b in range(nb):
                    abx = sdx[j, b]
                    aby = sdy[j, b]
                    axx = cx - px[n, j, b]
                    axy = cy - py[n, j, b]
                    bxx = cx - px[n, j + 1, b]
                    bxy = cy - py[n, j + 1, b]
                    d2a = axx * axx + axy * axy
                    d2b = bxx * bxx + bxy * bxy
                    zero = abx == 0.0 and aby == 0.0
                    on = ((-abx * bxx) + (-aby * bxy)) * ((abx * axx) + (aby * axy)) >= 0
                    perp = abs(abx * axy - aby * axx) * cb[j, b]
                    d_off = math.sqrt(d2a if zero else min(d2a, d2b))
                    d = perp if (on and not zero) else d_off
                    redo = abs(d - inner) <= DECISION_TOL or abs(d - outer) <= DECISION_TOL
                    c = 0.0 if d > outer else (np.inf if d < inner else outer - d)
                    depth = inner - d
                    depth = depth if depth >= 0.0 else 0.0
                    acc[b] += 0.0 if redo else c
                    acc2[b] += 0.0 if redo else depth
                    lanes[2, b] += 1.0 if redo else 0.0
        for b in range(nb):
            if lanes[2, b] == 0.0:
                continue
            for t in range(T):  # rare: redo the flagged pairs with NumPy's exact arithmetic
                cx = cyl[t, 0]
                cy = cyl[t, 1]
                inner = cyl[t, 2] + radius
                outer = inner + margin
                for j in range(S):
                    ax = px[n, j, b]
                    ay = py[n, j, b]
                    bx = px[n, j + 1, b]
                    by = py[n, j + 1, b]
                    abx = sdx[j, b]
                    aby = sdy[j, b]
                    axx = cx - ax
                    axy = cy - ay
                    bxx = cx - bx
                    bxy = cy - by
                    d2a = axx * axx + axy * axy
                    d2b = bxx * bxx + bxy * bxy
                    zero = abx == 0.0 and aby == 0.0
                    on = ((-abx * bxx) + (-aby * bxy)) * ((abx * axx) + (aby * axy)) >= 0
                    perp = abs(abx * axy - aby * axx) * cb[j, b]
                    d_off = math.sqrt(d2a if zero else min(d2a, d2b))
                    d = perp if (on and not zero) else d_off
                    if abs(d - inner) <= DECISION_TOL or abs(d - outer) <= DECISION_TOL:
                        d = axis_distance(ax, ay, bx, by, cx, cy, True)
                        acc[b] += 0.0 if d > outer else (np.inf if d < inner else outer - d)
                        depth = inner - d
                        acc2[b] += depth if depth >= 0.0 else 0.0
        for b in range(nb):
            terms[n, 1, b] = acc[b]
            vio[n, 0, b] = acc2[b]

        # Altitude and ground violation.
        for k in range(K):
            for b in range(nb):
                h = tw[n, 2, k, b]
                tmp[k, b] = np.inf if h < 0 else abs(h - href)
        pairwise_lanes(tmp, K, nb, acc)
        for k in range(K):
            for b in range(nb):
                d = -tw[n, 2, k, b]
                tmp[k, b] = d if d >= 0.0 else 0.0
        pairwise_lanes(tmp, K, nb, acc2)
        for b in range(nb):
            terms[n, 2, b] = acc[b]
            vio[n, 1, b] = acc2[b]

        # Nearest non-zero projection at or before (s1) and at or after (s2) each segment.
        for j in range(S):
            for b in range(nb):
                if j == 0 or sdx[j, b] != 0.0 or sdy[j, b] != 0.0:
                    s1x[j, b] = sdx[j, b]
                    s1y[j, b] = sdy[j, b]
                    s1h[j, b] = shxy[j, b]
                else:
                    s1x[j, b] = s1x[j - 1, b]
                    s1y[j, b] = s1y[j - 1, b]
                    s1h[j, b] = s1h[j - 1, b]
        for j in range(S - 1, -1, -1):
            for b in range(nb):
                if j == S - 1 or sdx[j, b] != 0.0 or sdy[j, b] != 0.0:
                    s2x[j, b] = sdx[j, b]
                    s2y[j, b] = sdy[j, b]
                    s2h[j, b] = shxy[j, b]
                else:
                    s2x[j, b] = s2x[j + 1, b]
                    s2y[j, b] = s2y[j + 1, b]
                    s2h[j, b] = s2h[j + 1, b]

        # Turning angle at vertex i between s1[i] and s2[i + 1] (degrees).
        for i in range(K):
            for b in range(nb):
                ux = s1x[i, b]
                uy = s1y[i, b]
                vx = s2x[i + 1, b]
                vy = s2y[i + 1, b]
                tmp[i, b] = atan2(abs(ux * vy - uy * vx), ux * vx + uy * vy) * RAD2DEG
        for i in range(K):
            for b in range(nb):
                a = tmp[i, b]
                if exact_turn and abs(a - thr_t) <= DECISION_TOL:
                    ux = s1x[i, b]
                    uy = s1y[i, b]
                    vx = s2x[i + 1, b]
                    vy = s2y[i + 1, b]
                    a = math.atan2(abs(ux * vy - uy * vx), ux * vx + uy * vy) * RAD2DEG
                a = abs(a)
                tmp[i, b] = a if a > thr_t else 0.0
        pairwise_lanes(tmp, K, nb, acc)
        for b in range(nb):
            terms[n, 3, b] = acc[b]

        # Climb angles with the substituted horizontal lengths, and their changes.
        for j in range(S):
            for b in range(nb):
                cb[j, b] = atan2(sdz[j, b], s1h[j, b]) * RAD2DEG
        for j in range(S):
            for b in range(nb):
                cf[j, b] = cb[j, b]
        for j in range(S):
            for b in range(nb):
                if s2h[j, b] != s1h[j, b]:  # rare: a zero projection substituted differently
                    cf[j, b] = atan2(sdz[j, b], s2h[j, b]) * RAD2DEG
        for i in range(K):
            for b in range(nb):
                ch = abs(cf[i + 1, b] - cb[i, b])
                if exact_climb and abs(ch - thr_c) <= DECISION_TOL:
                    c1 = math.atan2(sdz[i, b], math.hypot(s1x[i, b], s1y[i, b])) * RAD2DEG
                    c2 = math.atan2(sdz[i + 1, b], math.hypot(s2x[i + 1, b], s2y[i + 1, b])) * RAD2DEG
                    ch = abs(c2 - c1)
                tmp[i, b] = ch if ch > thr_c else 0.0
        pairwise_lanes(tmp, K, nb, acc)
        for b in range(nb):
            terms[n, 4, b] = acc[b]

    # Formation error (eq. 5, edge form) at the free waypoints: form[0] = E (N, K, B).
    E = form[0]
    near2 = form[1]
    seg2 = form[2]
    for n in range(N):
        for k in range(K):
            for b in range(nb):
                E[n, k, b] = 0.0
    for m in range(M):
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
            if w != 0.0:
                for k in range(K):
                    for b in range(nb):
                        E[n, k, b] += w * tmp[k, b]

    # Squared distance to the nearest team-mate at waypoints (near2) and along segments (seg2);
    # pairs farther apart than the largest separation limit along one axis are skipped.
    for n in range(N):
        for j in range(S):
            for b in range(nb):
                near2[n, j, b] = np.inf
                seg2[n, j, b] = np.inf
    for a in range(N):
        for c in range(a + 1, N):
            for k in range(K):
                for b in range(nb):
                    dx = px[a, k + 1, b] - px[c, k + 1, b]
                    dy = py[a, k + 1, b] - py[c, k + 1, b]
                    dz = pz[a, k + 1, b] - pz[c, k + 1, b]
                    d2 = (dx * dx + dy * dy) + dz * dz
                    near2[a, k, b] = min(near2[a, k, b], d2)
                    near2[c, k, b] = min(near2[c, k, b], d2)
            if not continuous:
                continue
            # Can any segment of this pair come within ``reject``? Not if both ends lie beyond
            # it on the same side along one axis. (Skips far pairs of large teams.)
            close = 0.0
            for j in range(S):
                for b in range(nb):
                    r0x = px[a, j, b] - px[c, j, b]
                    r1x = px[a, j + 1, b] - px[c, j + 1, b]
                    r0y = py[a, j, b] - py[c, j, b]
                    r1y = py[a, j + 1, b] - py[c, j + 1, b]
                    r0z = pz[a, j, b] - pz[c, j, b]
                    r1z = pz[a, j + 1, b] - pz[c, j + 1, b]
                    far = ((r0x > reject and r1x > reject) or (r0x < -reject and r1x < -reject)
                           or (r0y > reject and r1y > reject) or (r0y < -reject and r1y < -reject)
                           or (r0z > reject and r1z > reject) or (r0z < -reject and r1z < -reject))
                    close += 0.0 if far else 1.0
            if close == 0.0:
                continue
            for j in range(S):
                for b in range(nb):
                    r0x = px[a, j, b] - px[c, j, b]
                    r0y = py[a, j, b] - py[c, j, b]
                    r0z = pz[a, j, b] - pz[c, j, b]
                    drx = (px[a, j + 1, b] - px[c, j + 1, b]) - r0x
                    dry = (py[a, j + 1, b] - py[c, j + 1, b]) - r0y
                    drz = (pz[a, j + 1, b] - pz[c, j + 1, b]) - r0z
                    dd = (drx * drx + dry * dry) + drz * drz
                    t = (-((r0x * drx + r0y * dry) + r0z * drz)) / dd
                    t = min(max(t, 0.0), 1.0) if dd > 0.0 else 0.0
                    clx = r0x + t * drx
                    cly = r0y + t * dry
                    clz = r0z + t * drz
                    d2 = (clx * clx + cly * cly) + clz * clz
                    seg2[a, j, b] = min(seg2[a, j, b], d2)
                    seg2[c, j, b] = min(seg2[c, j, b], d2)

    # Collision test (eq. 6), separation deficit and J_f (eq. 7); then J_s and J_n.
    hitw = rows[0]  # the per-segment rows are free again
    hits = rows[1]
    for n in range(N):
        limit = uav[n, 10]
        for k in range(K):
            for b in range(nb):
                d = math.sqrt(near2[n, k, b])
                hit = d <= limit
                hitw[k, b] = 1.0 if hit else 0.0
                tmp[k, b] = max(limit - d, 1e-9) if hit else 0.0
        pairwise_lanes(tmp, K, nb, acc)
        if continuous:
            for j in range(S):
                for b in range(nb):
                    d = math.sqrt(seg2[n, j, b])
                    hit = d <= limit
                    hits[j, b] = 1.0 if hit else 0.0
                    tmp[j, b] = max(limit - d, 1e-9) if hit else 0.0
            pairwise_lanes(tmp, S, nb, acc2)
            for b in range(nb):
                acc[b] = acc[b] + acc2[b]
            for k in range(K):
                for b in range(nb):
                    if hits[k, b] != 0.0 or hits[k + 1, b] != 0.0:
                        hitw[k, b] = 1.0
        for b in range(nb):
            vio[n, 2, b] = acc[b]
        for k in range(K):
            for b in range(nb):
                tmp[k, b] = np.inf if hitw[k, b] != 0.0 else E[n, k, b]
        pairwise_lanes(tmp, K, nb, acc)
        beta = uav[n, 9]
        for b in range(nb):
            jf = acc[b]
            single = 0.0
            for i in range(5):
                w = weights[n, i]
                single += 0.0 if w == 0.0 else w * terms[n, i, b]
            res[0, n, b] = jf
            res[1, n, b] = single
            res[2, n, b] = single + (0.0 if beta == 0.0 else beta * jf)


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
def sample_positions(key: np.uint64, X: np.ndarray, sw: np.ndarray) -> None:
    """Uniform initial positions in the search ranges (counter-based draws of iteration 0)."""
    S, K, _, P = X.shape
    for s in range(S):
        for k in range(K):
            for c in range(3):
                lo = sw[s, 9 + c]
                span = sw[s, 12 + c] - lo
                base = np.uint64(((s * K + k) * 3 + c)) * np.uint64(P)
                for p in range(P):
                    X[s, k, c, p] = lo + uniform53(counter_hash(key, base + np.uint64(p))) * span


@njit(cache=True, nogil=True, error_model="numpy")
def swarm_block(p0, p1, it, key, inertia, X, V, PB, pcost, pviol, cost, viol, J, gbest,  # noqa: ANN001
                sw, member, offsets, fixed, players,
                uav, weights, cyl, heads, tails, mu, ref_diff, grid, par) -> None:
    """One iteration for particles ``p0 .. p1`` (``it = 0``: evaluate the initial positions and
    make them the personal bests; ``it >= 1``: PSO step first, then evaluate and update the
    personal bests by dominance). Draws ``r1, r2`` from the counter-based stream of ``key``
    indexed by ``(it, s, k, c, p)``, so the result does not depend on how particles are split.
    """
    S, K, _, P = X.shape
    N = uav.shape[0]
    C = cost.shape[0]
    c1 = par[P_C1]
    c2 = par[P_C2]
    team_sum = par[P_SUM] != 0.0
    B = block_size(N, K)
    px, py, pz, tw, sww, rows, form, terms, vio, res, tmp, lanes = alloc_scratch(N, K, S, B)
    acc = lanes[2]
    for q0 in range(p0, p1, B):
        nb = min(B, p1 - q0)
        if it > 0:
            for s in range(S):
                for k in range(K):
                    for c in range(3):
                        lo = sw[s, 9 + c]
                        hi = sw[s, 12 + c]
                        vm = sw[s, 15 + c]
                        g = gbest[s, k, c]
                        base = np.uint64((((it * S + s) * K + k) * 3 + c)) * np.uint64(P)
                        for p in range(q0, q0 + nb):
                            r1, r2 = uniform_pair(counter_hash(key, base + np.uint64(p)))
                            x = X[s, k, c, p]
                            v = (inertia * V[s, k, c, p] + c1 * r1 * (PB[s, k, c, p] - x)) + c2 * r2 * (g - x)
                            v = min(max(v, -vm), vm)
                            x = x + v
                            if x < lo or x > hi:
                                v = -v
                            X[s, k, c, p] = min(max(x, lo), hi)
                            V[s, k, c, p] = v
        # Decode: spherical steps from each swarm's start, clamped to its box after every step.
        for s in range(S):
            for b in range(nb):
                lanes[0, b] = sw[s, 0]
                lanes[1, b] = sw[s, 1]
                lanes[3, b] = sw[s, 2]
            for k in range(K):
                for b in range(nb):
                    p = q0 + b
                    rho = X[s, k, 0, p]
                    sp, cp = sincos(X[s, k, 1, p])
                    sf, cf = sincos(X[s, k, 2, p])
                    rc = rho * cp
                    x = min(max(lanes[0, b] + rc * cf, sw[s, 3]), sw[s, 6])
                    y = min(max(lanes[1, b] + rc * sf, sw[s, 4]), sw[s, 7])
                    h = min(max(lanes[3, b] + rho * sp, sw[s, 5]), sw[s, 8])
                    lanes[0, b] = x
                    lanes[1, b] = y
                    lanes[3, b] = h
                    sww[s, 0, k, b] = x
                    sww[s, 1, k, b] = y
                    sww[s, 2, k, b] = h
        for n in range(N):
            m = member[n]
            for c in range(3):
                for k in range(K):
                    if m < 0:
                        f = fixed[n, k, c]
                        for b in range(nb):
                            tw[n, c, k, b] = f
                    else:
                        o = offsets[n, c]
                        for b in range(nb):
                            tw[n, c, k, b] = sww[m, c, k, b] + o
        evaluate_block(nb, tw, uav, weights, cyl, heads, tails, mu, ref_diff, grid, par,
                       px, py, pz, rows, form, terms, vio, res, tmp, lanes)
        # Compared costs, total violation (NumPy's summation order), personal bests.
        for n in range(N):
            for i in range(3):
                for b in range(nb):
                    tmp[3 * n + i, b] = vio[n, i, b]
        pairwise_lanes(tmp, 3 * N, nb, acc)
        for b in range(nb):
            viol[q0 + b] = acc[b]
        for n in range(N):
            for b in range(nb):
                J[n, q0 + b] = res[2, n, b]
        if team_sum:
            for n in range(N):
                for b in range(nb):
                    tmp[n, b] = res[2, n, b]
            pairwise_lanes(tmp, N, nb, acc)
            for b in range(nb):
                cost[0, q0 + b] = acc[b]
        else:
            for c in range(C):
                for b in range(nb):
                    cost[c, q0 + b] = res[2, players[c], b]
        for p in range(q0, q0 + nb):
            if it == 0 or _dominates(cost, p, viol[p], pcost, p, pviol[p]):
                for c in range(C):
                    pcost[c, p] = cost[c, p]
                pviol[p] = viol[p]
                for s in range(S):
                    for k in range(K):
                        for c in range(3):
                            PB[s, k, c, p] = X[s, k, c, p]


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
def evaluate_population(wp, uav, weights, cyl, heads, tails, mu, ref_diff, grid, par,  # noqa: ANN001
                        terms_out, vio_out, res_out) -> None:
    """Twin of :func:`staghunt.costs.evaluate`: ``wp`` ``(P, N, K, 3)`` -> ``terms_out (P, N, 5)``,
    ``vio_out (P, N, 3)``, ``res_out (P, 3, N)`` (``J_f``, ``J_s``, ``J_n``)."""
    P, N, K, _ = wp.shape
    B = block_size(N, K)
    px, py, pz, tw, sww, rows, form, terms, vio, res, tmp, lanes = alloc_scratch(N, K, 1, B)
    for q0 in range(0, P, B):
        nb = min(B, P - q0)
        for n in range(N):
            for c in range(3):
                for k in range(K):
                    for b in range(nb):
                        tw[n, c, k, b] = wp[q0 + b, n, k, c]
        evaluate_block(nb, tw, uav, weights, cyl, heads, tails, mu, ref_diff, grid, par,
                       px, py, pz, rows, form, terms, vio, res, tmp, lanes)
        for b in range(nb):
            for n in range(N):
                for i in range(5):
                    terms_out[q0 + b, n, i] = terms[n, i, b]
                for i in range(3):
                    vio_out[q0 + b, n, i] = vio[n, i, b]
                    res_out[q0 + b, i, n] = res[i, n, b]
