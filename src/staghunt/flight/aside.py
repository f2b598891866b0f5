"""A second process for the plan from rest that a re-plan solves beside the moving one.

On two cores :class:`~staghunt.flight.replan.Replanner` solves the plan from the switch state
and the stop-then-plan-from-rest at once. In two threads of one process the two solves share
the interpreter lock, and most of a small solve is Python between short compiled calls: on
scenario 2 two solves in threads took 1.5-1.8x the time of one. In a process of its own the
plan from rest takes nothing from the moving solve.

One worker process per Python process (:func:`rest_worker`), started on first use and kept
(spawned, not forked: the parent has OpenMP threads), with its kernels loaded from Numba's
cache and the module named by :func:`start` imported. A solve in it is cancelled through a
shared event, checked after every reply. Its result is the same as in a thread: the solve's
generator is drawn by the parent and sent along, and the worker's engine is the compiled one
on one thread. This module imports nothing of the planner: the function it runs arrives
pickled by name (:meth:`RestWorker.submit`).
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.util
import signal
import threading
import warnings
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any, Callable

_cancel: Any = None
"""The worker's cancel event (set in the worker by :func:`_start`)."""


def _start(cancel: Any) -> None:
    """The worker's set-up: the cancel event; Ctrl-C is the parent's to handle (the worker is
    shut down with it), and warnings are the parent's to report (a solve here reports none)."""
    global _cancel
    _cancel = cancel
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    warnings.simplefilter("ignore")


def _warm(preload: str) -> bool:
    """Import ``preload`` and load the kernels (run once in the worker, before any solve)."""
    import importlib

    from staghunt.engine import get_engine

    importlib.import_module(preload)  # imported now rather than at the first solve
    get_engine("numba", threads=1).prepare()
    return True


def _call(fn: Callable[..., Any], state: Any, args: tuple[Any, ...]) -> Any:
    """``fn(state, args, cancel)`` in the worker, with the worker's cancel event."""
    return fn(state, args, _cancel)


class RestWorker:
    """The worker process: :meth:`submit` a solve, :meth:`cancel` it."""

    def __init__(self, preload: str) -> None:
        context = multiprocessing.get_context("spawn")
        self._event = context.Event()
        self._pool = ProcessPoolExecutor(1, mp_context=context, initializer=_start, initargs=(self._event,))
        self.ready: Future[bool] = self._pool.submit(_warm, preload)
        self.solves = 0

    def submit(self, fn: Callable[..., Any], state: Any, args: tuple[Any, ...]) -> Future[Any]:
        """Run ``fn(state, args, cancel)`` in the worker (``fn`` a module-level function, sent
        by name; ``cancel`` the event :meth:`cancel` sets)."""
        self._event.clear()
        self.solves += 1
        return self._pool.submit(_call, fn, state, args)

    def cancel(self) -> None:
        self._event.set()

    def close(self) -> None:
        """Stop the worker and wait for it (a solve in progress stops after its reply)."""
        self._event.set()
        self._pool.shutdown(wait=True, cancel_futures=True)


_worker: RestWorker | None = None
_failed = False
_lock = threading.Lock()


def start(preload: str) -> RestWorker | None:
    """Start the process's worker if it is not running yet, without waiting for it, importing
    the module ``preload`` in it (``None`` if no process can be started here)."""
    global _worker, _failed
    with _lock:
        if _worker is None and not _failed:
            try:
                _worker = RestWorker(preload)
                # Stopped at exit by multiprocessing's finalizers, which run in every process
                # (atexit does not in one that multiprocessing started, a pool's worker flying
                # episodes: there the worker, never told to stop, kept the process alive for
                # ever), by priority: this one before the queue to the worker is closed
                # (priority 10), else the stop signal is queued behind the queue's end.
                multiprocessing.util.Finalize(_worker, _worker.close, exitpriority=100)
            except (OSError, RuntimeError):
                _failed = True
        return None if _failed else _worker


def rest_worker(wait: str | None = None) -> RestWorker | None:
    """The worker, if it has loaded its kernels (``wait``: a module to preload; start the
    worker and wait until it has, a few seconds the first time); else ``None``, and the
    caller solves in a thread (the same result). A worker that failed to start, or died, is
    not used again."""
    global _failed
    worker = start(wait) if wait else _worker
    if worker is None or _failed or not (wait or worker.ready.done()):
        return None
    try:
        worker.ready.result()
    except Exception:  # noqa: BLE001 (a worker that cannot even start: solve in threads)
        worker_broke()
        return None
    return worker


def worker_broke() -> None:
    """The worker died (its pool is broken): solve in threads from now on."""
    global _failed
    with _lock:
        _failed = True
