"""Entry 1 of the compiled pass, :func:`uav_pass`, and its parts: the PSO step (or the uniform
initial draw) and the decoding of the spherical particles into team paths (:func:`_advance`),
or given waypoints (:func:`_load`); absolute altitudes (:func:`_absolute_z`); every UAV's
single-path cost terms, eq. (2) (:func:`_uav_terms`). See :mod:`staghunt.engine.kernels`."""

from __future__ import annotations

import math

import numpy as np

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
from staghunt.engine.geometry import (
    bilinear_z,
    fill,
    ground_z,
    prism_threats,
    threats_exact,
)
from staghunt.engine.jit import compiled, entry_call, subroutine
from staghunt.engine.layout import (
    MODE_EVALUATE,
    MODE_INIT,
    MODE_STEP,
    N_PAR,
    P_C1,
    P_C2,
    P_CEIL,
    P_CELL,
    P_CLEAR,
    P_HREF,
    P_MARGIN,
    P_OX,
    P_OY,
    P_TERRAIN,
    P_THR_CLIMB,
    P_THR_TURN,
    SOLO_STRIDE,
    SW_CENTRE,
    SW_COS,
    SW_HIGH,
    SW_LOW,
    SW_RANGE_HIGH,
    SW_RANGE_LOW,
    SW_SIN,
    SW_SMALL,
    SW_START,
    SW_VMAX,
    U_GOAL,
    U_GOAL_Z,
    U_RADIUS,
    U_START,
    U_START_Z,
)


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
            threats_exact(b, xn, yn, seg, cyl, radius, margin, clear, acc, acc2)
    if prm.shape[0] > 0 or par[P_CEIL] < np.inf:
        prism_threats(nb, xn, yn, zn, prm, pedge, radius, margin, clear, par[P_CEIL], acc, acc2)
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


@subroutine
def _advance(mode, q0, nb, it, key, inertia, X, V, PB, gbest, initial, sw, member, offsets, fixed,  # noqa: ANN001
             par, sww, px, py, ph, stx, sty, sth, prev, bits1, bits2, u1, u2, kept) -> None:
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
    ``sty``, ``sth`` ``(B,)`` steps, ``prev`` ``(3, B)``; ``bits1``, ``bits2`` ``(B,)`` uint64 and
    ``u1``, ``u2`` the same memory as float64 (made by the caller: a view made here compiles
    Numba's dtype checks into every entry).
    """
    S, K, _, P = X.shape
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
            fill(prev[c], nb, sw[s, SW_START + c])
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
                fill(px[n, k + 1], nb, fixed[n, k, 0])
                fill(py[n, k + 1], nb, fixed[n, k, 1])
                fill(ph[n, k], nb, fixed[n, k, 2])
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
        fill(px[n, 0], nb, uav[n, U_START])
        fill(py[n, 0], nb, uav[n, U_START + 1])
        fill(pz[n, 0], nb, uav[n, U_START_Z])
        fill(px[n, K + 1], nb, uav[n, U_GOAL])
        fill(py[n, K + 1], nb, uav[n, U_GOAL + 1])
        fill(pz[n, K + 1], nb, uav[n, U_GOAL_Z])
        same = solo and member[n] < 0
        for k in range(K):
            if flat:
                for b in range(nb):
                    pz[n, k + 1, b] = ph[n, k, b] + 0.0
            elif same:
                fill(pz[n, k + 1], nb, ground_z(px[n, k + 1, 0], py[n, k + 1, 0], ph[n, k, 0], grid, par))
            elif bilinear:
                for b in range(nb):
                    pz[n, k + 1, b] = bilinear_z(px[n, k + 1, b], py[n, k + 1, b], ph[n, k, b], grid, ox, oy, cell)
            else:
                for b in range(nb):
                    pz[n, k + 1, b] = ground_z(px[n, k + 1, b], py[n, k + 1, b], ph[n, k, b], grid, par)


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


@compiled()
def uav_pass(mode, q0, nb, it, key, inertia, X, V, PB, gbest, initial, sw, member, offsets, fixed,  # noqa: ANN001
             par, wp, uav, cyl, prm, pedge, grid, sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2,
             ubits1, ubits2, seg, sub, ang, tmp, acc, acc2, flag, terms, vio) -> None:
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
                 fixed, par, sww, px, py, ph, stx, sty, sth, prev, bits1, bits2, ubits1, ubits2, kept)
    _absolute_z(nb, px, py, ph, pz, uav, grid, par, member, solo, kept)
    for n in range(uav.shape[0]):
        if kept and member[n] < 0:
            continue
        if solo and member[n] < 0:  # a fixed path: its constant terms (see SOLO_STRIDE)
            base = N_PAR + SOLO_STRIDE * n
            for i in range(5):
                fill(terms[n, i], nb, par[base + i])
            for i in range(2):
                fill(vio[n, i], nb, par[base + 5 + i])
        else:
            _uav_terms(nb, n, px, py, pz, ph, uav, cyl, prm, pedge, par, seg, sub, ang, tmp, acc, acc2, flag, terms, vio)


uav_pass_by_address = entry_call(uav_pass)
""":func:`uav_pass` as :func:`staghunt.engine.kernels.iterate`, ``polish`` and ``team_search``
call it: through its address in a table of its compiled code (``uav_entries``,
:func:`staghunt.engine.jit.entry_call`), so that no caller compiles it again inside itself."""
