"""The ``staghunt compare`` and ``staghunt certify`` subcommands (parse, call the library, report).

:func:`add_commands` registers both on the ``staghunt`` parser's subparsers; each handler returns
the exit code:

- ``compare``: ``0`` every run finished (whatever the plans' outcomes); ``2`` bad input;
  ``130`` interrupted (finished runs stay on disk; the same command resumes).
- ``certify``: ``0`` the plan is an epsilon-equilibrium; ``3`` it is not (a UAV would deviate,
  or the plan is infeasible); ``2`` bad input; ``130`` interrupted.

Bad input is reported as one line ``staghunt: error: ...`` on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from staghunt.analysis.certify import certificate_table, certificate_to_dict, certify_result_file
from staghunt.analysis.compare import (
    DEFAULT_METHODS, CompareListener, RunRecord, certificate_file, check_compare, format_report, parse_methods,
    parse_seeds, run_compare, run_file,
)
from staghunt.cli.common import (  # the shared options, exit codes and error lines
    EXIT_INTERRUPTED, EXIT_NEGATIVE, EXIT_OK, PROG, StatusLine, add_certificate_options,
    add_engine_options, add_quiet_option, add_run_options, add_scenario_argument, budget_settings,
    add_cluster_options, certify_options, check_out_dir, check_path_lengths, command, engine_kwargs, error,
    int_at_least, one_line, os_reason, path_argument, safe_name, say,
)
from staghunt.io.atomic import check_replaceable
from staghunt.io.numbers import number_text
from staghunt.io.result_json import read_result, write_json_atomic
from staghunt.scenario import load_scenario
from staghunt.study.executor import make_executor, runs_here




def add_commands(subparsers: Any) -> None:
    """Register ``compare`` and ``certify`` on ``subparsers`` (from ``add_subparsers``)."""
    p = command(subparsers, "compare", cmd_compare, {EXIT_OK: "done", EXIT_INTERRUPTED: "interrupted (finished runs kept)"})
    add_scenario_argument(p)
    p.add_argument("--methods", metavar="LIST", default=",".join(DEFAULT_METHODS),
                   help=f"comma-separated methods (default: {','.join(DEFAULT_METHODS)})")
    p.add_argument("--seeds", metavar="SEEDS", default="1-10", help="seeds, e.g. 1-10, 1,4,7 or 1-3,8 (default: 1-10)")
    add_run_options(p, "runs/<scenario>-compare")
    add_certificate_options(p, "certify-", skip="the equilibrium certificates")
    p.add_argument("--no-figure", action="store_true", help="do not draw DIR/compare.png")
    add_cluster_options(p, "runs", "one run after the other in this process; see 'staghunt sweep'")

    p = command(subparsers, "certify", cmd_certify, {
        EXIT_OK: "epsilon-equilibrium", EXIT_NEGATIVE: "not one (a UAV would deviate, or the plan is infeasible)"})
    p.add_argument("result", metavar="RESULT.json", help="a result.json written by 'staghunt plan'")
    add_certificate_options(p, "")
    p.add_argument("--seed", type=int_at_least(0), metavar="N", help="base seed of the searches (default: the plan's seed)")
    p.add_argument("--out", metavar="FILE", type=path_argument, help="also write the certificate as JSON to FILE")
    add_engine_options(p)
    add_quiet_option(p)


# ------------------------------------------------------------------------------------------------
# Progress
# ------------------------------------------------------------------------------------------------


def _g(v: float) -> str:
    return number_text(v, ".4g")


class _CompareProgress(CompareListener):
    """Progress of ``compare`` on stderr: one line per run; on a terminal also a live status line."""

    def __init__(self, stream: TextIO, quiet: bool) -> None:
        self.line = StatusLine(stream)
        self.quiet = quiet
        self.prefix = ""
        self.t0 = time.perf_counter()

    def run_started(self, index: int, total: int, method: str, seed: int) -> None:
        self.prefix = f"{PROG}: [{index}/{total}] {method} seed {seed}"
        self.t0 = time.perf_counter()
        if not self.quiet and not self.line.tty:
            self.line.say(f"{self.prefix}: planning")

    def plan_progress(self, iteration: int, total: int, best_cost: np.ndarray) -> None:
        if not self.quiet:
            best = " ".join(_g(v) for v in np.atleast_1d(best_cost))
            self.line.draw(f"{self.prefix}: planning, iteration {iteration}/{total}, best {best}",
                           force=iteration == total)

    def certify_started(self, index: int, total: int, method: str, seed: int) -> None:
        prefix = f"{PROG}: [{index}/{total}] {method} seed {seed}"
        if prefix != self.prefix:  # planned earlier, certified now
            self.prefix = prefix
            self.t0 = time.perf_counter()
        if not self.quiet and not self.line.tty:
            self.line.say(f"{self.prefix}: certifying")

    def certify_progress(self, uav: int, n_uavs: int, iteration: int, total: int) -> None:
        if not self.quiet:
            self.line.draw(f"{self.prefix}: certifying UAV {uav + 1}/{n_uavs}, iteration {iteration}/{total}")

    def run_finished(self, index: int, total: int, record: RunRecord, resumed: bool) -> None:
        if self.quiet:
            return
        prefix = f"{PROG}: [{index}/{total}] {record.method} seed {record.seed}"
        state = "feasible" if record.feasible else "INFEASIBLE"
        gaps = record.nash_gaps()
        gap = "" if gaps is None else f", max Nash gap {_pct(float(np.max(gaps[1])))}"
        how = "found on disk" if resumed else f"{time.perf_counter() - self.t0:.1f} s"
        self.line.say(f"{prefix}: {state}, J_n = {' '.join(_g(v) for v in record.J)}{gap} ({how})")

    def close(self) -> None:
        self.line.close()


def _pct(v: float) -> str:
    return "inf" if math.isinf(v) else f"{v:.2%}"


# ------------------------------------------------------------------------------------------------
# Handlers
# ------------------------------------------------------------------------------------------------


def cmd_compare(args: argparse.Namespace) -> int:
    """run every method on every seed; table, dominance, Nash gaps, figure

    Plan SCENARIO with every method on every seed with the same budget, re-score every plan with the
    same J_n, test whether the game allocation Pareto-dominates each other method's (per seed),
    certify every plan (Nash gaps), and put the paper's Fig. 8 numbers next to ours. Writes
    DIR/runs/<method>-s<seed>.json (+ .certify.json) as each run finishes, DIR/compare.json,
    DIR/compare.csv and DIR/compare.png. Runs already in DIR are not planned again, so an
    interrupted comparison resumes where it stopped. Budget: every method spends particles x
    (iterations + 1) x N single-UAV path evaluations.
    """
    workers = args.workers if args.workers is not None else 1
    try:
        methods = parse_methods(args.methods)
        seeds = parse_seeds(args.seeds)
        scenario = load_scenario(args.scenario)
        out = Path(args.out) if args.out is not None else Path("runs") / f"{safe_name(scenario.name)}-compare"
        check_out_dir(out)
        # Every run must be possible (and fit in memory) before the first starts; on a cluster
        # each run takes one thread (the workers are the parallelism).
        request = check_compare(scenario, methods, seeds, budget_settings(scenario, args), certify_options(args),
                                engine=args.engine, threads=args.threads if runs_here(args.scheduler, workers) else 1,
                                warn=say)
    except (ValueError, OSError) as exc:
        return error(one_line(exc, "compare"))
    settings, certify = request.settings, request.certify
    total = len(methods) * len(seeds)
    if not args.quiet:
        cert = "no certificates" if certify is None else (
            f"certificates {certify.particles} x {certify.iterations} per UAV")
        print(
            f"{PROG}: comparing {', '.join(methods)} on {scenario.name}, seeds "
            f"{args.seeds} ({total} runs): {settings.particles} particles x {settings.iterations} "
            f"iterations, K = {settings.waypoints}; {cert}; writing to {out}",
            file=sys.stderr,
        )
    try:
        executor = make_executor(args.scheduler, workers, args.connect_timeout)
    except ValueError as exc:  # ClusterError: the scheduler cannot be reached
        return error(one_line(exc))
    if not executor.local:  # compile once here, into the on-disk cache the workers load
        request.runs[(methods[0], seeds[0])].engine.prepare()
    listener = _CompareProgress(sys.stderr, args.quiet)
    try:
        report = run_compare(request, out, listener=listener, executor=executor)
    except KeyboardInterrupt:
        executor.close()
        listener.close()
        done = _count_done(out, methods, seeds, certify is not None)
        print(
            f"{PROG}: interrupted: {done} of {total} runs finished and kept in {out} "
            "(compare.json and compare.csv cover them); run the same command again to resume",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    except (ValueError, OSError) as exc:
        executor.close()
        listener.close()
        return error(one_line(exc, "compare"))
    executor.close()
    listener.close()
    print(format_report(report))
    written = [out / "compare.json", out / "compare.csv"]
    if not args.no_figure:
        try:
            from staghunt.plots.compare import save_compare_figure

            written.append(save_compare_figure(report, out / "compare.png"))
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # a plotting failure must not lose the comparison
            print(f"{PROG}: warning: figure not written: {' '.join(str(exc).split())}", file=sys.stderr)
    runs = f"{total} run" + ("s" if total != 1 else "")
    print(f"wrote {', '.join(str(p) for p in written)} and {runs} in {out / 'runs'}")
    return EXIT_OK


def _count_done(out: Path, methods: tuple[str, ...], seeds: tuple[int, ...], certified: bool) -> int:
    return sum(
        run_file(out, m, s).exists() and (not certified or certificate_file(out, m, s).exists())
        for s in seeds for m in methods
    )


def cmd_certify(args: argparse.Namespace) -> int:
    """equilibrium certificate of a plan: each UAV's Nash gap

    For every UAV of the plan in RESULT.json, fix the others' paths and re-optimise its own path on
    its own J_n (single-player SPSO, warm-started from its current path, seeded). Its Nash gap is
    the best unilateral improvement found, absolute and relative to its J_n. The plan is reported as
    an epsilon-equilibrium when every relative gap is <= epsilon; otherwise the UAV that would
    deviate is named. The search is heuristic: a gap is a lower bound on the true one.
    """
    line = StatusLine(sys.stderr)

    def progress(uav: int, n_uavs: int, iteration: int, total: int) -> None:
        if not args.quiet:
            line.draw(f"{PROG}: certifying UAV {uav + 1}/{n_uavs}, iteration {iteration}/{total}",
                      force=iteration == total)

    try:
        if args.out is not None:
            target = Path(args.out)
            check_path_lengths(target, "--out")
            if target.is_dir():
                raise ValueError(f"--out {str(target)!r} is a directory; give a file name")
            check_replaceable(target)  # before the search: never replace a device or a FIFO
            if not target.parent.is_dir() and str(target.parent):
                raise ValueError(f"--out {str(target)!r}: no such directory {str(target.parent)!r}")
        data = read_result(args.result)  # once: RESULT.json may be a pipe (<(cat result.json))
        seed = args.seed if args.seed is not None else int(data.get("seed", 0))
        cert, data = certify_result_file(args.result, data=data, warn=say, particles=args.particles,
                                         iterations=args.iterations, seed=seed,
                                         epsilon=args.epsilon, progress=progress,
                                         **engine_kwargs(args))
    except KeyboardInterrupt:
        line.close()
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (ValueError, OSError) as exc:
        line.close()
        return error(one_line(exc, "certify"))
    line.close()
    print(
        f"{args.result}: method {data.get('method')}, seed {data.get('seed')}, scenario "
        f"{data['scenario'].get('name')}; best-response search per UAV: {cert.particles} particles "
        f"x {cert.iterations} iterations, seed {cert.seed}"
    )
    print(certificate_table(cert))
    print(f"verdict: {cert.verdict}")
    for n in cert.notes:
        print(f"note: {n}")
    if args.out is not None:
        try:
            path = write_json_atomic(certificate_to_dict(cert), args.out)
        except OSError as exc:
            return error(f"cannot write {args.out!r}: {os_reason(exc)}")
        print(f"wrote {path}")
    return EXIT_OK if cert.is_equilibrium else EXIT_NEGATIVE
