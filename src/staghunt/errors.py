"""The library's refusals that name the argument at fault.

A :class:`FieldError` is a ``ValueError`` with one line in the library's own words and a
``field``: the name of the argument or input at fault (``seed``, ``settings``, ``origin``,
``out``...). The library never names command-line flags; the command line
(:func:`staghunt.cli.common.worded`) adds them from ``field``.
"""

from __future__ import annotations


class FieldError(ValueError):
    """A refused input; ``field`` names the argument at fault so that a caller can word it."""

    def __init__(self, message: str, field: str) -> None:
        super().__init__(message)
        self.field = field
