"""Per-thread block buffers of the compiled engine, pooled by shape: many short runs (``game``'s
replies, the polish's evaluations) would otherwise spend more time allocating than computing."""

from __future__ import annotations

import threading

import numpy as np


class Scratch:
    """One thread's block buffers for ``N`` UAVs, ``K`` waypoints, ``S`` swarms, ``B`` lanes
    (shapes in :mod:`staghunt.engine.kernels`)."""

    def __init__(self, N: int, K: int, S: int, B: int) -> None:
        S1 = K + 1
        self.B = B
        self.sww = np.zeros((max(S, 1), 3, K, B))
        self.px = np.zeros((N, K + 2, B))
        self.py = np.zeros((N, K + 2, B))
        self.pz = np.zeros((N, K + 2, B))
        self.ph = np.zeros((N, K, B))
        self.seg = np.zeros((5, S1, B))
        self.sub = np.zeros((6, S1, B))
        self.ang = np.zeros((2, S1, B))
        self.form = np.zeros((3, N, S1, B))
        self.hit = np.zeros((2, S1, B))
        self.rx = np.zeros((K + 2, B))
        self.ry = np.zeros((K + 2, B))
        self.rz = np.zeros((K + 2, B))
        self.terms = np.zeros((N, 5, B))
        self.vio = np.zeros((N, 3, B))
        self.res = np.zeros((3, N, B))
        self.tmp = np.zeros((max(S1, 3 * N, 8), B))
        self.stx = np.zeros(B)
        self.sty = np.zeros(B)
        self.sth = np.zeros(B)
        self.prev = np.zeros((3, B))
        self.acc = np.zeros(B)
        self.acc2 = np.zeros(B)
        self.flag = np.zeros(B)
        self.better = np.zeros(B)
        self.bits1 = np.zeros(B, dtype=np.uint64)
        self.bits2 = np.zeros(B, dtype=np.uint64)


_POOL: dict[tuple[int, int, int, int], list[Scratch]] = {}
_POOL_LOCK = threading.Lock()
_POOL_KEEP = 8
"""Idle buffers kept per shape: many short runs (``game``'s replies, the polish's evaluations)
would otherwise spend more time allocating buffers than computing."""


def borrow(shape: tuple[int, int, int, int], count: int) -> list[Scratch]:
    with _POOL_LOCK:
        free = _POOL.setdefault(shape, [])
        taken = [free.pop() for _ in range(min(count, len(free)))]
    return taken + [Scratch(*shape) for _ in range(count - len(taken))]


def give_back(shape: tuple[int, int, int, int], scratch: list[Scratch]) -> None:
    with _POOL_LOCK:
        free = _POOL.setdefault(shape, [])
        free.extend(scratch[: max(0, _POOL_KEEP - len(free))])
