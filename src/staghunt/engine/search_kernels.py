"""The local searches of ``game`` in one compiled call each: UAV ``n``'s pattern search on its own
path with the others fixed (:func:`polish`, the twin of :func:`staghunt.solvers.local.polish`)
and the team's slide and polish (:func:`team_search`, the twins of
:func:`staghunt.solvers.game.team_slide` and :func:`~staghunt.solvers.game.team_polish`), on
the two entries of the pass called through their addresses."""

from __future__ import annotations

import math

import numpy as np

from staghunt.engine.jit import compiled, subroutine
from staghunt.engine.layout import (
    MODE_DEVIATE,
    MODE_EVALUATE,
)
from staghunt.engine.team_kernel import team_pass_by_address as _team_pass
from staghunt.engine.uav_kernel import uav_pass_by_address as _uav_pass


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


@compiled()
def polish(n, step, min_step, max_evaluations, J0, lower, upper, path,  # noqa: ANN001
           sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, weights, heads, tails, mu,
           ref_diff, players, X, V, PB, gbest, initial, pcost, pviol, cost, viol, J, terms_out, vio_out,
           res_out, sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub, ang, tmp,
           acc, acc2, flag, terms, vio, form, hit, better, box, near, res, qcost, uav_entries, team_entries):
    """The twin of :func:`staghunt.solvers.local.polish` on UAV ``n``'s deviations in one call:
    a pattern search from ``path (K, 3)`` (cost ``J0``) that moves one coordinate by
    ``+-step`` per candidate (``6 K`` of them, rows ``0 .. 6K-1`` of ``wp``, whose other UAVs'
    rows hold the fixed paths), then the combination of every improving move (row ``6 K``),
    evaluated in ``MODE_DEVIATE`` (``inf`` where a candidate breaks a hard constraint); the
    best that lowers ``J_n`` by more than ``1e-9`` relative is taken, else ``step`` halves,
    down to ``min_step``, within ``max_evaluations``. The same decisions in the same order as
    the reference, so the same path. Searches ``path`` in place (the result); returns ``(J_n, spent)``.
    Scratch: ``qcost (2, 6 K)``: the candidates' ``J_n`` and gains.

    Each pass of the loop evaluates rows ``r0 .. r1-1``: a sweep's candidates, or (``combine``)
    the combined move after a sweep that improved."""
    K = path.shape[0]
    M = 3 * K
    Q = 2 * M
    B = px.shape[2]
    best = path  # searched in place
    Jc = qcost[0]
    gain = qcost[1]
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
                      sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub, ang, tmp, acc, acc2, flag, terms, vio)
            _team_pass(team_entries, False, MODE_DEVIATE, q0, nb, px, py, pz, uav, weights, heads, tails, mu,
                       ref_diff, par, form, hit, tmp, acc, acc2, flag, better, box, near, terms, vio, res, X, PB,
                       pcost, pviol, cost, viol, J, players, terms_out, vio_out, res_out)
        spent += r1 - r0
        if combine:  # the combination or the best single move, whichever is cheaper
            combine = False
            combined = _deviation_cost(Q, n, vio_out, res_out)
            i = _argmax(gain)
            if combined < Jc[i]:
                for k in range(K):  # element by element: a slice assignment compiles Numba's error formatting
                    for c in range(3):
                        best[k, c] = wp[Q, n, k, c]
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
    return Jn, spent


@compiled()
def team_search(slide, fractions, step, min_step, max_evaluations, spent, costs, lower, upper, ends,  # noqa: ANN001
                best, sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, weights, heads, tails,
                mu, ref_diff, players, X, V, PB, gbest, initial, pcost, pviol, cost, viol, J, terms_out,
                vio_out, res_out, sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub,
                ang, tmp, acc, acc2, flag, terms, vio, form, hit, better, box, near, res, uav_entries, team_entries):
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
                      sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub, ang, tmp, acc, acc2, flag, terms, vio)
            _team_pass(team_entries, False, MODE_EVALUATE, q0, nb, px, py, pz, uav, weights, heads, tails, mu,
                       ref_diff, par, form, hit, tmp, acc, acc2, flag, better, box, near, terms, vio, res, X, PB,
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
        for n in range(N):  # element by element (see polish)
            for k in range(K):
                for c in range(3):
                    best[n, k, c] = wp[chosen, n, k, c]
        for n in range(N):
            costs[n] = res_out[chosen, 2, n]
    return spent


@compiled()
def _argmax(x):  # noqa: ANN001
    """``np.argmax`` of a 1-D array (the first maximum; the first NaN if any), without the
    library's implementation, whose error checks compile Numba's string formatting."""
    best = 0
    for i in range(x.shape[0]):
        if math.isnan(x[i]):
            return i
        if x[i] > x[best]:
            best = i
    return best


@compiled()
def _deviation_cost(q, n, vio_out, res_out) -> float:  # noqa: ANN001
    """``J_n`` of evaluated row ``q``, ``inf`` if any of its violations is not zero."""
    for m in range(vio_out.shape[1]):
        for i in range(vio_out.shape[2]):
            if vio_out[q, m, i] != 0.0:
                return np.inf
    return res_out[q, 2, n]
