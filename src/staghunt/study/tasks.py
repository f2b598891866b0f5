"""One task of a study: one plan plus its certificate, run by :func:`run_plan_task` wherever the
executor puts it (this process or a Dask worker).

A :class:`PlanTask` carries a :class:`~staghunt.api.PlanRequest` already checked by the client
(scenario after overrides, method, seed, settings, engine, certificate budget), so a worker
checks nothing again. The outcome is plain data (:class:`TaskOutcome`): the full
:class:`~staghunt.result.PlanResult` when asked for (``compare`` writes its ``result.json``
files from it), and always the summary :func:`summary_row` (what a sweep stores). A task that
raises does not raise out of :func:`run_plan_task`: its outcome has ``error`` set (one line),
so one bad task never ends a study.
"""

from __future__ import annotations

import math
import os
import socket
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from staghunt.api import PlanRequest
    from staghunt.result import PlanResult
    from staghunt.solvers.response import Certificate
    from staghunt.solvers.swarm import Progress


@dataclass(frozen=True, eq=False)
class PlanTask:
    """``request``: the checked run (with its certificate options, ``None``: no certificate);
    ``key``: the task's identity (a hash of its configuration, :func:`task_key`); ``labels``:
    what the caller wants back in the row (scenario name, overrides...); ``keep_result``: also
    return the :class:`PlanResult`; ``waypoints``: ``(N, K, 3)`` to certify an existing plan
    instead of planning (``compare`` resuming a run planned but not yet certified)."""

    request: "PlanRequest"
    key: str = ""
    labels: Mapping[str, Any] = field(default_factory=dict)
    keep_result: bool = False
    waypoints: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class TaskOutcome:
    """What a task sends back: ``row`` (plain data, :func:`summary_row`), the ``result`` (if
    kept), the ``certificate`` (certify-only tasks), ``error`` (one line) if the task raised."""

    key: str
    row: dict[str, Any]
    result: "PlanResult | None" = None
    certificate: "Certificate | None" = None
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


def worker_name() -> str:
    """``host:pid`` of the process running the task."""
    return f"{socket.gethostname()}:{os.getpid()}"


def summary_row(result: "PlanResult") -> dict[str, Any]:
    """The stored summary of a finished task: status, per-UAV ``J``, ``J_s``, ``J_f`` (lists of
    ``N`` floats), the largest relative Nash gap, whether the plan is a certified equilibrium,
    whether the method reports it payoff-dominant (``None`` when it does not say), evaluations,
    times, and ``history``: ``(iterations + 1, N)`` as a list of lists (each UAV's ``J_n`` of the
    best allocation per iteration)."""
    cert = result.certificate
    gap = math.nan
    equilibrium = None
    if cert is not None:
        gap = float(cert.max_relative_gap)
        equilibrium = bool(cert.is_equilibrium)
    selection = result.details.get("selection", {}) if isinstance(result.details, Mapping) else {}
    dominant = selection.get("payoff_dominant") if isinstance(selection, Mapping) else None
    return {
        "status": str(getattr(result.status, "value", result.status)),
        "message": "",
        "J": [float(v) for v in result.costs.total[0]],
        "J_s": [float(v) for v in result.costs.single[0]],
        "J_f": [float(v) for v in result.costs.formation[0]],
        "max_relative_gap": gap,
        "equilibrium": equilibrium,
        "payoff_dominant": None if dominant is None else bool(dominant),
        "evaluations": int(result.evaluations),
        "wall_time_s": float(result.wall_time_s),
        "certificate_time_s": float(result.certificate_time_s),
        "compile_time_s": float(result.compile_time_s),
        "history": [[float(v) for v in row] for row in np.asarray(result.history, dtype=float)],
    }


def run_plan_task(task: PlanTask, progress: "Progress | None" = None,
                  certify_progress: Callable[[int, int, int, int], None] | None = None) -> TaskOutcome:
    """Plan and certify ``task.request`` (:func:`staghunt.api.plan`), or only certify
    ``task.waypoints``; never raises for the task's own failure (see the module docstring).
    ``progress`` and ``certify_progress``: callbacks of :func:`staghunt.api.plan` (in-process
    executors only)."""
    import staghunt.api as api  # looked up at call time (tests replace api.plan)

    t0, cpu0 = time.perf_counter(), time.thread_time()  # one engine thread: the calling thread's CPU time
    base = {"worker": worker_name()}
    try:
        if task.waypoints is not None:
            cert = api.certify_waypoints(task.request, np.asarray(task.waypoints, dtype=float), certify_progress)
            return TaskOutcome(task.key, {**base, "status": "certified", "task_time_s": time.perf_counter() - t0},
                               certificate=cert)
        result = api.plan(task.request, progress=progress, certify_progress=certify_progress)
        row = {**base, **summary_row(result), "task_time_s": time.perf_counter() - t0,
               "cpu_time_s": time.thread_time() - cpu0}
        return TaskOutcome(task.key, row, result if task.keep_result else None)
    except (KeyboardInterrupt, SystemExit):
        raise
    except Exception as exc:  # recorded, never fatal to the study
        message = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
        return TaskOutcome(task.key, {**base, "status": "error", "message": message,
                                      "task_time_s": time.perf_counter() - t0}, error=message)
