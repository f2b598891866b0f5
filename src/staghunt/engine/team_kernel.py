"""Entry 2 of the compiled pass, :func:`team_pass`, and its parts: formation cost and
separation, eqs. (5)-(7), then ``J_s``, ``J_f``, ``J_n`` (:func:`_team_terms`); the compared
costs and personal bests (:func:`_bests`) or the evaluation's outputs (:func:`_store`). See
:mod:`staghunt.engine.kernels`."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from staghunt.engine.fastmath import pairwise_lanes
from staghunt.engine.geometry import dominates_at, fill, is_player, rows_kept
from staghunt.engine.jit import compiled, entry_call, subroutine
from staghunt.engine.layout import (
    MODE_DEVIATE,
    MODE_EVALUATE,
    MODE_INIT,
    N_PAR,
    PRUNE_GUARD,
    PRUNE_MIN_UAVS,
    P_CONTINUOUS,
    P_SUM,
    U_BETA,
    U_LIMIT,
)


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
                form, hit, tmp, acc, acc2, flag, box, near, terms, vio, res) -> None:
    """Formation cost and separation for the whole team (:mod:`staghunt.costs.formation`), then
    ``J_s``, ``J_f``, ``J_n`` (:func:`staghunt.costs.evaluate`).

    Writes ``vio[:, 2]`` (separation deficit) and ``res (3, N, B)`` = ``J_f``, ``J_s``, ``J_n``.
    Scratch: ``form (3, N, S, B)`` = ``E`` (eq. 5), nearest squared distance at the waypoints,
    along the segments; ``hit (2, S, B)`` collisions at waypoints / along segments;
    ``tmp (>= S, B)``; ``acc``, ``acc2``, ``flag`` ``(B,)``; ``box (6, N, K + 2)`` and
    ``near (S,)`` int64 (the pruning's boxes and segments, below). For ``N > PRUNE_MIN_UAVS`` a
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
        if not rows_kept(solo, every, players, n):
            continue
        for k in range(K):
            fill(E[n, k], nb, 0.0)
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
            if w != 0.0 and not (solo and not is_player(players, n)):
                for k in range(K):
                    for b in range(nb):
                        E[n, k, b] += w * tmp[k, b]

    # Nearest team-mate, squared, at the waypoints and along the synchronised segments.
    for n in range(N):
        if not rows_kept(solo, every, players, n):
            continue
        for j in range(S):
            fill(near2[n, j], nb, np.inf)
            fill(seg2[n, j], nb, np.inf)
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
    # box: lo, hi of x, y, z; near: whether segment j of a pair may be within its limit
    for j in range(S):
        near[j] = 1
    if prune:
        for n in range(N):
            # With ``solo`` a UAV other than the players has one fixed path in every lane.
            lanes = nb if not solo or is_player(players, n) else min(nb, 1)
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
            if solo and not (is_player(players, a) or is_player(players, c)):
                continue
            keep_a = rows_kept(solo, every, players, a)  # the UAVs whose rows are read
            keep_c = rows_kept(solo, every, players, c)
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
            fixed_a = solo and not is_player(players, a)
            fixed_c = solo and not is_player(players, c)
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
        if not rows_kept(solo, every, players, n):
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
        own = not solo or is_player(players, n)
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
        better[b] = 1.0 if (mode == MODE_INIT or dominates_at(cost, p, viol[p], pcost, p, pviol[p])) else 0.0
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


@compiled()
def team_pass(mode, q0, nb, px, py, pz, uav, weights, heads, tails, mu, ref_diff, par,  # noqa: ANN001
               form, hit, tmp, acc, acc2, flag, better, box, near, terms, vio, res,
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
                players, form, hit, tmp, acc, acc2, flag, box, near, terms, vio, res)
    if mode >= MODE_EVALUATE:
        _store(q0, nb, terms, vio, res, terms_out, vio_out, res_out)
    else:
        _bests(mode, q0, nb, X, PB, pcost, pviol, cost, viol, J, players, par, solo, vio, res, tmp, acc, better)


team_pass_by_address = entry_call(team_pass)
""":func:`team_pass` as its compiled callers call it (see ``uav_pass_by_address``)."""
