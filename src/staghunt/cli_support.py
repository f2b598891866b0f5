"""What the ``staghunt`` commands share: exit codes, option types, error lines, engine options."""

from __future__ import annotations

import argparse
import math
import re
import shutil
import sys
import time
from typing import Any, TextIO

PROG = "staghunt"
EXIT_OK = 0
EXIT_USAGE = 2
EXIT_NEGATIVE = 3
"""The command ran but the answer is no: an infeasible plan, or a plan that is no equilibrium."""
EXIT_INTERRUPTED = 130


def int_at_least(low: int) -> Any:
    """An argparse ``type`` accepting integers ``>= low``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer >= {low}, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {value}")
        return value

    parse.__name__ = f"integer >= {low}"
    return parse


def add_engine_options(p: argparse.ArgumentParser) -> None:
    """``--engine`` and ``--threads`` (shared by plan, compare and certify)."""
    from staghunt.engine import ENGINE_NAMES

    p.add_argument("--engine", choices=list(ENGINE_NAMES),
                   default="auto", help="numba (compiled), numpy (reference) or auto: numba if "
                   "installed (default: auto)")
    p.add_argument("--threads", type=int_at_least(1), metavar="N",
                   help="threads of the numba engine (default: adaptive)")


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


def error(message: str) -> int:
    """Print ``staghunt: error: ...`` (one line) on stderr; returns :data:`EXIT_USAGE`."""
    text = " ".join(str(message).split())
    print(f"{PROG}: error: {text}", file=sys.stderr)
    return EXIT_USAGE


def safe_name(name: str) -> str:
    """A scenario name usable as part of a directory name."""
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")
    return cleaned or "scenario"


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

    def draw(self, text: str, force: bool = False) -> None:
        if not self.tty:
            return
        now = time.perf_counter()
        if not force and now - self.last < 0.1:
            return
        self.last = now
        cols = shutil.get_terminal_size((80, 24)).columns
        self.stream.write("\r" + text[: max(cols - 1, 10)] + "\x1b[K")
        self.stream.flush()
        self.drawn = True

    def say(self, text: str) -> None:
        """A permanent line (clears the status line first)."""
        if self.drawn:
            self.stream.write("\r\x1b[K")
            self.drawn = False
        self.stream.write(text + "\n")
        self.stream.flush()

    def close(self, keep: bool = False) -> None:
        """Clear the status line, or with ``keep`` end it so it stays on screen."""
        if self.drawn:
            self.stream.write("\n" if keep else "\r\x1b[K")
            self.stream.flush()
            self.drawn = False
