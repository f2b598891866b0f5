"""The ``type`` functions of the command line's options: integers and numbers in a range (an
integer may be written ``1e6``), a relative tolerance (``0.01`` or ``1%``), a path (not empty,
no NUL). Each raises ``argparse.ArgumentTypeError`` with what it expected and what it got; its
``__name__`` is what argparse calls the value in that error."""

from __future__ import annotations

import argparse
import math
from typing import Any

__all__ = ["epsilon_value", "int_at_least", "int_between", "number_between", "path_argument"]


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


def path_argument(text: str) -> str:
    """An argparse ``type`` for file and directory options: refuses the empty string (which
    would silently mean the current directory) and NUL characters."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty")
    if "\x00" in text:
        raise argparse.ArgumentTypeError("must not contain a NUL character")
    return text


path_argument.__name__ = "path"
