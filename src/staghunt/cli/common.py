"""What the ``staghunt`` commands share: the parser, the option blocks used by several commands
(scenario, budget, certificate, output directory, engine, cluster, quiet) and the run they check.

Its other concerns live apart and are re-exported here: the options' types
(:mod:`~staghunt.cli.argtypes`), exit codes and error wording (:mod:`~staghunt.cli.wording`),
checks of output paths (:mod:`~staghunt.cli.paths`), the terminal status line
(:mod:`~staghunt.cli.status`)."""

from __future__ import annotations

import argparse
import inspect
from typing import Any

from staghunt.cli.argtypes import epsilon_value, int_at_least, int_between, number_between, path_argument
from staghunt.cli.paths import SAFE_NAME_MAX, check_out_dir, check_path_lengths, safe_name
from staghunt.cli.status import StatusLine
from staghunt.cli.wording import (
    COMMAND_FLAGS, EXIT_BROKEN_PIPE, EXIT_INTERRUPTED, EXIT_NEGATIVE, EXIT_OK, EXIT_USAGE, FIELD_FLAGS, PROG,
    SHARED_EXITS, SHRINK_FLAGS, UsageError, error, exit_codes, one_line, os_reason, say, worded,
)
from staghunt.study.executor import DEFAULT_CONNECT_TIMEOUT_S

__all__ = [  # the re-exported names first
    "COMMAND_FLAGS", "EXIT_BROKEN_PIPE", "EXIT_INTERRUPTED", "EXIT_NEGATIVE", "EXIT_OK", "EXIT_USAGE", "FIELD_FLAGS",
    "PROG", "SAFE_NAME_MAX", "SHARED_EXITS", "SHRINK_FLAGS", "StatusLine", "UsageError", "check_out_dir",
    "check_path_lengths", "epsilon_value", "error", "exit_codes", "int_at_least", "int_between", "number_between",
    "one_line", "os_reason", "path_argument", "safe_name", "say", "worded",
    "MAX_THREADS", "Parser", "add_budget_options", "add_certificate_options", "add_cluster_options",
    "add_engine_options", "add_out_option", "add_plots_option", "add_quiet_option", "add_run_options",
    "add_scenario_argument", "add_seed_option", "budget_settings", "certify_options", "checked_request", "command",
    "engine_kwargs",
]


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are raised (one line), not printed with the usage."""

    def error(self, message: str) -> Any:  # type: ignore[override]
        raise UsageError(f"{message} (see '{self.prog} --help')")


MAX_THREADS = 256
"""Largest ``--threads`` (each thread holds its own block buffers)."""


def add_engine_options(p: argparse.ArgumentParser) -> None:
    """``--engine`` and ``--threads`` (shared by plan, compare and certify)."""
    from staghunt.engine import ENGINE_NAMES

    p.add_argument("--engine", choices=list(ENGINE_NAMES),
                   default="auto", help="numba (compiled), numpy (reference) or auto: numba if "
                   "installed (default: auto)")
    p.add_argument("--threads", type=int_between(1, MAX_THREADS), metavar="N",
                   help=f"threads of the numba engine, at most {MAX_THREADS} (default: adaptive)")


def command(sub: Any, name: str, func: Any, exits: dict[int, str] | None = None) -> argparse.ArgumentParser:
    """Register the subcommand ``name`` on ``sub``: its handler ``func(args) -> exit code``,
    whose docstring is the command's help (its first line in the list of commands, the
    paragraphs after it the command's description, rewrapped by argparse). ``exits``: what its
    own exit codes mean (``0``, ``3``, ...; its words for 2, 130 or 141 replace
    :data:`SHARED_EXITS`), listed after its options (:func:`exit_codes`)."""
    summary, _, description = inspect.cleandoc(func.__doc__ or "").partition("\n\n")
    p = sub.add_parser(name, help=summary, description=description or None,
                       epilog=exit_codes(exits) if exits is not None else None)
    p.set_defaults(func=func)
    return p


def add_scenario_argument(p: argparse.ArgumentParser) -> None:
    """The positional ``SCENARIO`` (plan, evaluate, show, compare)."""
    p.add_argument("scenario", metavar="SCENARIO", help="built-in name or path to a .toml file")


def add_budget_options(p: argparse.ArgumentParser) -> None:
    """``--particles``, ``--iterations``, ``--waypoints``: the swarm budget, each defaulting to the
    scenario's ``[solver]`` setting (plan, compare)."""
    p.add_argument("--particles", type=int_at_least(1), metavar="N",
                   help="particles per swarm (default: the scenario's)")
    p.add_argument("--iterations", type=int_at_least(0), metavar="N",
                   help="swarm iterations (default: the scenario's)")
    p.add_argument("--waypoints", type=int_at_least(1), metavar="N",
                   help="free waypoints K per UAV (default: the scenario's)")
    p.add_argument("--starts", type=int_at_least(1), metavar="N",
                   help="starts of the game method's equilibrium search: rigid, independent, weighted, "
                   "then random allocations (default: the scenario's, 3)")


def budget_settings(scenario: Any, args: argparse.Namespace) -> Any:
    """The scenario's solver settings with the budget options applied (checked with the rest of
    the run by :func:`checked_request`)."""
    return scenario.solver.with_(particles=args.particles, iterations=args.iterations,
                                 waypoints=args.waypoints, starts=args.starts)


