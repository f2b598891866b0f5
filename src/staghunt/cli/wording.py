"""How the command line words what goes wrong: its name and exit codes (and what each command's
mean, :func:`exit_codes`), one line per error on stderr (:func:`error`, :func:`say`), an
exception as one line (:func:`one_line`) naming the flags at fault of a refusal
(:func:`worded`)."""

from __future__ import annotations

import sys
from typing import Any, TextIO

__all__ = [
    "COMMAND_FLAGS", "EXIT_BROKEN_PIPE", "EXIT_INTERRUPTED", "EXIT_NEGATIVE", "EXIT_OK", "EXIT_USAGE", "FIELD_FLAGS",
    "PROG", "SHARED_EXITS", "SHRINK_FLAGS", "UsageError", "error", "exit_codes", "one_line", "os_reason", "say", "worded",
]

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


def exit_codes(exits: dict[int, str]) -> str:
    """``Exit codes: 0 ..., 3 ..., 2 bad input, 130 interrupted, 141 ...``: a command's own
    codes in their order, then the shared ones (:data:`SHARED_EXITS`), in its words where it
    gives them."""
    codes = {**{c: w for c, w in exits.items() if c not in SHARED_EXITS},
             **{c: exits.get(c, w) for c, w in SHARED_EXITS.items()}}
    return "Exit codes: " + ", ".join(f"{code} {words}" for code, words in codes.items()) + "."


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

