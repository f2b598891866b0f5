"""Stretches of a swarm run's iterations in one compiled call (:func:`kernels.iterate` on several
threads, :func:`kernels.iterate_serial` on one): the thread count, the block size and the OpenMP
runtime's idle policy."""

from __future__ import annotations

import os
import threading
from typing import Any, NamedTuple

import numpy as np

from staghunt.engine import kernels as kn
from staghunt.engine.arrays import kernel_args
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
CHUNK_SECONDS = 0.05
"""A swarm run's iterations go to the compiled loop (:func:`kernels.iterate`) in stretches of
``CHUNK_ITERATIONS``, or of as many as the last stretch's pace fits in ``CHUNK_SECONDS`` if that
is more (:func:`chunk_length`): between calls the thread count may change, progress is reported
and Ctrl-C is honoured. A call costs about 36 us to dispatch its 60 arguments, so a reply swarm
of ``game`` (668 x 100 on scenario 2: 0.3 ms an iteration) makes two calls instead of five."""


def chunk_length(seconds: float, iterations: int) -> int:
    """The longest next stretch after ``iterations`` iterations took ``seconds`` (see
    :data:`CHUNK_SECONDS`)."""
    pace = seconds / max(1, iterations)
    return max(CHUNK_ITERATIONS, int(CHUNK_SECONDS / pace)) if pace > 0 else CHUNK_ITERATIONS

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
    """One call of the compiled loop: :func:`kernels.iterate` on ``threads`` threads (serialised
    across Python threads unless the threading layer is thread-safe), or
    :func:`kernels.iterate_serial` on one. The caller has loaded the kernel it asks for
    (:func:`staghunt.engine.compilation.parallel_ready` for several threads)."""
    import numba

    parallel = threads > 1
    if not parallel:
        kn.iterate_serial(it0, it1, bs, *_bound(run, w, key, state, gcost, history, rhistory, hviol))
        return
    safe = _thread_safe_layer()
    numba.set_num_threads(threads)
    numba.set_parallel_chunksize(1)  # blocks handed out one at a time: a slow thread takes fewer
    if not safe:
        _LAYER_LOCK.acquire()
    try:
        kn.iterate(it0, it1, bs, *_bound(run, w, key, state, gcost, history, rhistory, hviol))
    finally:
        if not safe:
            _LAYER_LOCK.release()
        numba.set_parallel_chunksize(0)


ITERATE_PER_CALL = ("it0", "it1", "bs")
"""The compiled loop's leading parameters given at each call; the rest are bound by name once per
run (:func:`staghunt.engine.arrays.kernel_args`)."""


class RunState(NamedTuple):
    """What the compiled loop takes besides the run's, model's, swarm's and scratch arrays."""

    key: np.uint64
    state: np.ndarray
    gcost: np.ndarray
    history: np.ndarray
    rhistory: np.ndarray
    hviol: np.ndarray


def _bound(run: Any, w: Scratch, key: np.uint64, state: np.ndarray, gcost: np.ndarray, history: np.ndarray,
           rhistory: np.ndarray, hviol: np.ndarray) -> tuple[Any, ...]:
    """The arguments of :func:`kernels.iterate` after :data:`ITERATE_PER_CALL`, bound by name once
    per run (and stack of scratch buffers)."""
    bound = getattr(run, "_iterate_bound", None)
    if bound is None or bound[0] is not w or bound[1] is not state:
        extra = RunState(key, state, gcost, history, rhistory, hviol)
        bound = (w, state, kernel_args(kn.iterate, extra, run, run.ma, run.sa, w, per_call=ITERATE_PER_CALL))
        run._iterate_bound = bound
    return bound[2]