def checked_request(scenario: Any, settings: Any, args: argparse.Namespace, certify: Any,
                    method: str | None = None, memory: bool = True) -> Any:
    """The run of ``scenario`` checked once (:func:`staghunt.api.check_plan`) with the options in
    ``args`` (``method`` overrides ``--method``); a refusal (:class:`staghunt.api.PlanRequestError`)
    is worded with the flags at fault where it is reported (:func:`one_line`)."""
    from staghunt.api import check_plan

    return check_plan(scenario, method or args.method, getattr(args, "seed", 0), settings,
                      getattr(args, "engine", "auto"), getattr(args, "threads", None), certify,
                      warn=say, stop=getattr(args, "stop", "budget"), memory=memory)


def add_certificate_options(p: argparse.ArgumentParser, prefix: str, skip: str | None = None) -> None:
    """The certificate's budget and tolerance: ``--{prefix}particles``, ``--{prefix}iterations``
    (each UAV's best-response search) and ``--epsilon``; with ``skip`` (what is skipped) also
    ``--no-certify`` (plan, compare: prefix ``certify-``; certify: no prefix)."""
    from staghunt.solvers.response import DEFAULT_EPSILON, DEFAULT_ITERATIONS, DEFAULT_PARTICLES

    p.add_argument(f"--{prefix}particles", type=int_at_least(1), metavar="N", default=DEFAULT_PARTICLES,
                   help=f"particles of each UAV's best-response search (default: {DEFAULT_PARTICLES})")
    p.add_argument(f"--{prefix}iterations", type=int_at_least(0), metavar="N", default=DEFAULT_ITERATIONS,
                   help=f"iterations of each UAV's best-response search (default: {DEFAULT_ITERATIONS})")
    p.add_argument("--epsilon", type=epsilon_value, metavar="EPS", default=DEFAULT_EPSILON,
                   help=f"relative Nash-gap tolerance, e.g. 0.01 or 1%% (default: {DEFAULT_EPSILON:g} = 1%%)")
    if skip is not None:
        p.add_argument("--no-certify", action="store_true", help=f"skip {skip}")


def certify_options(args: argparse.Namespace) -> Any:
    """The :class:`~staghunt.solvers.response.CertifyOptions` of the ``certify-`` options of
    :func:`add_certificate_options`, or ``None`` with ``--no-certify``."""
    from staghunt.solvers.response import CertifyOptions

    if args.no_certify:
        return None
    return CertifyOptions(args.certify_particles, args.certify_iterations, args.epsilon)


def add_out_option(p: argparse.ArgumentParser, default: str | None = None) -> None:
    """``--out DIR``, the output directory (not empty: :func:`path_argument`); required without a
    ``default`` (what it is when not given, for the help)."""
    if default is None:
        p.add_argument("--out", metavar="DIR", type=path_argument, required=True, help="output directory")
    else:
        p.add_argument("--out", metavar="DIR", type=path_argument, help=f"output directory (default: {default})")


def add_plots_option(p: argparse.ArgumentParser, what: str = "figures") -> None:
    """``--no-plots``: do not draw ``what``."""
    p.add_argument("--no-plots", action="store_true", help=f"do not write {what}")


def add_seed_option(p: argparse.ArgumentParser, help: str = "random seed (default: 0)") -> None:
    """``--seed N``, an integer >= 0, default 0."""
    p.add_argument("--seed", type=int_at_least(0), default=0, metavar="N", help=help)


def add_cluster_options(p: argparse.ArgumentParser, what: str, workers_default: str) -> None:
    """Where the ``what`` run (compare's runs, sweep's tasks): ``--workers N`` processes of a
    local Dask cluster (``workers_default``: what it is when not given) or the Dask
    ``--scheduler ADDRESS``, reached within ``--connect-timeout S``."""
    p.add_argument("--workers", type=int_between(1, 1024), metavar="N",
                   help=f"run the {what} on a local Dask cluster of N worker processes, one thread each "
                   f"(default: {workers_default})")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help=f"run the {what} on the Dask scheduler at ADDRESS (e.g. tcp://host:8786)")
    p.add_argument("--connect-timeout", type=number_between(0, 3600, "seconds", above_low=True), metavar="S",
                   default=DEFAULT_CONNECT_TIMEOUT_S,
                   help=f"seconds to reach --scheduler before giving up (default: {DEFAULT_CONNECT_TIMEOUT_S:g})")


def add_quiet_option(p: argparse.ArgumentParser, help: str = "no progress on stderr") -> None:
    p.add_argument("--quiet", action="store_true", help=help)


def add_run_options(p: argparse.ArgumentParser, out_default: str | None,
                    quiet_help: str = "no progress on stderr") -> None:
    """What every planning command takes: the budget, ``--out DIR`` (:func:`add_out_option`), the
    engine, ``--quiet``."""
    add_budget_options(p)
    add_out_option(p, out_default)
    add_engine_options(p)
    add_quiet_option(p, quiet_help)


def engine_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """``engine``/``threads`` keyword arguments from the parsed options."""
    out: dict[str, Any] = {}
    if getattr(args, "engine", None) is not None:
        out["engine"] = args.engine
    if getattr(args, "threads", None) is not None:
        out["threads"] = args.threads
    return out

