"""Executors: where the tasks of a study run, behind one generator, :func:`run_tasks`.

- :class:`InlineExecutor`: in this process, one task after the other, in order (``--workers 1``,
  tests, ``compare`` by default); the task function may take progress callbacks.
- :class:`DaskExecutor`: a Dask ``distributed`` cluster, either a ``LocalCluster`` started here
  (one worker *process* per core, one thread each) or an existing scheduler joined by address.
  Tasks are submitted in batches (two per worker, at most two batches in flight), so the first
  results come back within seconds and the client's memory does not grow with the number of
  tasks; results come back as tasks complete, in any order.

A task function takes one picklable task and returns one picklable outcome; it must not raise
for a failure of its own task (it returns the failure as data), so an exception that reaches
:func:`run_tasks` from Dask is a lost worker or a lost connection: it is yielded as
:class:`TaskFailure` for that task, and the other tasks go on.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

T = TypeVar("T")
R = TypeVar("R")

DEFAULT_CONNECT_TIMEOUT_S = 10.0
"""How long joining an existing scheduler may take before it is reported unreachable."""

TASKS_PER_WORKER = 2
MIN_BATCH = 8
"""A Dask executor submits tasks in batches of ``max(MIN_BATCH, TASKS_PER_WORKER x workers)``
and holds at most two batches in flight."""


class ClusterError(ValueError):
    """The cluster cannot be started or reached (one line)."""


@dataclass(frozen=True)
class TaskFailure:
    """A task whose worker (or connection) was lost: ``message`` is one line."""

    message: str


class Executor(Protocol):
    """Runs ``fn(task)`` for every task, yielding ``(index, outcome)`` as tasks complete."""

    local: bool
    """Whether tasks run in this process (progress callbacks can then reach the caller)."""

    workers: int

    def map_unordered(self, fn: Callable[[T], R], tasks: Sequence[T]) -> Iterator[tuple[int, "R | TaskFailure"]]:
        ...

    def warm_workers(self, fn: Callable[[], float]) -> list[float]:
        ...

    def close(self) -> None:
        ...


class InlineExecutor:
    """Runs every task here, one after the other, in order."""

    local = True
    workers = 1
    description = "this process"

    def map_unordered(self, fn: Callable[[T], R], tasks: Sequence[T]) -> Iterator[tuple[int, "R | TaskFailure"]]:
        for index, task in enumerate(tasks):
            yield index, fn(task)

    def warm_workers(self, fn: Callable[[], float]) -> list[float]:
        """Nothing to warm apart from this process (the caller's own warm-up)."""
        return []

    def close(self) -> None:
        pass

    def __enter__(self) -> "InlineExecutor":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


class DaskExecutor(Generic[T, R]):
    """A Dask ``distributed`` client: a ``LocalCluster`` of ``workers`` processes (default: one
    per usable core; one thread each) or, with ``address``, an existing scheduler, joined within
    ``connect_timeout`` seconds. Raises :class:`ClusterError` when the scheduler cannot be
    reached or the cluster cannot start."""

    local = False

    def __init__(self, address: str | None = None, workers: int | None = None,
                 connect_timeout: float = DEFAULT_CONNECT_TIMEOUT_S) -> None:
        import logging

        # The cluster's own logging (worker restarts, lost connections) is not the user's
        # business unless STAGHUNT_DEBUG is set: the sweep reports what matters. The variable is
        # read when distributed is imported, here and in the (spawned) workers.
        if not os.environ.get("STAGHUNT_DEBUG"):
            os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "critical")
        import dask
        from distributed import Client, LocalCluster

        if not os.environ.get("STAGHUNT_DEBUG"):
            # tornado.application: Dask's logging configuration sets it apart, to "error"; a
            # Ctrl-C in the middle of a client call made it print a traceback.
            for name in ("distributed", "tornado", "tornado.application"):
                logging.getLogger(name).setLevel(logging.CRITICAL)
        self.cluster = None
        if address is not None:
            try:
                self.client = Client(address, timeout=connect_timeout, set_as_default=False)
            except (OSError, TimeoutError, ValueError) as exc:
                raise ClusterError(f"cannot reach the Dask scheduler at {address} within "
                                   f"{connect_timeout:g} s ({_one_line(exc)})") from None
            self.description = f"the Dask scheduler at {address}"
        else:
            from staghunt.engine.threads import usable_cores

            n = workers if workers is not None else usable_cores()
            env = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                   "NUMBA_NUM_THREADS": "1"}
            try:
                # No dashboard, so nobody reads the workers' statistical profiler: it would sample
                # the task thread's stack 100 times a second, taking the GIL from the task.
                with dask.config.set({"distributed.worker.profile.enabled": False}):
                    self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                                dashboard_address=None, env=env)
                self.client = Client(self.cluster, set_as_default=False)
            except (OSError, TimeoutError, RuntimeError) as exc:
                if self.cluster is not None:
                    self.cluster.close()
                raise ClusterError(f"cannot start a local Dask cluster of {n} workers ({_one_line(exc)})") from None
            self.description = f"a local Dask cluster of {n} worker processes"

    @property
    def workers(self) -> int:
        try:  # distributed >= 2025.1 lists only the first few workers unless told otherwise
            info = self.client.scheduler_info(n_workers=-1)
        except TypeError:
            info = self.client.scheduler_info()
        return max(1, len(info.get("workers", {})))

    def warm_workers(self, fn: Callable[[], float]) -> list[float]:
        """Run ``fn`` once on every worker now (e.g. load the compiled kernels from the on-disk
        cache, so the first task of each worker does not pay it); returns what each returned."""
        return [float(v) for v in self.client.run(fn).values()]

    def batch_size(self) -> int:
        """Tasks submitted at once: :data:`TASKS_PER_WORKER` per worker, at least :data:`MIN_BATCH`."""
        return max(MIN_BATCH, TASKS_PER_WORKER * self.workers)

    def map_unordered(self, fn: Callable[[T], R], tasks: Sequence[T]) -> Iterator[tuple[int, "R | TaskFailure"]]:
        """Submit ``tasks`` in batches: one batch at the start, the next one each time the
        tasks in flight fall to a batch or fewer, so the cluster always has work queued while
        the client holds at most two batches of futures (and of tasks: ``tasks`` may be a lazy
        sequence, read in order as the batches go)."""
        from distributed import as_completed

        queue = iter(range(len(tasks)))
        flight: dict[str, tuple[int, Any]] = {}  # key -> (index, future) of the tasks not yet yielded
        pending = as_completed(loop=self.client.loop)

        def submit(n: int) -> None:
            batch = list(itertools.islice(queue, n))
            if batch:
                futures = self.client.map(fn, [tasks[i] for i in batch], pure=False)
                flight.update({f.key: (i, f) for f, i in zip(futures, batch)})
                pending.update(futures)

        batch = self.batch_size()
        submit(batch)
        try:
            for future in pending:
                i, _ = flight.pop(future.key)
                try:
                    outcome: R | TaskFailure = future.result()
                except Exception as exc:  # a lost worker (KilledWorker), a lost connection
                    outcome = TaskFailure(f"{type(exc).__name__}: {_one_line(exc)}")
                future.release()
                if len(flight) <= batch:
                    batch = self.batch_size()  # workers may have joined or left
                    submit(2 * batch - len(flight))
                yield i, outcome
        finally:
            for _, f in flight.values():
                f.cancel()

    def close(self) -> None:
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()

    def __enter__(self) -> "DaskExecutor[T, R]":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def runs_here(address: str | None = None, workers: int | None = None) -> bool:
    """Whether :func:`make_executor` with these arguments runs the tasks in this process (one
    worker, no scheduler), known before any cluster starts."""
    return address is None and workers == 1


def make_executor(address: str | None = None, workers: int | None = None,
                  connect_timeout: float = DEFAULT_CONNECT_TIMEOUT_S) -> "InlineExecutor | DaskExecutor[Any, Any]":
    """An :class:`InlineExecutor` when :func:`runs_here`; otherwise a :class:`DaskExecutor` (a
    local cluster, or the scheduler at ``address``)."""
    if runs_here(address, workers):
        return InlineExecutor()
    return DaskExecutor(address, workers, connect_timeout)


def run_tasks(fn: Callable[[T], R], tasks: Sequence[T],
              executor: "Executor | InlineExecutor | DaskExecutor[Any, Any]") -> Iterator[tuple[int, "R | TaskFailure"]]:
    """Run ``fn`` over ``tasks`` on ``executor``; yields ``(index into tasks, outcome)`` as each
    task completes (in order for the inline executor)."""
    if not tasks:
        return iter(())
    return executor.map_unordered(fn, tasks)
