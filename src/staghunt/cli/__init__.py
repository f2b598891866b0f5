"""The ``staghunt`` command line: parse, call the library, report. No planning logic lives here.

One module per group of commands: :mod:`~staghunt.cli.scenarios` (scenarios, show, methods,
schema), :mod:`~staghunt.cli.plan` (plan, evaluate), :mod:`~staghunt.cli.analysis` (compare,
certify); :mod:`~staghunt.cli.common` holds what they share (exit codes, option blocks, error
lines, the terminal status line).

Exit codes:

- ``0``: success (for ``plan`` and ``evaluate``: the paths are feasible);
- ``3``: the command ran but the answer is no (``plan`` / ``evaluate``: the paths are infeasible,
  ``result.json`` is still written; ``certify``: the plan is no equilibrium);
- ``2``: bad input of any kind (scenario, options, files, output directory), reported as one line
  ``staghunt: error: ...`` on stderr;
- ``130``: interrupted (Ctrl-C); no partial ``result.json`` is left behind.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Sequence

from staghunt.cli import analysis, plan, scenarios
from staghunt.cli.common import EXIT_INTERRUPTED, EXIT_USAGE, PROG, Parser, UsageError, error, one_line
from staghunt.cli.plan import ProgressReporter, summary_table

__all__ = ["ProgressReporter", "build_parser", "main", "summary_table"]


def build_parser() -> argparse.ArgumentParser:
    from staghunt import __version__

    parser = Parser(
        prog=PROG,
        description="Cooperative multi-UAV path planning as a stag hunt game (game-based SPSO).",
        epilog="Exit codes: 0 feasible/success, 3 infeasible plan (result still written), "
        "2 bad input, 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    scenarios.add_commands(sub)
    plan.add_commands(sub)
    analysis.add_commands(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    try:
        parser = build_parser()
        try:
            args = parser.parse_args(argv)
        except UsageError as exc:
            return error(one_line(exc))
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
            return error(one_line(exc))
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
