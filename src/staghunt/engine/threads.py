"""Running one iteration's particle blocks on several threads, and choosing how many.

A swarm run's iterations run in the compiled loop :func:`staghunt.engine.kernels.iterate`
(Numba's ``prange`` over the blocks, stretches of iterations per call; :class:`BlockRunner`,
plain Python threads over the ``nogil`` kernels, is the older way, kept for callers that run
blocks themselves). Every iteration ends at a barrier (the global best needs every particle),
and a barrier is what makes extra threads *slower* on a busy machine: a thread that shares its core with another process
waits for a whole scheduler time slice while the others idle at the barrier. So the default
(``threads=None``) is adaptive: :class:`AdaptiveThreads` times iterations with 1 thread and with
all usable cores in short probes, repeated periodically and whenever the many-thread
iterations slow down, and keeps the faster for the next stretch. Results never depend on the
thread count (counter-based random draws, per-particle work, an order-independent reduction),
so switching is free.
"""

from __future__ import annotations

import itertools
import math
import os
import statistics
from concurrent.futures import Future
from typing import Callable

from staghunt.solvers.swarm import shared_pool

PROBE_EVERY = 100
"""Iterations between two probes (the first probe starts at the first iteration)."""

PROBE_LENGTH = 3
"""Iterations timed per candidate thread count in a probe (the medians are compared)."""

MARGIN = 0.9
"""Many threads are kept only when their median probe iteration takes under this fraction of
the single thread's."""

WATCH = 5
"""Running many threads, the median of this many latest iterations is watched."""

BLOCKS_PER_THREAD = 2
"""Particle blocks per thread and iteration when running on several threads (work sharing)."""


def usable_cores() -> int:
    """Cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


class BlockRunner:
    """Runs ``work(p0, p1, worker)`` over ``[0, P)`` split into blocks, on ``1..max_threads`` threads.

    The calling thread works too; the others come from a process-wide pool. Blocks are handed out
    dynamically (first come, first served), so a thread slowed down by another process simply
    takes fewer blocks.
    """

    def __init__(self, max_threads: int) -> None:
        self.max_threads = max(1, int(max_threads))
        self._pool = shared_pool(self.max_threads - 1, "block") if self.max_threads > 1 else None

    def run(self, work: Callable[[int, int, int], None], n_particles: int, threads: int, align: int = 8) -> None:
        """Process all particles with ``threads`` threads (``1 <= threads <= max_threads``):
        ``work(p0, p1, worker)`` for ranges whose sizes are multiples of ``align`` (but the last);
        ``worker`` in ``0 .. threads-1`` identifies the thread (for its scratch buffers)."""
        threads = max(1, min(threads, self.max_threads))
        if threads == 1 or self._pool is None:
            work(0, n_particles, 0)
            return
        n_blocks = threads * BLOCKS_PER_THREAD
        size = -(-n_particles // n_blocks)
        size = max(align, -(-size // align) * align)
        bounds = [(p, min(p + size, n_particles)) for p in range(0, n_particles, size)]
        counter = itertools.count()  # next() is atomic under the GIL

        def worker(wid: int) -> None:
            while True:
                i = next(counter)
                if i >= len(bounds):
                    return
                work(bounds[i][0], bounds[i][1], wid)

        futures: list[Future[None]] = [self._pool.submit(worker, w) for w in range(1, threads)]
        worker(0)
        for f in futures:
            f.result()

    def close(self) -> None:
        """Detach from the shared pool (its threads stay for the next run)."""
        self._pool = None

    def __enter__(self) -> "BlockRunner":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class AdaptiveThreads:
    """Picks the thread count for each iteration; ``fixed`` pins it (even above the core count).

    With ``fixed=None`` and more than one usable core, a *probe* runs ``2 * PROBE_LENGTH``
    iterations alternating 1 thread and ``max_threads``, and the many-thread count is kept only
    if its median iteration time beats the single thread's by :data:`MARGIN`. Probes repeat
    every ``PROBE_EVERY`` iterations, and at once when, running many threads, the median of the
    last :data:`WATCH` iterations exceeds the single-thread median (the machine got busy).
    ``record`` receives each iteration's wall time.
    """

    def __init__(self, max_threads: int, fixed: int | None = None) -> None:
        self.fixed = None if fixed is None else max(1, int(fixed))
        self.max_threads = max(1, max_threads) if self.fixed is None else self.fixed
        self.choice = self.max_threads if self.fixed is None else self.fixed
        self._probe: list[tuple[int, float]] = []
        self._probe_left = 2 * PROBE_LENGTH
        self._since_probe = 0
        self._single = math.inf
        self._recent: list[float] = []
        self.history: list[int] = []

    @property
    def adaptive(self) -> bool:
        return self.fixed is None and self.max_threads > 1

    def next(self) -> int:
        """Thread count for the coming iteration."""
        if not self.adaptive:
            n = self.max_threads
        elif self._probe_left > 0:
            n = 1 if self._probe_left % 2 == 0 else self.max_threads
        else:
            n = self.choice
        self.history.append(n)
        return n

    def record(self, seconds: float) -> None:
        """Wall time of the iteration just run with the count :meth:`next` returned."""
        if not self.adaptive:
            return
        n = self.history[-1]
        if self._probe_left > 0:
            self._probe.append((n, seconds))
            self._probe_left -= 1
            if self._probe_left == 0:
                one = statistics.median(t for k, t in self._probe if k == 1)
                many = statistics.median(t for k, t in self._probe if k != 1)
                self._single = one
                self.choice = self.max_threads if many < MARGIN * one else 1
                self._probe, self._recent, self._since_probe = [], [], 0
            return
        self._since_probe += 1
        if n != 1:
            self._recent = (self._recent + [seconds])[-WATCH:]
            slow = len(self._recent) == WATCH and statistics.median(self._recent) > self._single
        else:
            slow = False
        if slow or self._since_probe >= PROBE_EVERY:
            self._probe_left = 2 * PROBE_LENGTH

    def chunk(self, left: int, longest: int) -> tuple[int, int]:
        """Thread count and length (iterations, at most ``min(left, longest)``) of the next
        stretch run in one call: one iteration while probing, else up to the next probe."""
        n = self.next()
        if self.adaptive and self._probe_left > 0:
            length = 1
        else:
            length = max(1, min(left, longest))
            if self.adaptive:
                length = max(1, min(length, PROBE_EVERY - self._since_probe))
        self.history.extend([n] * (length - 1))
        return n, length

    def record_chunk(self, seconds: float, length: int) -> None:
        """Wall time of a stretch from :meth:`chunk`: each of its ``length`` iterations is taken
        to have lasted ``seconds / length`` (a probe due during the stretch starts after it)."""
        if not self.adaptive:  # nothing to decide: a pinned count keeps no timings
            return
        for _ in range(length):
            probing = self._probe_left > 0
            self.record(seconds / length)
            if not probing and self._probe_left > 0:
                break

    def summary(self) -> dict[int, int]:
        """Iterations run with each thread count."""
        out: dict[int, int] = {}
        for n in self.history:
            out[n] = out.get(n, 0) + 1
        return out
