"""Running a sweep: the tasks of an expanded spec not yet in the store, on an executor, their
rows appended to the store as they complete.

``DIR/results.parquet/``: one row per finished task (status ``feasible`` or ``infeasible``),
each key once (:mod:`staghunt.study.store`). A task that raised (a bug, or a worker lost for
good) is not finished: its row (status ``error``, the one-line message) goes to
``DIR/errors.parquet/`` instead, and the next run of the same spec runs it again. So a sweep
whose client or worker was killed (``kill -9``) finishes, when rerun, with every task exactly
once in ``results.parquet``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from staghunt.study.executor import InlineExecutor, TaskFailure, run_tasks
from staghunt.study.grid import Sweep, TaskList
from staghunt.study.store import ResultStore
from staghunt.study.tasks import PlanTask, TaskOutcome, run_plan_task

RESULTS = "results.parquet"
ERRORS = "errors.parquet"
FLUSH_EVERY_S = 2.0
"""Rows are written at most this long after their task completes (and at the end)."""

_LIST = pa.list_(pa.float64())
_KINDS = {"float": pa.float64(), "int": pa.int64(), "weights": _LIST}


def sweep_schema_columns(sweep: Sweep) -> pa.Schema:
    """The columns of ``results.parquet`` for ``sweep`` (the override columns in between)."""
    fields = [("key", pa.string()), ("scenario", pa.string()), ("method", pa.string()), ("seed", pa.int64())]
    fields += [(name, _KINDS[kind]) for name, kind in sweep.overrides]
    fields += [("particles", pa.int64()), ("iterations", pa.int64()), ("waypoints", pa.int64()),
               ("engine", pa.string()), ("status", pa.string()), ("message", pa.string()),
               ("J", _LIST), ("J_s", _LIST), ("J_f", _LIST), ("max_relative_gap", pa.float64()),
               ("equilibrium", pa.bool_()), ("payoff_dominant", pa.bool_()), ("evaluations", pa.int64()),
               ("wall_time_s", pa.float64()), ("certificate_time_s", pa.float64()),
               ("compile_time_s", pa.float64()), ("task_time_s", pa.float64()), ("cpu_time_s", pa.float64()),
               ("history", pa.list_(_LIST)), ("worker", pa.string()), ("version", pa.string())]
    return pa.schema([pa.field(n, t) for n, t in fields])


@dataclass
class SweepSummary:
    """What a run of the sweep did: ``total`` tasks in the spec, ``skipped`` (already in the
    store), ``done`` now, ``failed`` now (in ``errors.parquet``; run again next time),
    ``elapsed_s`` for the tasks run now (excluding cluster start-up), ``remaining``: tasks not
    finished when the run ended (interrupted)."""

    total: int
    skipped: int
    done: int = 0
    failed: int = 0
    elapsed_s: float = 0.0
    interrupted: bool = False

    @property
    def throughput(self) -> float:
        """Tasks finished per second (done and failed alike)."""
        return (self.done + self.failed) / self.elapsed_s if self.elapsed_s > 0 else 0.0

    @property
    def remaining(self) -> int:
        return self.total - self.skipped - self.done - self.failed


class SweepListener:
    """Progress hooks (the default does nothing); the CLI subclasses it."""

    def started(self, summary: SweepSummary, workers: int) -> None:
        """The tasks to run are known; the executor has ``workers`` workers."""

    def task_finished(self, summary: SweepSummary, row: dict[str, Any]) -> None:
        """A task finished (``row["status"]``; ``"error"`` for a failed one)."""


def open_stores(out_dir: Path, sweep: Sweep) -> tuple[ResultStore, ResultStore]:
    """The result and error stores under ``out_dir`` (created; stale temporary parts removed,
    duplicate keys compacted)."""
    schema = sweep_schema_columns(sweep)
    return (ResultStore(out_dir / RESULTS, schema).open(), ResultStore(out_dir / ERRORS, schema).open())


def pending(sweep: Sweep, results: ResultStore, tasks: TaskList | None = None) -> TaskList:
    """The tasks of ``sweep`` (or of its subset ``tasks``) whose key is not in ``results`` yet,
    in the spec's order, as a lazy sequence (an array of indices: 8 bytes per task)."""
    tasks = tasks if tasks is not None else sweep.tasks
    done = results.keys()
    if not done:
        return tasks
    if isinstance(tasks.indices, range) and tasks.indices == range(len(sweep)):
        keys: Iterator[str] = sweep.keys()
        todo = np.fromiter((i for i, k in enumerate(keys) if k not in done), dtype=np.int64)
    else:
        todo = np.fromiter((i for i in tasks.indices if sweep.task(int(i)).key not in done), dtype=np.int64)
    return TaskList(sweep, todo)


