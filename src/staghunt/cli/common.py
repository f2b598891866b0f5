"""What the ``staghunt`` commands share: exit codes, the parser, option types and the option blocks
used by several commands (scenario, budget, output directory, engine, quiet), error lines, the
terminal status line."""

from __future__ import annotations

import argparse
import inspect
import math
import os
import re
import shutil
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from staghunt.study.executor import DEFAULT_CONNECT_TIMEOUT_S

PROG = "staghunt"
EXIT_OK = 0
EXIT_USAGE = 2
EXIT_NEGATIVE = 3
"""The command ran but the answer is no: an infeasible plan, or a plan that is no equilibrium."""
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 128 + 13
"""Exit code when stdout's reader went away (as if ended by SIGPIPE)."""

SHARED_EXITS = {
    EXIT_USAGE: "bad input",
    EXIT_INTERRUPTED: "interrupted",
    EXIT_BROKEN_PIPE: "stdout closed early (files already written)",
}
"""What every subcommand's exit codes 2, 130 and 141 mean, unless it words them itself."""


class UsageError(Exception):
    """Bad command-line input (reported as one line, exit code 2)."""


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are raised (one line), not printed with the usage."""

    def error(self, message: str) -> Any:  # type: ignore[override]
        raise UsageError(f"{message} (see '{self.prog} --help')")


def int_at_least(low: int) -> Any:
    """An argparse ``type`` accepting integers ``>= low``."""

    def parse(text: str) -> int:
        from staghunt.inputs import show

        try:
            value = int(text)
        except ValueError:
            try:  # 1e6: an integer written in exponent notation
                f = float(text)
            except ValueError:
                f = math.nan
            if not (math.isfinite(f) and f.is_integer() and abs(f) < 1e18):
                raise argparse.ArgumentTypeError(f"expected an integer >= {low}, got {show(text)}") from None
            value = int(f)
        if value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {value}")
        return value

    parse.__name__ = f"integer >= {low}"
    return parse


def number_between(low: float, high: float, unit: str, above_low: bool = False) -> Any:
    """An argparse ``type`` accepting numbers in ``[low, high]`` (``above_low``: ``(low, high]``),
    in ``unit``."""

    def parse(text: str) -> float:
        from staghunt.inputs import clip

        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {clip(repr(text))}") from None
        if not ((low < v if above_low else low <= v) and v <= high):
            span = f"{'(' if above_low else '['}{low:g}, {high:g}]"
            raise argparse.ArgumentTypeError(f"must lie in {span} {unit}, got {clip(repr(text))}")
        return v

    parse.__name__ = "number"
    return parse


MAX_THREADS = 256
"""Largest ``--threads`` (each thread holds its own block buffers)."""


def int_between(low: int, high: int) -> Any:
    """An argparse ``type`` accepting integers in ``[low, high]``."""
    at_least = int_at_least(low)

    def parse(text: str) -> int:
        value = at_least(text)
        if value > high:
            raise argparse.ArgumentTypeError(f"must be an integer <= {high}, got {value}")
        return value

    parse.__name__ = f"integer in [{low}, {high}]"
    return parse


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


def exit_codes(exits: dict[int, str]) -> str:
    """``Exit codes: 0 ..., 3 ..., 2 bad input, 130 interrupted, 141 ...``: a command's own
    codes in their order, then the shared ones (:data:`SHARED_EXITS`), in its words where it
    gives them."""
    codes = {**{c: w for c, w in exits.items() if c not in SHARED_EXITS},
             **{c: exits.get(c, w) for c, w in SHARED_EXITS.items()}}
    return "Exit codes: " + ", ".join(f"{code} {words}" for code, words in codes.items()) + "."


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


FIELD_FLAGS = {
    "method": "--method",
    "seed": "--seed",
    "settings": "--particles, --iterations, --waypoints, --starts or the scenario's [solver]",
    "certify": "--certify-particles, --certify-iterations, --epsilon; --no-certify skips the certificate",
    "stop": "--stop certified; drop --no-certify",
    "origin": "--origin LAT,LON,ALT",
    "out": "--out",
    "force": "--force",
    "altitude_frame": "--altitude-frame, --formats",
    "formats": "--formats",
    "seeds": "--seeds",
    "methods": "--methods",
}
"""How the command line names the argument at fault of a refusal
(:class:`staghunt.errors.FieldError`: ``field``); per command in :data:`COMMAND_FLAGS`."""

COMMAND_FLAGS = {
    "certify": {"certify": "--particles, --iterations, --epsilon", "settings": "the file's settings"},
    "compare": {"method": "--methods"},
    "fly": {"settings": "--particles, --iterations, --waypoints or the scenario's [solver]"},
}

SHRINK_FLAGS: dict[Any, str] = {
    "threads": "fewer threads (--threads) or waypoints",
    "iterations": "fewer iterations (--iterations)",
    ("certify", "certify"): "a smaller --particles or --iterations",
}
"""How to shrink a run that cannot fit in memory (:class:`staghunt.budget.MemoryBudgetError`),
in flags."""


def worded(exc: BaseException, command: str | None = None) -> str:
    """The text of ``exc`` as the command line says it: a :class:`staghunt.errors.FieldError`
    gets the flags of its field (of ``command``), a memory refusal its remedy in flags."""
    from staghunt.budget import MemoryBudgetError
    from staghunt.errors import FieldError

    if isinstance(exc, MemoryBudgetError):
        shrink = SHRINK_FLAGS.get((command, exc.field), SHRINK_FLAGS.get(exc.field))
        return f"{exc.need}; use {shrink}" if shrink else str(exc)
    if isinstance(exc, FieldError):
        flags = COMMAND_FLAGS.get(command or "", {}).get(exc.field, FIELD_FLAGS.get(exc.field))
        return f"{exc} ({flags})" if flags else str(exc)
    return str(exc)


def checked_request(scenario: Any, settings: Any, args: argparse.Namespace, certify: Any,
                    method: str | None = None, memory: bool = True) -> Any:
    """The run of ``scenario`` checked once (:func:`staghunt.api.check_plan`) with the options in
    ``args`` (``method`` overrides ``--method``); a refusal (:class:`staghunt.api.PlanRequestError`)
    is worded with the flags at fault where it is reported (:func:`one_line`)."""
    from staghunt.api import check_plan

    return check_plan(scenario, method or args.method, getattr(args, "seed", 0), settings,
                      getattr(args, "engine", "auto"), getattr(args, "threads", None), certify,
                      warn=say, stop=getattr(args, "stop", "budget"), memory=memory)


def epsilon_value(text: str) -> float:
    """``0.01`` or ``1%``: a finite relative tolerance >= 0."""
    t = text.strip()
    try:
        value = float(t[:-1]) / 100.0 if t.endswith("%") else float(t)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number like 0.01 or 1%, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return value


epsilon_value.__name__ = "epsilon"


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


def os_reason(exc: OSError) -> str:
    """An ``OSError`` as one short phrase naming the file."""
    reason = exc.strerror or str(exc)
    return f"{reason}: {exc.filename!r}" if exc.filename else reason


def one_line(exc: BaseException, command: str | None = None) -> str:
    """An exception as one line of text (an ``OSError`` naming its file; a refusal naming the
    flags of ``command`` at fault: :func:`worded`)."""
    text = os_reason(exc) if isinstance(exc, OSError) else worded(exc, command)
    return " ".join(text.split()) or type(exc).__name__


def error(message: str) -> int:
    """Print ``staghunt: error: ...`` (one line, echoed input cut: :func:`staghunt.inputs.clip`)
    on stderr; returns :data:`EXIT_USAGE`."""
    from staghunt.inputs import clip

    say(f"{PROG}: error: {clip(str(message))}")
    return EXIT_USAGE


def say(line: str, stream: TextIO | None = None) -> None:
    """Write one line to ``stream`` (default stderr), ignoring a closed or broken stream: a
    message must never turn into a traceback."""
    try:
        out = stream if stream is not None else sys.stderr
        out.write(line + "\n")
        out.flush()
    except (OSError, ValueError, AttributeError):
        pass


SAFE_NAME_MAX = 64
"""Longest scenario-name part of a default output directory name."""


def safe_name(name: str) -> str:
    """A scenario name usable as part of a directory name (at most :data:`SAFE_NAME_MAX` characters)."""
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")[:SAFE_NAME_MAX].strip("._")
    return cleaned or "scenario"


def path_argument(text: str) -> str:
    """An argparse ``type`` for file and directory options: refuses the empty string (which
    would silently mean the current directory) and NUL characters."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty")
    if "\x00" in text:
        raise argparse.ArgumentTypeError("must not contain a NUL character")
    return text


