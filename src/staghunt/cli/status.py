"""The terminal status line of long commands (plan's progress, compare's and sweep's tasks)."""

from __future__ import annotations

import math
import shutil
import time
from typing import TextIO

__all__ = ["StatusLine"]


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
