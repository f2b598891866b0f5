"""``staghunt plan`` and ``staghunt evaluate``: parse, call the library, report.

Exit codes: ``0`` the paths are feasible; ``3`` they are infeasible (``plan`` still writes
``result.json``, with ``status`` and ``message``); ``2`` bad input; ``130`` interrupted (no partial
``result.json`` is left behind).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from staghunt.cli.common import (  # the shared options, exit codes and error lines
    EXIT_BROKEN_PIPE, EXIT_NEGATIVE, EXIT_OK, PROG, StatusLine, add_certificate_options, add_plots_option,
    add_run_options, add_scenario_argument, add_seed_option, budget_settings, certify_options, check_out_dir,
    checked_request, command, one_line, os_reason, safe_name, say,
)
from staghunt.inputs import clip
from staghunt.io.numbers import number_text


def add_commands(sub: Any) -> None:
    """Register ``plan`` and ``evaluate`` on ``sub`` (from ``add_subparsers``)."""
    from staghunt.solvers import METHODS

    p = command(sub, "plan", cmd_plan, {EXIT_OK: "feasible", EXIT_NEGATIVE: "infeasible (result.json still written)",
                                         EXIT_BROKEN_PIPE: "stdout closed early (result.json already written)"})
    add_scenario_argument(p)
    p.add_argument("--method", choices=list(METHODS), default="game", help="planning method (default: game)")
    add_seed_option(p)
    add_run_options(p, "runs/<scenario>-<method>-s<seed>",
                    "no progress and no summary table; print only the status and where files went")
    add_certificate_options(p, "certify-", skip="the equilibrium certificate that ends the run")
    p.add_argument("--stop", choices=["budget", "certified"], default="budget",
                   help="budget (default): the method's own stopping rule; certified: the game "
                   "stops at the first plan the certificate accepts, leaving later starts unsearched "
                   "(the time to a certified equilibrium, e.g. for re-planning; needs the certificate)")
    add_plots_option(p)
    from staghunt.cli.inspect import add_allocation_option, add_objectives_option

    add_objectives_option(p)
    add_allocation_option(p)
    p.add_argument("--dry-run", action="store_true",
                   help="check the inputs and print the budget and the memory the run needs "
                   "(estimate), without planning or writing anything")

    p = command(sub, "evaluate", cmd_evaluate, {EXIT_OK: "feasible", EXIT_NEGATIVE: "infeasible"})
    add_scenario_argument(p)
    p.add_argument("paths", metavar="PATHS.json", help="the paths to evaluate")


# ------------------------------------------------------------------------------------------------
# Commands
# ------------------------------------------------------------------------------------------------


def cmd_plan(args: argparse.Namespace) -> int:
    """plan paths for a scenario and write DIR/result.json

    Plan paths for the team of SCENARIO, then certify the plan: every UAV's Nash gap by a unilateral
    best-response search (the verdict is printed and stored in result.json; 'staghunt certify'
    re-checks with a larger budget). Budget options default to the scenario's [solver] settings (the
    built-ins carry the paper's 2000 particles, 1500 iterations, K = 10). With objectives (in the
    scenario, or --objectives FILE) it plans the inspection instead: captures, allocation, the
    team's game to the first captures, every UAV timed and checked, the planned coverage;
    DIR/inspection.json and figures. Memory: the run's arrays
    are estimated before anything is allocated (see --dry-run); a run that cannot fit in the
    available memory is refused, one that needs over a quarter of it is announced on stderr.
    """
    from staghunt.api import plan
    from staghunt.io.result_json import write_result
    from staghunt.scenario import load_scenario

    scenario = load_scenario(args.scenario, objectives=args.objectives)
    if scenario.inspection is not None and scenario.inspection.objectives and not args.dry_run:
        from staghunt.cli.inspect import run_inspection_plan

        return run_inspection_plan(scenario, args, certify_options(args))
    settings = budget_settings(scenario, args)
    if args.out is not None:
        out_dir = Path(args.out)
    else:
        out_dir = Path("runs") / f"{safe_name(scenario.name)}-{args.method}-s{args.seed}"
    check_out_dir(out_dir, "result.json")
    certify = certify_options(args)
    # Every check, once, before the search and before the directory is made: the method, seed and
    # settings, whether they can certify, the stopping rule, the engine, the memory the run needs.
    request = checked_request(scenario, settings, args, certify, memory=not args.dry_run)
    if args.dry_run:
        return _dry_run(request, out_dir)
    created = not out_dir.exists()
    try:  # before the search: a plan must never be computed only to be thrown away
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create output directory {str(out_dir)!r}: {os_reason(exc)}") from None

    reporter = ProgressReporter(sys.stderr, quiet=args.quiet)
    try:
        result = plan(request, progress=reporter, certify_progress=reporter.certifying)
    except BaseException:
        if created:  # interrupted or failed: leave no empty directory behind
            try:
                out_dir.rmdir()
            except OSError:
                pass
        raise
    finally:
        reporter.close()
    # Files first, terminal second: a closed stdout (| head) cannot lose the plan or its figures.
    path = write_result(result, out_dir / "result.json")
    figures = [] if args.no_plots else _write_figures(result, out_dir)

    if not args.quiet:
        print(
            f"{scenario.name} / {result.method} / seed {result.seed}: {settings.particles} particles, "
            f"{settings.iterations} iterations, K = {settings.waypoints}; "
            f"{result.evaluations} path evaluations in {result.wall_time_s:.2f} s"
            + (f" (+ {result.compile_time_s:.2f} s engine start-up, one-time compilation included)"
               if result.compile_time_s >= 0.05 else "")
        )
        print(summary_table(result))
        if result.certificate is not None:
            from staghunt.analysis.certify import certificate_table

            c = result.certificate
            print(f"equilibrium certificate ({c.particles} particles x {c.iterations} iterations per "
                  f"UAV, {result.certificate_time_s:.2f} s):")
            print(certificate_table(c))
        if result.details.get("selection"):
            print(equilibria_text(result.details["equilibria"], result.details["selection"], result.uav_names))
    print(f"status: {result.message}")
    if result.certificate is not None:
        print(f"verdict: {result.certificate.verdict}")
    print(f"wrote {path}")
    if figures:
        print(f"wrote {len(figures)} figure(s): {', '.join(str(p) for p in figures)}")
    return EXIT_OK if result.feasible else EXIT_NEGATIVE


def _dry_run(request: Any, out_dir: Path) -> int:
    """``plan --dry-run``: the budget and the memory estimate of the checked ``request``;
    nothing planned, nothing written."""
    from staghunt.budget import available_memory, human

    scenario, settings, certify, engine, est = (request.scenario, request.settings, request.certify,
                                                request.engine, request.estimate)
    N = scenario.n_uavs
    evals = settings.particles * (settings.iterations + 1) * N
    print(f"{scenario.name} / {request.method} / seed {request.seed}, engine {engine.name}: "
          f"{settings.particles} particles x {settings.iterations} iterations, K = {settings.waypoints}, "
          f"{N} UAVs: {evals} path evaluations")
    if certify is not None:
        print(f"certificate: {certify.particles} particles x {certify.iterations} iterations per UAV "
              f"({certify.particles * (certify.iterations + 1) * N} path evaluations)")
    avail, source = available_memory()
    have = "unknown" if avail is None else f"{human(avail)} available ({source}), {est.total / avail:.1%} of it"
    print(f"memory: {est.describe()}; {have}")
    print(f"output: {out_dir / 'result.json'} (not written: dry run)")
    from staghunt.budget import check_memory

    check_memory(est, available=avail, warn=say)  # the run would be refused: exit 2 with the reason
    return EXIT_OK


def cmd_evaluate(args: argparse.Namespace) -> int:
    """cost and check given paths (PATHS.json) in a scenario

    Print the costs and constraint checks of the paths in PATHS.json as JSON. PATHS.json: {"uavs":
    [{"name": optional, "waypoints": [[x, y, h], ...]} or {"path": [[x, y, h], ...] from start to
    goal}, ...]}, h above ground. A result.json written by 'staghunt plan' is accepted as PATHS.json
    too (its paths are evaluated in SCENARIO). A waypoint outside the site box makes the paths
    infeasible.
    """
    from staghunt.io.paths_json import evaluate_paths, read_paths
    from staghunt.io.result_json import dumps_strict
    from staghunt.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    waypoints = read_paths(args.paths, scenario)
    out = evaluate_paths(scenario, waypoints)
    sys.stdout.write(dumps_strict(out))
    return EXIT_OK if out["status"] == "feasible" else EXIT_NEGATIVE


def _write_figures(result: Any, out_dir: Path) -> list[Path]:
    """Figures are a by-product: a failure is a warning, the plan and result.json stand."""
    try:
        from staghunt.plots import save_figures

        return list(save_figures(result, out_dir) or [])
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # missing matplotlib, a plotting bug...: not the user's input
        say(f"{PROG}: warning: figures not written: {clip(one_line(exc))}")
        return []


# ------------------------------------------------------------------------------------------------
# Helpers
# ------------------------------------------------------------------------------------------------


def _g(v: float) -> str:
    return number_text(v, ".6g")


def _ln(v: float) -> str:
    v = float(v)
    if math.isinf(v) and v > 0:
        return "inf"
    if not v > 0:
        return "-"
    return f"{math.log(v):.4f}"


def equilibria_text(equilibria: list[dict[str, Any]], selection: dict[str, Any], names: list[str]) -> str:
    """The equilibria a multi-start search found, one line each, and the selection in plain words."""
    n = len(equilibria)
    lines = [f"equilibria found from {selection['starts']} starts: {n} distinct (certified, merged within "
             "the certificate's tolerance)"]
    width = max([len(e["start"]) for e in equilibria] + [5])
    for e in equilibria:
        mark = "selected" if e["selected"] else ("dominated" if e["dominated"] else "undominated")
        js = "  ".join(f"{nm} {_g(j)}" for nm, j in zip(names, e["J"]))
        lines.append(f"  {e['start']:<{width}}  {js}  (gap {e['certificate']['max_relative_gap']:.2%})  {mark}")
    if n == 0:
        lines.append(f"  none certified: {selection['rule']}")
    elif selection["payoff_dominant"] and n > 1:
        lines.append("  the selected equilibrium is payoff-dominant: it Pareto-dominates every other one found")
    elif n == 1 and selection.get("stopped_at_first_certified"):
        lines.append(f"  --stop certified: the search ended at this first certified equilibrium, after "
                     f"{selection['starts_searched']} of {selection['starts']} starts; no selection among several")
    elif n == 1:
        lines.append("  one equilibrium found: payoff-dominant among those found only trivially")
    else:
        lines.append("  no equilibrium found dominates all the others (no payoff-dominant one among them); "
                     "selected: the least sum_n ln J_n among the undominated ones (eq. 9c)")
    return "\n".join(lines)


def summary_table(result: Any) -> str:
    """Per UAV: J_n, ln J_n, J_s, J_f, path length, min clearance, min separation (waypoints, segments)."""
    header = ("UAV", "J_n", "ln J_n", "J_s", "J_f", "length", "clearance", "sep wp", "sep seg")
    c, m = result.costs, result.metrics
    rows = [header]
    for n, name in enumerate(result.uav_names):
        rows.append(
            (
                name,
                _g(c.total[0, n]),
                _ln(c.total[0, n]),
                _g(c.single[0, n]),
                _g(c.formation[0, n]),
                _g(m.path_length[n]),
                _g(m.min_clearance[n]),
                _g(m.min_separation_waypoints[n]),
                _g(m.min_separation_segments[n]),
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    lines = []
    for r in rows:
        cells = [r[0].ljust(widths[0])] + [v.rjust(w) for v, w in zip(r[1:], widths[1:])]
        lines.append("  ".join(cells).rstrip())
    lines.append("(lengths, clearances and separations in metres; separation limit d_s + 2r = "
                 + ", ".join(_g(v) for v in np.unique(m.separation_limit)) + " m)")
    return "\n".join(lines)


def _clock(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "--:--"
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    mnt, sec = divmod(rem, 60)
    return f"{h}:{mnt:02d}:{sec:02d}" if h else f"{mnt:02d}:{sec:02d}"


class ProgressReporter:
    """The ``progress`` callable handed to :func:`staghunt.plan`.

    On a terminal: a progress bar redrawn in place (at most ~10 times a second). Otherwise: one
    plain line about every 10 % of the iterations. With ``quiet``: nothing.
    """

    def __init__(self, stream: TextIO, quiet: bool = False) -> None:
        self.stream = stream
        self.quiet = quiet
        self.line = StatusLine(stream)
        self.start = time.perf_counter()

    def __call__(self, iteration: int, total: int, best_cost: np.ndarray) -> None:
        if self.quiet or total <= 0:
            return
        elapsed = time.perf_counter() - self.start
        eta = elapsed / iteration * (total - iteration) if iteration > 0 else math.inf
        frac = iteration / total
        best = " ".join(_g(v) for v in np.atleast_1d(best_cost))
        if self.line.tty:
            filled = int(round(frac * 20))
            self.line.draw(
                f"[{'#' * filled}{'.' * (20 - filled)}] {iteration}/{total} {frac:4.0%} "
                f"{_clock(elapsed)} ETA {_clock(eta)}  best J: {best}",
                force=iteration >= total,
            )
            return
        step = max(1, math.ceil(total / 10))
        if iteration % step and iteration != total:
            return
        self.line.say(
            f"{PROG}: iteration {iteration}/{total} ({frac:.0%}), elapsed {elapsed:.1f} s, "
            f"ETA {eta:.1f} s, best J: {best}"
        )

    def certifying(self, uav: int, n_uavs: int, iteration: int, total: int) -> None:
        """Progress of the certificate's searches (on a terminal only; the table follows)."""
        if not self.quiet and self.line.tty:
            self.line.draw(f"{PROG}: certifying UAV {uav + 1}/{n_uavs}, iteration {iteration}/{total}",
                           force=iteration >= total)

    def close(self) -> None:
        """End the bar's line (also when the run was interrupted)."""
        self.line.close(keep=True)
