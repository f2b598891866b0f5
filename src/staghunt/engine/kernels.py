"""The compiled hot path: one fused pass per iteration over a block of particles.

Two entry points run one block of ``nb <= B`` particles, in this order:

- :func:`uav_pass`: PSO step (or the uniform initial draw), decoding of the spherical particles
  and assembly of the team paths (or, in ``MODE_EVALUATE``, loading given waypoints), then
  every UAV's single-path cost terms (eq. 2);
- :func:`team_pass`: formation cost and separation (eqs. 5-7), ``J_n``, then the personal bests
  (or, in ``MODE_EVALUATE``, the outputs of the twin of :func:`staghunt.costs.evaluate`).

:func:`select_global` then picks the global best. :func:`iterate` runs stretches of a swarm's
iterations in one call (both entries over all blocks through :func:`_block`, in a ``prange``
over the blocks, then the global best; :func:`iterate_serial` the same in a plain loop), so a
small swarm pays no per-block dispatch from Python and no Python-level barrier per iteration.
Intermediate results stay in the block's scratch arrays (:class:`staghunt.engine.scratch.Scratch`).
Callers bind the arrays by these kernels' parameter names (:func:`staghunt.engine.arrays.kernel_args`),
so each definition is the one place that spells its argument order. The parts of each entry are
:func:`~staghunt.engine.jit.subroutine` s, compiled only as part of it; the entries are compiled
in two processes the first time (see :func:`staghunt.engine.compile.prepare`).

The pieces live in their own modules, re-exported here (callers use ``kernels.X``):
:mod:`~staghunt.engine.layout` (the arrays' named columns and the modes; the layout of every
array), :mod:`~staghunt.engine.geometry` (small compiled helpers),
:mod:`~staghunt.engine.uav_kernel` and :mod:`~staghunt.engine.team_kernel` (the two entries),
:mod:`~staghunt.engine.search_kernels` (``polish`` and ``team_search``); this module holds the
swarm loop.

Semantics are those of the NumPy reference (``staghunt.costs``, ``staghunt.solvers.swarm``),
with NumPy's arithmetic order wherever a result decides anything; see
:mod:`staghunt.engine.fastmath` for the approximations and how threshold decisions stay exact.
Loops are written so that LLVM vectorises them over the lanes: few output rows per loop, plain
indexing (1-D row views only in the PSO step and decoding, where they measured faster).
"""

from __future__ import annotations

import math

import numpy as np
from numba import get_thread_id, prange

from staghunt.engine.geometry import (  # noqa: F401  (re-exported)
    axis_distance,
    bilinear_z,
    dominates_at,
    fill,
    ground_z,
    prism_segment_distance,
)
from staghunt.engine.jit import compiled, subroutine
from staghunt.engine.layout import (  # noqa: F401  (re-exported: the named columns, indices and modes)
    P_MARGIN, P_SAFE, P_THR_TURN, P_THR_CLIMB, P_HREF, P_CONTINUOUS, P_TERRAIN, P_OX, P_OY, P_CELL, P_C1,
    P_C2, P_SUM, P_CLEAR, P_CEIL, N_PAR, SOLO_STRIDE, PRUNE_MIN_UAVS, PRUNE_GUARD, U_START, U_GOAL, U_START_Z,
    U_GOAL_Z, U_RADIUS, U_BETA, U_LIMIT, U_COLUMNS, SW_START, SW_LOW, SW_HIGH, SW_RANGE_LOW, SW_RANGE_HIGH,
    SW_VMAX, SW_SMALL, SW_CENTRE, SW_SIN, SW_COS, SW_COLUMNS, MODE_INIT, MODE_STEP, MODE_EVALUATE,
    MODE_DEVIATE, block_size,
)
from staghunt.engine.search_kernels import polish, team_search  # noqa: F401  (re-exported)
from staghunt.engine.team_kernel import team_pass, team_pass_by_address as _team_pass  # noqa: F401
from staghunt.engine.uav_kernel import uav_pass, uav_pass_by_address as _uav_pass  # noqa: F401


@compiled()
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
        if masked and not dominates_at(cost, i, v, gcost, 0, gviol):
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