def _prepare_numba() -> float:
    """Load (or compile) the compiled engine's kernels in this process; the seconds it took."""
    from staghunt.engine.numba_engine import prepare

    return float(prepare())


def warm_engine(sweep: Sweep) -> float:
    """Compile (or load) the compiled engine's kernels here, into Numba's on-disk cache, before
    any worker starts, so that no worker compiles; returns the seconds it took."""
    return _prepare_numba() if sweep.spec.engine == "numba" else 0.0


def warm_workers(sweep: Sweep, executor: Any) -> list[float]:
    """Load the compiled kernels on every worker of ``executor`` before the first task (from
    the on-disk cache :func:`warm_engine` filled, when the workers share this file system);
    returns the seconds each worker took (a few tenths when loaded, a minute when compiled)."""
    if sweep.spec.engine != "numba":
        return []
    return executor.warm_workers(_prepare_numba)


def run_sweep(sweep: Sweep, out_dir: str | os.PathLike[str], executor: Any = None,
              listener: SweepListener | None = None,
              task_fn: Callable[[PlanTask], TaskOutcome] = run_plan_task,
              flush_every_s: float = FLUSH_EVERY_S, tasks: TaskList | None = None,
              stores: tuple[ResultStore, ResultStore] | None = None, todo: TaskList | None = None) -> SweepSummary:
    """Run the tasks of ``sweep`` (or its subset ``tasks``) not yet in
    ``out_dir/results.parquet`` on ``executor`` (default: in this process); rows are written as
    tasks complete (at most ``flush_every_s`` late; ``0``: a part per task) and at the end, also
    on ``KeyboardInterrupt`` (re-raised). ``stores`` and ``todo``: what :func:`open_stores`
    and :func:`pending` gave the caller (not computed again)."""
    from staghunt._version import __version__

    executor = executor if executor is not None else InlineExecutor()
    listener = listener or SweepListener()
    out = Path(out_dir)
    results, errors = stores if stores is not None else open_stores(out, sweep)
    tasks = tasks if tasks is not None else sweep.tasks
    todo = todo if todo is not None else pending(sweep, results, tasks)
    summary = SweepSummary(total=len(tasks), skipped=len(tasks) - len(todo))
    listener.started(summary, executor.workers)
    ok_rows: list[dict[str, Any]] = []
    bad_rows: list[dict[str, Any]] = []
    last = time.perf_counter()
    t0 = last

    def flush() -> None:
        nonlocal last
        results.append(ok_rows)
        errors.append(bad_rows)
        ok_rows.clear()
        bad_rows.clear()
        last = time.perf_counter()

    try:
        for index, outcome in run_tasks(task_fn, todo, executor):
            task = todo[index]
            if isinstance(outcome, TaskFailure):
                data = {"status": "error", "message": outcome.message}
            else:
                data = outcome.row
            row = {**task.labels, **data, "key": task.key, "version": __version__}
            if row["status"] == "error":
                bad_rows.append(row)
                summary.failed += 1
            else:
                ok_rows.append(row)
                summary.done += 1
            summary.elapsed_s = time.perf_counter() - t0
            if time.perf_counter() - last >= flush_every_s:
                flush()
            listener.task_finished(summary, row)
    except KeyboardInterrupt:
        summary.interrupted = True
        flush()
        raise
    flush()
    summary.elapsed_s = time.perf_counter() - t0
    return summary


def read_results(out_dir: str | os.PathLike[str]) -> pa.Table:
    """``out_dir/results.parquet`` as one table, each key once (whatever its columns)."""
    import pyarrow.dataset as ds

    from staghunt.study.store import _first_per_key

    path = Path(out_dir) / RESULTS
    if not path.is_dir() or not any(path.glob("part-*.parquet")):
        raise ValueError(f"{path}: no results (run the sweep first)")
    table = ds.dataset(path, format="parquet").to_table()
    return _first_per_key(table)
