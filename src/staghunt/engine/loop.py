"""Stretches of a swarm run's iterations in one compiled call (:func:`kernels.iterate`): the
thread count, the block size and the OpenMP runtime's idle policy."""

from __future__ import annotations

import os
import threading
from typing import Any

import numpy as np

from staghunt.engine import kernels as kn
from staghunt.engine.scratch import Scratch

os.environ.setdefault("GOMP_SPINCOUNT", "100000")
"""Idle OpenMP threads (Numba's ``omp`` layer) spin briefly, then sleep: between two iterations
of a small swarm the worker stays awake (a reply swarm of 601 particles: 2 threads 1.41x
faster than 1 at load 1.5, against 0.95x with sleeping at once, ``OMP_WAIT_POLICY=PASSIVE``),
while a long spin (the default active policy) took the core from the thread everyone waits for
on a loaded machine. Read by the OpenMP runtime when Numba first loads it; set it beforehand to
override."""

MIN_SHARED_PARTICLES = 200
"""A swarm with fewer particles runs on one thread: its iteration (tens of microseconds) is too
short to pay for waking a second thread and meeting it at the barrier (``game``'s smallest
replies; measured slower on two threads)."""

CHUNK_ITERATIONS = 25
"""Most iterations of a swarm run per call of the compiled loop (:func:`kernels.iterate`):
between calls the thread count may change, progress is reported and Ctrl-C is honoured."""

_LAYER_LOCK = threading.Lock()


def kernel_threads() -> int:
    """Threads the compiled parallel loop may use (Numba's ``NUMBA_NUM_THREADS``)."""
    import numba

    return max(1, int(numba.config.NUMBA_NUM_THREADS))


def parallel_block(P: int, B: int, threads: int) -> int:
    """Lanes per block of a run of ``P`` particles on ``threads`` threads: ``B`` on one thread,
    else small enough for four blocks per thread (work sharing), a multiple of 8."""
    if threads <= 1:
        return B
    size = -(-P // (4 * threads))
    return max(8, min(B, -(-size // 8) * 8))


def _thread_safe_layer() -> bool:
    """Whether Numba's threading layer runs parallel loops launched from several Python threads
    at once (``omp``, ``tbb``; not ``workqueue``, which aborts the process then)."""
    import numba

    try:
        return numba.threading_layer() in ("omp", "tbb")
    except ValueError:  # no parallel loop has run yet
        return False


def iterate_chunk(it0: int, it1: int, bs: int, threads: int, key: np.uint64, state: np.ndarray,
             run: Any, gcost: np.ndarray, history: np.ndarray, rhistory: np.ndarray, hviol: np.ndarray,
             w: Scratch) -> None:
    """One call of :func:`kernels.iterate` on ``threads`` threads (serialised across Python
    threads unless the threading layer is thread-safe; one thread: its serial loop)."""
    import numba

    ma, sa = run.ma, run.sa
    parallel = threads > 1
    safe = not parallel or _thread_safe_layer()
    if parallel:
        numba.set_num_threads(threads)
        numba.set_parallel_chunksize(1)  # blocks handed out one at a time: a slow thread takes fewer
    if not safe:
        _LAYER_LOCK.acquire()
    try:
        kn.iterate(it0, it1, bs, not parallel, key, state, run.X, run.V, run.PB, run.gbest, run.initial, sa.sw,
                   sa.member, sa.offsets, sa.fixed, ma.par, ma.uav, ma.cyl, ma.prm, ma.pedge, ma.grid,
                   ma.weights, ma.heads, ma.tails, ma.mu, ma.ref_diff, sa.players, run.pcost, run.pviol,
                   run.cost, run.viol, run.J, gcost, history, rhistory, hviol, w.sww, w.px, w.py, w.pz,
                   w.ph, w.stx, w.sty, w.sth, w.prev, w.bits1, w.bits2, w.seg, w.sub, w.ang, w.tmp, w.acc,
                   w.acc2, w.flag, w.terms, w.vio, w.form, w.hit, w.rx, w.ry, w.rz, w.better, w.res,
                   run.wp, run.terms_out, run.vio_out, run.res_out)
    finally:
        if not safe:
            _LAYER_LOCK.release()
        if parallel:
            numba.set_parallel_chunksize(0)