@compiled()
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
    (sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub, ang, tmp, acc, acc2, flag,
     terms, vio, form, hit, better, box, near, res) = scratch
    _uav_pass(uav_entries, probe, mode, q0, nb, it, key, inertia, X, V, PB, gbest, initial, sw, member,
              offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, sww[t], px[t], py[t], pz[t], ph[t], stx[t],
              sty[t], sth[t], prev[t], bits1[t], bits2[t], ubits1[t], ubits2[t], seg[t], sub[t], ang[t], tmp[t],
              acc[t], acc2[t], flag[t], terms[t], vio[t])
    _team_pass(team_entries, probe, mode, q0, nb, px[t], py[t], pz[t], uav, weights, heads, tails, mu, ref_diff,
               par, form[t], hit[t], tmp[t], acc[t], acc2[t], flag[t], better[t], box[t], near[t],
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
                fill(px[t, n, k + 1], B, x)
                fill(py[t, n, k + 1], B, y)
                fill(ph[t, n, k], B, h)
                fill(pz[t, n, k + 1], B, h + 0.0 if flat else ground_z(x, y, h, grid, par))
            fill(px[t, n, 0], B, uav[n, U_START])
            fill(py[t, n, 0], B, uav[n, U_START + 1])
            fill(pz[t, n, 0], B, uav[n, U_START_Z])
            fill(px[t, n, K + 1], B, uav[n, U_GOAL])
            fill(py[t, n, K + 1], B, uav[n, U_GOAL + 1])
            fill(pz[t, n, K + 1], B, uav[n, U_GOAL_Z])
            base = N_PAR + SOLO_STRIDE * n
            for i in range(5):
                fill(terms[t, n, i], B, par[base + i])
            for i in range(2):
                fill(vio[t, n, i], B, par[base + 5 + i])


@compiled(parallel=True)
def iterate(it0, it1, bs, key, state, X, V, PB, gbest, initial, sw, member, offsets, fixed, par, uav,  # noqa: ANN001
            cyl, prm, pedge, grid, weights, heads, tails, mu, ref_diff, players, pcost, pviol, cost, viol, J, gcost,
            history, rhistory, hviol, sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub,
            ang, tmp, acc, acc2, flag, terms, vio, form, hit, better, box, near, res, wp, terms_out, vio_out, res_out,
            uav_entries, team_entries) -> None:
    """Iterations ``it0 .. it1-1`` of a swarm run in one call (iteration 0: the initial draw),
    each over all particles in blocks of ``bs``, then the global best, the histories
    ``history (I+1, C)``, ``rhistory (I+1, N)``, ``hviol (I+1,)`` and the inertia's damping
    (:func:`_global`; ``state`` = ``[inertia, global violation, damping]``, carried from call to
    call). The blocks run in a parallel loop (a block on thread ``get_thread_id()`` with that
    thread's scratch, the leading axis of ``sww .. res``). Every particle's work is its own and
    the global best is chosen after the loop, so results depend neither on the thread count nor
    on the block size. The fixed paths' rows of every thread's scratch are filled first
    (:func:`_fixed_rows`): blocks in ``MODE_STEP`` do not write them again."""
    P = X.shape[3]
    n_blocks = (P + bs - 1) // bs
    shared = (X, V, PB, gbest, initial, sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, weights,
              heads, tails, mu, ref_diff, players, pcost, pviol, cost, viol, J, terms_out, vio_out, res_out,
              uav_entries, team_entries)
    scratch = (sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub, ang, tmp, acc,
               acc2, flag, terms, vio, form, hit, better, box, near, res)
    _block(MODE_STEP, 0, 0, it0, key, 0.0, 0, shared, scratch, True)  # raises here, not in the loop
    _fixed_rows(member, fixed, uav, grid, par, px, py, pz, ph, terms, vio)
    for it in range(it0, it1):
        mode = MODE_INIT if it == 0 else MODE_STEP
        inertia = state[0]
        for blk in prange(n_blocks):
            _block(mode, blk * bs, min(bs, P - blk * bs), it, key, inertia, get_thread_id(), shared, scratch, False)
        _global(it, state, X, gbest, cost, viol, J, gcost, history, rhistory, hviol)


@compiled()
def iterate_serial(it0, it1, bs, key, state, X, V, PB, gbest, initial, sw, member, offsets, fixed, par, uav,  # noqa: ANN001
                   cyl, prm, pedge, grid, weights, heads, tails, mu, ref_diff, players, pcost, pviol, cost, viol, J, gcost,
                   history, rhistory, hviol, sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub,
                   ang, tmp, acc, acc2, flag, terms, vio, form, hit, better, box, near, res, wp, terms_out, vio_out, res_out,
                   uav_entries, team_entries) -> None:
    """:func:`iterate` in a plain loop over the blocks, on scratch 0 (one thread: no parallel
    launch per iteration). A function of its own, not ``iterate``'s branch: Numba's parallel
    compilation costs several seconds more than this loop's, so a first run can start on this
    one while the parallel one is compiled beside it (:mod:`staghunt.engine.compile`)."""
    P = X.shape[3]
    n_blocks = (P + bs - 1) // bs
    shared = (X, V, PB, gbest, initial, sw, member, offsets, fixed, par, wp, uav, cyl, prm, pedge, grid, weights,
              heads, tails, mu, ref_diff, players, pcost, pviol, cost, viol, J, terms_out, vio_out, res_out,
              uav_entries, team_entries)
    scratch = (sww, px, py, pz, ph, stx, sty, sth, prev, bits1, bits2, ubits1, ubits2, seg, sub, ang, tmp, acc,
               acc2, flag, terms, vio, form, hit, better, box, near, res)
    _block(MODE_STEP, 0, 0, it0, key, 0.0, 0, shared, scratch, True)  # raises here, not in the loop
    _fixed_rows(member, fixed, uav, grid, par, px, py, pz, ph, terms, vio)
    for it in range(it0, it1):
        mode = MODE_INIT if it == 0 else MODE_STEP
        inertia = state[0]
        for blk in range(n_blocks):
            _block(mode, blk * bs, min(bs, P - blk * bs), it, key, inertia, 0, shared, scratch, False)
        _global(it, state, X, gbest, cost, viol, J, gcost, history, rhistory, hviol)
