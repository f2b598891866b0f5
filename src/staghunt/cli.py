"""The ``staghunt`` command line: parse, call the library, report. No planning logic lives here.

Exit codes:

- ``0``: success (for ``plan`` and ``evaluate``: the paths are feasible);
- ``3``: ``plan`` / ``evaluate`` ran but the paths are infeasible (``result.json`` is still
  written, with ``status`` and ``message``);
- ``2``: bad input of any kind (scenario, options, files, output directory), reported as one line
  ``staghunt: error: ...`` on stderr;
- ``130``: interrupted (Ctrl-C); no partial ``result.json`` is left behind.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any, Sequence, TextIO

import numpy as np

from staghunt.cli_analysis import add_commands
from staghunt.cli_support import (
    EXIT_INTERRUPTED,
    EXIT_NEGATIVE,
    EXIT_OK,
    EXIT_USAGE,
    PROG,
    StatusLine,
    add_engine_options,
    engine_kwargs,
    error,
    int_at_least,
    os_reason,
    safe_name,
)



class UsageError(Exception):
    """Bad command-line input (reported as one line, exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are raised (one line), not printed with the usage."""

    def error(self, message: str) -> Any:  # type: ignore[override]
        raise UsageError(f"{message} (see '{self.prog} --help')")


# ------------------------------------------------------------------------------------------------
# Parser
# ------------------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    from staghunt import __version__
    from staghunt.solvers import METHODS

    parser = _Parser(
        prog=PROG,
        description="Cooperative multi-UAV path planning as a stag hunt game (game-based SPSO).",
        epilog="Exit codes: 0 feasible/success, 3 infeasible plan (result still written), "
        "2 bad input, 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("scenarios", help="list the built-in scenarios")
    p.set_defaults(func=cmd_scenarios)

    p = sub.add_parser("show", help="print a validated scenario as JSON")
    p.add_argument("scenario", metavar="SCENARIO", help="built-in name or path to a .toml file")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser("methods", help="list the planning methods")
    p.set_defaults(func=cmd_methods)

    p = sub.add_parser(
        "plan",
        help="plan paths for a scenario and write DIR/result.json",
        description="Plan paths for the team of SCENARIO. Budget options default to the "
        "scenario's [solver] settings (the built-ins carry the paper's 2000 particles, "
        "1500 iterations, K = 10).",
        epilog="Exit codes: 0 feasible, 3 infeasible (result.json still written), 2 bad input, "
        "130 interrupted.",
    )
    p.add_argument("scenario", metavar="SCENARIO", help="built-in name or path to a .toml file")
    p.add_argument("--method", choices=list(METHODS), default="game", help="planning method (default: game)")
    p.add_argument("--seed", type=int_at_least(0), default=0, help="random seed (default: 0)")
    p.add_argument("--particles", type=int_at_least(1), help="particles per swarm")
    p.add_argument("--iterations", type=int_at_least(0), help="swarm iterations")
    p.add_argument("--waypoints", type=int_at_least(1), help="free waypoints K per UAV")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="output directory (default: runs/<scenario>-<method>-s<seed>)",
    )
    add_engine_options(p)
    p.add_argument("--no-plots", action="store_true", help="do not write figures")
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress and no summary table; print only the status and where files went",
    )
    p.set_defaults(func=cmd_plan)

    p = sub.add_parser(
        "evaluate",
        help="cost and check given paths (PATHS.json) in a scenario",
        description="Print the costs and constraint checks of the paths in PATHS.json as JSON. "
        'PATHS.json: {"uavs": [{"name": optional, "waypoints": [[x, y, h], ...]} or '
        '{"path": [[x, y, h], ...] from start to goal}, ...]}, h above ground.',
        epilog="Exit codes: 0 feasible, 3 infeasible, 2 bad input.",
    )
    p.add_argument("scenario", metavar="SCENARIO", help="built-in name or path to a .toml file")
    p.add_argument("paths", metavar="PATHS.json", help="the paths to evaluate")
    p.set_defaults(func=cmd_evaluate)
    add_commands(sub)
    return parser


# ------------------------------------------------------------------------------------------------
# Commands
# ------------------------------------------------------------------------------------------------


def cmd_scenarios(args: argparse.Namespace) -> int:
    from staghunt.scenario import builtin_names, load_scenario

    names = builtin_names()
    width = max((len(n) for n in names), default=0)
    for name in names:
        s = load_scenario(name)
        what = f"{s.n_uavs} UAVs, {len(s.world.cylinders)} obstacles"
        desc = " ".join(s.description.split())
        print(f"{name:<{width}}  {what}" + (f"  {desc}" if desc else ""))
    return EXIT_OK


def cmd_show(args: argparse.Namespace) -> int:
    from staghunt.scenario import load_scenario, scenario_to_dict

    scenario = load_scenario(args.scenario)
    print(json.dumps(scenario_to_dict(scenario), indent=2, allow_nan=False, ensure_ascii=False))
    return EXIT_OK


def cmd_methods(args: argparse.Namespace) -> int:
    from staghunt.solvers import DESCRIPTIONS, METHODS

    width = max((len(n) for n in METHODS), default=0)
    for name in METHODS:
        print(f"{name:<{width}}  {DESCRIPTIONS.get(name, '')}")
    return EXIT_OK


def cmd_plan(args: argparse.Namespace) -> int:
    from staghunt.api import plan, validate_settings
    from staghunt.io.result_json import write_result
    from staghunt.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    settings = scenario.solver.with_(
        particles=args.particles, iterations=args.iterations, waypoints=args.waypoints
    )
    validate_settings(settings)
    if args.out is not None:
        out_dir = Path(args.out)
    else:
        out_dir = Path("runs") / f"{safe_name(scenario.name)}-{args.method}-s{args.seed}"
    check_out_dir(out_dir)

    reporter = ProgressReporter(sys.stderr, quiet=args.quiet)
    try:
        result = plan(scenario, args.method, args.seed, settings, reporter, **engine_kwargs(args))
    finally:
        reporter.close()

    if not args.quiet:
        print(
            f"{scenario.name} / {result.method} / seed {result.seed}: {settings.particles} particles, "
            f"{settings.iterations} iterations, K = {settings.waypoints}; "
            f"{result.evaluations} path evaluations in {result.wall_time_s:.2f} s"
        )
        print(summary_table(result))
    print(f"status: {result.message}")

    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create output directory {str(out_dir)!r}: {os_reason(exc)}") from None
    path = write_result(result, out_dir / "result.json")
    print(f"wrote {path}")

    if not args.no_plots:
        _write_figures(result, out_dir)
    return EXIT_OK if result.feasible else EXIT_NEGATIVE


def cmd_evaluate(args: argparse.Namespace) -> int:
    from staghunt.io.paths_json import evaluate_paths, read_paths
    from staghunt.io.result_json import dumps_strict
    from staghunt.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    waypoints = read_paths(args.paths, scenario)
    out = evaluate_paths(scenario, waypoints)
    sys.stdout.write(dumps_strict(out))
    return EXIT_OK if out["status"] == "feasible" else EXIT_NEGATIVE


def _write_figures(result: Any, out_dir: Path) -> None:
    """Figures are a by-product: a failure is a warning, the plan and result.json stand."""
    try:
        from staghunt.plots import save_figures

        written = save_figures(result, out_dir)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # missing matplotlib, a plotting bug...: not the user's input
        print(f"{PROG}: warning: figures not written: {_one_line(exc)}", file=sys.stderr)
        return
    if written:
        print(f"wrote {len(written)} figure(s): {', '.join(str(p) for p in written)}")


# ------------------------------------------------------------------------------------------------
# Helpers
# ------------------------------------------------------------------------------------------------


def check_out_dir(out_dir: Path) -> None:
    """Raise ``ValueError`` if ``out_dir`` cannot hold ``result.json`` (checked before planning)."""
    label = f"output directory {str(out_dir)!r}"
    if out_dir.exists():
        if not out_dir.is_dir():
            raise ValueError(f"{label} exists and is not a directory")
        if not os.access(out_dir, os.W_OK | os.X_OK):
            raise ValueError(f"{label} is not writable")
        if (out_dir / "result.json").is_dir():
            raise ValueError(f"{label} holds a directory named result.json")
        return
    parent = out_dir.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{label} cannot be created: {str(parent)!r} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{label} cannot be created: {str(parent)!r} is not writable")


def _g(v: float) -> str:
    v = float(v)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.6g}"


def _ln(v: float) -> str:
    v = float(v)
    if math.isinf(v) and v > 0:
        return "inf"
    if not v > 0:
        return "-"
    return f"{math.log(v):.4f}"


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
        self.stream.write(
            f"{PROG}: iteration {iteration}/{total} ({frac:.0%}), elapsed {elapsed:.1f} s, "
            f"ETA {eta:.1f} s, best J: {best}\n"
        )
        self.stream.flush()

    def close(self) -> None:
        """End the bar's line (also when the run was interrupted)."""
        self.line.close(keep=True)


def _one_line(exc: BaseException) -> str:
    text = os_reason(exc) if isinstance(exc, OSError) else str(exc)
    text = " ".join(text.split()) or type(exc).__name__
    return text


# ------------------------------------------------------------------------------------------------
# Entry point
# ------------------------------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    try:
        parser = build_parser()
        try:
            args = parser.parse_args(argv)
        except UsageError as exc:
            return error(_one_line(exc))
        except SystemExit as exc:  # --help, --version
            return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else EXIT_USAGE)
        try:
            return int(args.func(args))
        except BrokenPipeError:
            # The reader went away (``staghunt show x | head``): stop quietly.
            try:
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, sys.stdout.fileno())
            except (OSError, ValueError, AttributeError):
                pass
            return 1
        except (ValueError, OSError) as exc:  # ScenarioError is a ValueError
            return error(_one_line(exc))
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