path_argument.__name__ = "path"


def _name_max(directory: Path) -> int:
    try:
        return int(os.pathconf(directory, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def check_path_lengths(path: Path, label: str) -> None:
    """Raise ``ValueError`` if a component of ``path`` is longer than the file system allows
    (``NAME_MAX``, 255 bytes on most) or the whole path longer than ``PATH_MAX`` (4096)."""
    anchor = Path(".")
    for parent in [*reversed(path.absolute().parents)]:
        try:
            if parent.is_dir():
                anchor = parent
        except OSError:  # a name too long to even look up
            break
    limit = _name_max(anchor)
    for part in path.parts:
        if len(os.fsencode(part)) > limit:
            raise ValueError(f"{label}: the name {part[:40]!r}... is {len(os.fsencode(part))} bytes long; "
                             f"this file system allows {limit}")
    if len(os.fsencode(str(path.absolute()))) >= 4096:
        raise ValueError(f"{label}: the path is longer than 4096 bytes")


def check_out_dir(out_dir: Path, file: str | None = None) -> None:
    """Raise ``ValueError`` if ``out_dir`` cannot be used as an output directory (checked before any
    work): it exists and is no directory, or cannot be created. With ``file``, also when it is not
    writable or already holds a directory of that name."""
    from staghunt.inputs import clip

    label = f"output directory {clip(repr(str(out_dir)))}"
    check_path_lengths(out_dir if file is None else out_dir / file, label)
    if out_dir.exists():
        if not out_dir.is_dir():
            raise ValueError(f"{label} exists and is not a directory")
        if file is None:
            return
        if not os.access(out_dir, os.W_OK | os.X_OK):
            raise ValueError(f"{label} is not writable")
        if (out_dir / file).is_dir():
            raise ValueError(f"{label} holds a directory named {file}")
        from staghunt.io.atomic import check_replaceable

        check_replaceable(out_dir / file)  # a FIFO or device named result.json: refused now
        return
    parent = out_dir.parent if file is not None else out_dir
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if file is None and not parent.exists():
        return
    if not parent.is_dir():
        raise ValueError(f"{label} cannot be created: {str(parent)!r} is not a directory")
    if file is not None and not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{label} cannot be created: {str(parent)!r} is not writable")


class StatusLine:
    """A status line redrawn in place on a terminal (at most ~10 times a second); silent when the
    stream is not a terminal."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        try:
            self.tty = bool(stream.isatty())
        except (AttributeError, ValueError):
            self.tty = False
        self.last = -math.inf
        self.drawn = False
        self.broken = False

    def draw(self, text: str, force: bool = False) -> None:
        if not self.tty:
            return
        now = time.perf_counter()
        if not force and now - self.last < 0.1:
            return
        self.last = now
        cols = shutil.get_terminal_size((80, 24)).columns
        self.drawn = self._write("\r" + text[: max(cols - 1, 10)] + "\x1b[K")

    def say(self, text: str) -> None:
        """A permanent line (clears the status line first)."""
        if self.drawn:
            self._write("\r\x1b[K")
            self.drawn = False
        self._write(text + "\n")

    def close(self, keep: bool = False) -> None:
        """Clear the status line, or with ``keep`` end it so it stays on screen."""
        if self.drawn:
            self._write("\n" if keep else "\r\x1b[K")
            self.drawn = False

    def _write(self, text: str) -> bool:
        """Write and flush; a broken or closed stream silences the line (progress is never
        worth losing a run over). Returns whether it was written."""
        if self.broken:
            return False
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            self.broken, self.tty = True, False
            return False
        return True
