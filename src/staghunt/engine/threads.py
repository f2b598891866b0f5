"""Running one iteration's particle blocks on several threads, and choosing how many.

The kernels release the GIL (``nogil``), so plain Python threads run them in parallel. Every
iteration ends at a barrier (the global best needs every particle), and a barrier is what makes
extra threads *slower* on a busy machine: a thread that shares its core with another process
waits for a whole scheduler time slice while the others idle at the barrier. So the default
(``threads=None``) is adaptive: :class:`AdaptiveThreads` times iterations with 1 thread and with
all usable cores in short probes, repeated periodically, and keeps the faster for the next
stretch. Results never depend on the thread count (counter-based random draws, per-particle
work, an order-independent reduction), so switching is free.
"""

from __future__ import annotations

import itertools
import os
import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable

PROBE_EVERY = 100
"""Iterations between two probes (the first probe starts at the first iteration)."""

PROBE_LENGTH = 3
"""Iterations timed per candidate thread count in a probe (the minimum is compared)."""

BLOCKS_PER_THREAD = 4
"""Particle blocks per thread and iteration when running on several threads (work sharing)."""


def usable_cores() -> int:
    """Cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


class BlockRunner:
    """Runs ``work(p0, p1)`` over ``[0, P)`` split into blocks, on ``1..max_threads`` threads.

    The calling thread works too; the others come from a private pool. Blocks are handed out
    dynamically (first come, first served), so a thread slowed down by another process simply
    takes fewer blocks.
    """

    def __init__(self, max_threads: int) -> None:
        self.max_threads = max(1, int(max_threads))
        self._pool = ThreadPoolExecutor(self.max_threads - 1) if self.max_threads > 1 else None

    def run(self, work: Callable[[int, int], None], n_particles: int, threads: int, align: int = 8) -> None:
        """Process all particles with ``threads`` threads (``1 <= threads <= max_threads``)."""
        threads = max(1, min(threads, self.max_threads))
        if threads == 1 or self._pool is None:
            work(0, n_particles)
            return
        n_blocks = threads * BLOCKS_PER_THREAD
        size = -(-n_particles // n_blocks)
        size = max(align, -(-size // align) * align)
        bounds = [(p, min(p + size, n_particles)) for p in range(0, n_particles, size)]
        counter = itertools.count()  # next() is atomic under the GIL

        def worker() -> None:
            while True:
                i = next(counter)
                if i >= len(bounds):
                    return
                work(*bounds[i])

        futures: list[Future[None]] = [self._pool.submit(worker) for _ in range(threads - 1)]
        worker()
        for f in futures:
            f.result()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> "BlockRunner":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class AdaptiveThreads:
    """Picks the thread count for each iteration; ``fixed`` pins it (even above the core count).

    With ``fixed=None`` and more than one usable core: a probe (``PROBE_LENGTH`` iterations with
    1 thread, then as many with ``max_threads``) every ``PROBE_EVERY`` iterations; in between, the
    count whose fastest probe iteration was faster. ``record`` receives each iteration's wall time.
    """

    def __init__(self, max_threads: int, fixed: int | None = None) -> None:
        self.fixed = None if fixed is None else max(1, int(fixed))
        self.max_threads = max(1, max_threads) if self.fixed is None else self.fixed
        self.choice = self.max_threads if self.fixed is None else self.fixed
        self._times: dict[int, list[float]] = {}
        self._step = 0
        self.history: list[int] = []

    def _plan(self, step: int) -> int:
        if self.fixed is not None:
            return self.fixed
        if self.max_threads == 1:
            return 1
        phase = step % PROBE_EVERY
        if phase < PROBE_LENGTH:
            return 1
        if phase < 2 * PROBE_LENGTH:
            return self.max_threads
        return self.choice

    def next(self) -> int:
        """Thread count for the coming iteration."""
        n = self._plan(self._step)
        self.history.append(n)
        return n

    def record(self, seconds: float) -> None:
        """Wall time of the iteration just run with the count :meth:`next` returned."""
        if self.fixed is None and self.max_threads > 1:
            phase = self._step % PROBE_EVERY
            n = self.history[-1]
            if phase == 0:
                self._times = {}
            if phase < 2 * PROBE_LENGTH:
                self._times.setdefault(n, []).append(seconds)
                if phase == 2 * PROBE_LENGTH - 1:
                    best = {k: min(v) for k, v in self._times.items()}
                    self.choice = min(best, key=lambda k: (best[k], k))
        self._step += 1

    def summary(self) -> dict[int, int]:
        """Iterations run with each thread count."""
        out: dict[int, int] = {}
        for n in self.history:
            out[n] = out.get(n, 0) + 1
        return out


def timed(fn: Callable[[], None]) -> float:
    """Wall time of ``fn()`` in seconds."""
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0
