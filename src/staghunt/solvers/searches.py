"""The searches of one equilibrium certificate (:func:`staghunt.solvers.response.certify_plan`),
scheduled: on the calling thread or as tasks on a pool, all of them or up to the first
refutation, and kept by UAV so that a later certificate of the same plan does not make them
again (docs/model.md section 7)."""

from __future__ import annotations

from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np


@dataclass
class CertificateWork:
    """The searches a certificate of one plan has made, by UAV: its swarm's result
    (``swarms``: best ``J_n``, path, evaluations, round trip, note) and its local searches
    (``from_plan``, ``from_best``: the ``J_n`` reached or ``None``, path, evaluations, those
    taken). :func:`~staghunt.solvers.response.certify_plan` fills it; a later call for the same
    request takes what it holds (the same computations, so the same certificate)."""

    swarms: dict[int, Any] = field(default_factory=dict)
    from_plan: dict[int, Any] = field(default_factory=dict)
    from_best: dict[int, Any] = field(default_factory=dict)


class Searches:
    """:func:`~staghunt.solvers.response.certify_plan`'s searches, into ``work`` (those it holds
    are not made again): on the calling thread, or as tasks on ``pool`` (three UAVs on two
    workers would leave one idle for a whole UAV if a task were a UAV); the same computations
    either way. The calling thread only waits."""

    def __init__(self, todo: list[int], swarm: Callable[[int], Any], local: Callable[[int, np.ndarray], Any],
                 wp: np.ndarray, work: CertificateWork, pool: ThreadPoolExecutor | None) -> None:
        self.todo, self.swarm, self.local, self.wp, self.work, self.pool = todo, swarm, local, wp, work, pool

    def from_plan(self) -> None:
        """Every UAV's local search from the plan (the cheapest search, and often a refutation)."""
        missing = [n for n in self.todo if n not in self.work.from_plan]
        if self.pool is None:
            for n in missing:
                self.work.from_plan[n] = self.local(n, self.wp[n])
            return
        futures = {n: self.pool.submit(self.local, n, self.wp[n]) for n in missing}
        try:
            for n, f in futures.items():
                self.work.from_plan[n] = f.result()
        except BaseException:
            for f in futures.values():
                f.cancel()
            raise

    def _needs_best(self, n: int) -> bool:
        return n not in self.work.from_best and not np.array_equal(self.work.swarms[n][1], self.wp[n])

    def _done(self, n: int) -> bool:
        return n in self.work.swarms and not self._needs_best(n)

    def in_turn(self, order: list[int], refuted: Callable[[int], bool] | None, plan_too: bool = False) -> list[int]:
        """Each UAV's swarm and its local search from the swarm's best, ``order``'s UAVs in
        turn; with ``refuted``, up to the first UAV for which it is true. Returns the UAVs
        searched, in order (on a pool the tasks run side by side, the swarms, the longest,
        first; a UAV counts once it and every UAV before it in ``order`` are done, so the UAVs
        counted are the same as on one thread; the tasks not started then are cancelled, those
        running are waited for and kept in ``work``). ``plan_too``: the local searches from the
        plan missing are made too (on a pool after the swarms are submitted, the longest first;
        on one thread before them)."""
        counted: list[int] = []
        if self.pool is None:
            if plan_too:
                self.from_plan()
            for n in order:
                if n not in self.work.swarms:
                    self.work.swarms[n] = self.swarm(n)
                if self._needs_best(n):
                    self.work.from_best[n] = self.local(n, self.work.swarms[n][1])
                counted.append(n)
                if refuted is not None and refuted(n):
                    break
            return counted
        pending: dict[Future, tuple[dict[int, Any], int]] = {}

        def submit(into: dict[int, Any], n: int, fn: Callable[..., Any], *args: Any) -> None:
            pending[self.pool.submit(fn, n, *args)] = (into, n)  # type: ignore[union-attr]

        try:
            for n in order:
                if n not in self.work.swarms:
                    submit(self.work.swarms, n, self.swarm)
                elif self._needs_best(n):
                    submit(self.work.from_best, n, self.local, self.work.swarms[n][1])
            for n in order if plan_too else ():
                if n not in self.work.from_plan:
                    submit(self.work.from_plan, n, self.local, self.wp[n])
            while True:
                while len(counted) < len(order) and self._done(order[len(counted)]):
                    counted.append(order[len(counted)])
                    if refuted is not None and refuted(counted[-1]):
                        for f, (into, n) in list(pending.items()):
                            if not f.cancel():
                                into[n] = f.result()
                        return counted
                if not pending:
                    return counted
                ended, _ = wait(pending, return_when=FIRST_COMPLETED)
                for f in ended:
                    into, n = pending.pop(f)
                    into[n] = f.result()
                    if into is self.work.swarms and self._needs_best(n):
                        submit(self.work.from_best, n, self.local, into[n][1])
        except BaseException:
            for f in pending:
                f.cancel()
            raise
