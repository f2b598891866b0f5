"""Per-thread block buffers of the compiled engine, pooled by shape: many short runs (``game``'s
replies, the polish's evaluations) would otherwise spend more time allocating than computing."""

from __future__ import annotations

import threading

import numpy as np


class Scratch:
    """One thread's block buffers for ``N`` UAVs, ``K`` waypoints, ``S`` swarms, ``B`` lanes
    (shapes in :mod:`staghunt.engine.kernels`); with ``threads``, one set per thread stacked on a
    leading axis (for :func:`staghunt.engine.kernels.iterate`)."""

    def __init__(self, N: int, K: int, S: int, B: int, threads: int | None = None) -> None:
        S1 = K + 1
        self.B = B
        lead = () if threads is None else (threads,)

        def z(*shape: int, dtype: type = np.float64) -> np.ndarray:
            return np.zeros(lead + shape, dtype=dtype)

        self.sww = z(max(S, 1), 3, K, B)
        self.px = z(N, K + 2, B)
        self.py = z(N, K + 2, B)
        self.pz = z(N, K + 2, B)
        self.ph = z(N, K, B)
        self.seg = z(5, S1, B)
        self.sub = z(6, S1, B)
        self.ang = z(2, S1, B)
        self.form = z(3, N, S1, B)
        self.hit = z(2, S1, B)
        self.terms = z(N, 5, B)
        self.vio = z(N, 3, B)
        self.res = z(3, N, B)
        self.tmp = z(max(S1, 3 * N, 8), B)
        self.stx = z(B)
        self.sty = z(B)
        self.sth = z(B)
        self.prev = z(3, B)
        self.acc = z(B)
        self.acc2 = z(B)
        self.flag = z(B)
        self.better = z(B)
        self.bits1 = z(B, dtype=np.uint64)
        self.bits2 = z(B, dtype=np.uint64)
        self.ubits1 = self.bits1.view(np.float64)  # the same memory, read as floats
        self.ubits2 = self.bits2.view(np.float64)
        self.box = z(6, N, K + 2)
        self.near = z(S1, dtype=np.int64)
        self.qcost = z(2, 6 * K)


_POOL: dict[tuple[int, ...], list[Scratch]] = {}
_POOL_LOCK = threading.Lock()
_POOL_KEEP = 8
"""Idle buffers kept per shape: many short runs (``game``'s replies, the polish's evaluations)
would otherwise spend more time allocating buffers than computing."""


def borrow(shape: tuple[int, ...], count: int) -> list[Scratch]:
    """``count`` buffers of ``shape`` = ``(N, K, S, B)`` (one thread's) or ``(N, K, S, B, T)``
    (``T`` threads' stacked), from the pool or new."""
    with _POOL_LOCK:
        free = _POOL.setdefault(shape, [])
        taken = [free.pop() for _ in range(min(count, len(free)))]
    return taken + [Scratch(*shape) for _ in range(count - len(taken))]


def give_back(shape: tuple[int, ...], scratch: list[Scratch]) -> None:
    with _POOL_LOCK:
        free = _POOL.setdefault(shape, [])
        free.extend(scratch[: max(0, _POOL_KEEP - len(free))])
