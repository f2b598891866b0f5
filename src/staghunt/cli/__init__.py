"""The ``staghunt`` command line: parse, call the library, report. No planning logic lives here.

One module per group of commands: :mod:`~staghunt.cli.scenarios` (scenarios, show, methods,
schema), :mod:`~staghunt.cli.plan` (plan, evaluate), :mod:`~staghunt.cli.inspect` (cameras, inspect, and
plan's inspections), :mod:`~staghunt.cli.analysis` (compare,
certify), :mod:`~staghunt.cli.missions` (export), :mod:`~staghunt.cli.fly` (fly),
:mod:`~staghunt.cli.sweep` (sweep);
:mod:`~staghunt.cli.common` holds what they share (the parser, option blocks), with the options'
types in :mod:`~staghunt.cli.argtypes`, exit codes and error lines in :mod:`~staghunt.cli.wording`,
output path checks in :mod:`~staghunt.cli.paths` and the terminal status line in
:mod:`~staghunt.cli.status` (all re-exported by ``common``). A command's help is its handler's
docstring, its exit codes listed after its options (:func:`~staghunt.cli.common.command`).

Exit codes:

- ``0``: success (for ``plan`` and ``evaluate``: the paths are feasible);
- ``3``: the command ran but the answer is no (``plan`` / ``evaluate``: the paths are infeasible,
  ``result.json`` is still written; ``certify``: the plan is no equilibrium);
- ``2``: bad input of any kind (scenario, options, files, output directory), reported as one line
  ``staghunt: error: ...`` on stderr;
- ``130``: interrupted (Ctrl-C); no partial ``result.json`` is left behind;
- ``141``: stdout was closed early (``staghunt plan ... | head -1``): the files were already
  written, the rest of the report is dropped quietly (the code of a process ended by SIGPIPE);
- ``1``: an internal error (a bug), reported as one line; ``STAGHUNT_DEBUG=1`` shows the traceback.

Whatever the input, no Python traceback and no NumPy warning reaches the terminal: input is
validated (files read once, sizes, magnitudes, memory budgets) before any search starts.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from typing import Sequence

from staghunt.cli import analysis, fly, inspect, missions, plan, scenarios, sweep
from staghunt.cli.common import (
    EXIT_BROKEN_PIPE, EXIT_INTERRUPTED, EXIT_USAGE, PROG, Parser, UsageError, error, one_line, say,
)
from staghunt.inputs import clip
from staghunt.cli.plan import ProgressReporter, summary_table

__all__ = ["ProgressReporter", "build_parser", "main", "summary_table"]


def build_parser() -> argparse.ArgumentParser:
    from staghunt._version import __version__

    parser = Parser(
        prog=PROG,
        description="Cooperative multi-UAV path planning as a stag hunt game (game-based SPSO).",
        epilog="Exit codes: 0 feasible/success, 3 the answer is no (infeasible plan, result still "
        "written; no equilibrium; export refused), 2 bad input, 130 interrupted, 141 stdout closed early "
        "(files already written), 1 internal error.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    scenarios.add_commands(sub)
    plan.add_commands(sub)
    inspect.add_commands(sub)
    analysis.add_commands(sub)
    missions.add_commands(sub)
    fly.add_commands(sub)
    sweep.add_commands(sub)
    return parser


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush cannot fail again (the Python
    documentation's recipe for SIGPIPE / BrokenPipeError)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    import numpy as np

    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            # Validated extremes may still reach inf in NumPy: costs are then inf (infeasible),
            # never a warning on the terminal; library warnings are for developers
            # (STAGHUNT_DEBUG=1 shows them).
            if not os.environ.get("STAGHUNT_DEBUG"):
                warnings.simplefilter("ignore")
            return _main(argv)
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        say(f"{PROG}: interrupted")
        return EXIT_INTERRUPTED


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(missions.join_negative_values(sys.argv[1:] if argv is None else argv))
    except UsageError as exc:
        return error(one_line(exc))
    except SystemExit as exc:  # --help, --version
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else EXIT_USAGE)
    try:
        code = int(args.func(args))
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's final flush
        return code
    except BrokenPipeError:
        raise
    except (ValueError, OSError, OverflowError) as exc:  # ScenarioError and MemoryBudgetError are ValueErrors
        return error(one_line(exc, args.command))
    except RecursionError:
        return error("input nested too deeply")
    except MemoryError as exc:  # not a budget: every budget is estimated and refused before it runs
        if os.environ.get("STAGHUNT_DEBUG"):
            raise
        detail = f" ({clip(one_line(exc))})" if str(exc) else ""
        return error(f"out of memory{detail}, although the inputs were checked; please report it "
                     "(STAGHUNT_DEBUG=1 shows where)")
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # a bug: one line, never a traceback (STAGHUNT_DEBUG=1 shows it)
        if os.environ.get("STAGHUNT_DEBUG"):
            raise
        say(f"{PROG}: internal error ({type(exc).__name__}): {clip(str(exc))}; "
            "please report it (STAGHUNT_DEBUG=1 shows the traceback)")
        return 1
