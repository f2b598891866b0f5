"""``staghunt sweep``: many plans at once, on Dask (parse, call :mod:`staghunt.study`, report).

Exit codes: ``0`` every task of the spec is finished; ``3`` some tasks failed (recorded in
DIR/errors.parquet, run again by the same command); ``2`` bad input (the spec, an override that
makes a scenario invalid, a spec of more than ``MAX_TASKS`` tasks, the output directory, an
unreachable scheduler), reported before any cluster starts (the scheduler: as soon as it is
found unreachable, after the line giving the number of tasks); ``130`` interrupted (finished
tasks are kept; the same command resumes).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from staghunt.cli.common import (
    EXIT_INTERRUPTED, EXIT_NEGATIVE, EXIT_OK, EXIT_USAGE, PROG, StatusLine, add_cluster_options, add_out_option,
    add_quiet_option, check_out_dir, command, error, number_between, one_line, path_argument, say,
)


def add_commands(sub: Any) -> None:
    """Register ``sweep`` on ``sub`` (from ``add_subparsers``)."""
    from staghunt.study.sweep import FLUSH_EVERY_S

    p = command(sub, "sweep", cmd_sweep, {
        EXIT_OK: "all tasks finished", EXIT_NEGATIVE: "some tasks failed (DIR/errors.parquet; rerun to retry them)",
        EXIT_USAGE: "bad input or unreachable scheduler", EXIT_INTERRUPTED: "interrupted (finished tasks kept)"})
    p.add_argument("spec", metavar="SPEC.toml", type=path_argument, help="the sweep spec")
    add_out_option(p, "runs/<spec name>-sweep")
    add_cluster_options(p, "tasks", "one per core; 1 runs in this process")
    p.add_argument("--flush-every", type=number_between(0, 3600, "seconds"), metavar="S", default=FLUSH_EVERY_S,
                   help=f"write finished rows at most S seconds after their task (0: after every task; "
                   f"default: {FLUSH_EVERY_S:g})")
    p.add_argument("--figures-only", action="store_true", help="only draw the figures from DIR/results.parquet")
    p.add_argument("--no-figures", action="store_true", help="do not draw the figures")
    add_quiet_option(p)


class _Progress:
    """The terminal status line (``[done/total]``, rate, ETA) and one line per failure."""

    def __init__(self, quiet: bool) -> None:
        from staghunt.study.sweep import SweepListener

        outer = self

        class Listener(SweepListener):
            def started(self, summary: Any, workers: int) -> None:
                outer.todo = summary.total - summary.skipped
                outer.t0 = time.perf_counter()

            def task_finished(self, summary: Any, row: dict[str, Any]) -> None:
                outer.finished(summary, row)

        self.listener = Listener()
        self.line = StatusLine(sys.stderr)
        self.quiet = quiet
        self.todo = 0
        self.t0 = time.perf_counter()
        self.last_plain = 0.0

    def finished(self, summary: Any, row: dict[str, Any]) -> None:
        if row.get("status") == "error" and not self.quiet:
            self.line.say(f"{PROG}: task failed ({row.get('scenario')}, {row.get('method')}, seed "
                          f"{row.get('seed')}): {row.get('message')}")
        if self.quiet:
            return
        n = summary.done + summary.failed
        rate = n / max(time.perf_counter() - self.t0, 1e-9)
        eta = (self.todo - n) / rate if rate > 0 else float("inf")
        text = (f"{PROG}: sweep [{n}/{self.todo}] {summary.done} done, {summary.failed} failed, "
                f"{rate * 60:.1f} tasks/min, about {eta:.0f} s left")
        if self.line.tty:
            self.line.draw(text, force=n == self.todo)
        elif time.perf_counter() - self.last_plain >= 10 or n == self.todo:
            self.last_plain = time.perf_counter()
            say(text)

    def close(self) -> None:
        self.line.close()


def cmd_sweep(args: argparse.Namespace) -> int:
    """run a grid of plans (scenarios x overrides x methods x seeds) on Dask

    Plan and certify every task of SPEC.toml (scenarios, a grid of overrides, methods, seeds; see
    docs/sweep.md and 'staghunt schema --sweep') on a Dask cluster: by default a local one with one
    worker process per core, or the one at --scheduler. Rows go to DIR/results.parquet (a Parquet
    dataset, one row per task) as tasks finish; tasks already there are skipped, so the same command
    resumes. Figures: DIR/beta_tradeoff.png and DIR/convergence.png.
    """
    from staghunt.study.spec import expand, load_spec
    from staghunt.study.sweep import open_stores, pending, run_sweep, warm_engine, warm_workers

    try:
        spec, base = load_spec(args.spec)
        sweep = expand(spec, base)
        out = Path(args.out) if args.out is not None else Path("runs") / f"{Path(args.spec).stem}-sweep"
        check_out_dir(out)
        if args.figures_only:
            return _figures(out, quiet=args.quiet, required=True)
        stores = open_stores(out, sweep)
        todo = pending(sweep, stores[0])
    except (ValueError, OSError) as exc:
        return error(one_line(exc))
    if not args.quiet:  # before any work: the size of the study and what is left of it
        say(f"{PROG}: sweep {args.spec}: {len(sweep):,} tasks, {len(sweep) - len(todo):,} already "
            f"in {out / 'results.parquet'}, {len(todo):,} to run")
    executor = None
    if len(todo):
        from staghunt.study.executor import ClusterError, make_executor

        try:
            executor = make_executor(args.scheduler, args.workers, args.connect_timeout)
        except ClusterError as exc:
            return error(one_line(exc))
    if executor is not None:
        try:  # before any task: compiled once here, loaded from Numba's on-disk cache by the workers
            compile_s = warm_engine(sweep)
            loaded = warm_workers(sweep, executor)
        except BaseException:
            executor.close()
            raise
        if compile_s > 1 and not args.quiet:
            say(f"{PROG}: compiled engine ready in {compile_s:.1f} s (cached for every worker)")
        if loaded and not args.quiet:
            say(f"{PROG}: workers loaded the compiled engine in at most {max(loaded):.1f} s")
        progress = _Progress(args.quiet)
        try:
            if not args.quiet:
                say(f"{PROG}: running on {executor.description} ({executor.workers} worker"
                    f"{'s' if executor.workers != 1 else ''})")
            summary = run_sweep(sweep, out, executor, progress.listener, flush_every_s=args.flush_every,
                                stores=stores, todo=todo)
        except KeyboardInterrupt:
            progress.close()
            say(f"{PROG}: interrupted: finished tasks are kept in {out / 'results.parquet'}; "
                "run the same command again to resume")
            return EXIT_INTERRUPTED
        finally:
            progress.close()
            executor.close()
        if not args.quiet:
            say(f"{PROG}: sweep done: {summary.done} tasks finished, {summary.skipped} skipped (already done), "
                f"{summary.failed} failed; {summary.elapsed_s:.1f} s, {summary.throughput * 60:.1f} tasks/min")
        failed = summary.failed
    else:
        failed = 0
    if not args.no_figures:
        _figures(out, quiet=args.quiet, required=False)
    if failed:
        say(f"{PROG}: {failed} task{'s' if failed != 1 else ''} failed (see {out / 'errors.parquet'}); "
            "run the same command again to retry them")
        return EXIT_NEGATIVE
    return EXIT_OK


def _figures(out: Path, quiet: bool, required: bool) -> int:
    """Draw the study figures into ``out``; a failure is a warning unless ``required``."""
    try:
        from staghunt.plots.study import save_study_figures
        from staghunt.study.sweep import read_results

        written = save_study_figures(read_results(out), out)
    except KeyboardInterrupt:
        raise
    except Exception as exc:
        if required:
            return error(one_line(exc))
        say(f"{PROG}: warning: figures not written: {one_line(exc)}")
        return EXIT_OK
    if written and not quiet:
        print(f"wrote {', '.join(str(p) for p in written)}")
    return EXIT_OK
