"""Reading untrusted input files, once, with one-line errors naming the file (shared by the
scenario loader, PATHS.json, result.json and every command).

- :func:`read_bytes` reads a file exactly once (so a FIFO such as ``<(cat result.json)`` works),
  says what a path is when it is no regular file (a directory, a socket), and refuses files
  larger than :data:`MAX_INPUT_BYTES`.
- :func:`decode_text` insists on UTF-8 (a UTF-16 file gets "not UTF-8 text (looks like UTF-16)").
- :func:`parse_json` / :func:`parse_toml` turn every parser failure (including the
  ``RecursionError`` of deeply nested data and Python's digit limit for huge integers) into
  ``ValueError``.
- :func:`check_waypoints` refuses a plan's waypoints that are no finite ``(N, K, 3)`` array
  of moderate magnitude (every entry point that takes waypoints: certify, evaluate, fly).
- :func:`check_magnitudes` refuses numbers beyond :data:`MAX_MAGNITUDE` (absurd coordinates,
  weights or heights that would overflow the costs) and naming the element.
- :func:`clip` shortens echoed text (a 100,000-character key) for error lines.
- :func:`parse_seeds` reads a seed list (``1-10``, ``1,4,7``) for compare, sweep and benchmarks.

Every error is a ``ValueError`` whose text starts with the file's name.
"""

from __future__ import annotations

import json
import math
import numbers
import os
import re
import stat
import tomllib
from collections.abc import Mapping
from typing import Any

import numpy as np

from staghunt.errors import FieldError

MAX_INPUT_BYTES = 256 * 2**20
"""Largest input file read (scenario, PATHS.json, result.json): 256 MB."""

MAX_MAGNITUDE = 1e9
"""Largest absolute value of any number in a scenario or path file (metres, weights, ...):
costs square distances and multiply by weights, so larger values overflow float64."""

MAX_ECHO = 60
"""Longest value echoed from user input in an error line (:func:`show`)."""

MAX_WORD = 160
"""Longest run of non-space characters (a file name, a key) kept whole in an error line."""

MAX_LINE = 500
"""Longest error line."""


def clip(text: str, run: int = MAX_WORD, limit: int = MAX_LINE) -> str:
    """``text`` on one line, each run of more than ``run`` non-space characters cut to its head
    and tail around ``...``, the whole cut to ``limit`` characters."""
    words = []
    for word in str(text).split():
        if len(word) > run:
            word = word[: run - 40] + "..." + word[-37:]
        words.append(word)
    out = " ".join(words)
    return out if len(out) <= limit else out[: limit - 3] + "..."


def show(value: Any, limit: int = MAX_ECHO) -> str:
    """``repr(value)`` cut to ``limit`` characters (for messages)."""
    try:
        text = repr(value)
    except (ValueError, RecursionError):  # an int beyond Python's digit limit, deep data
        text = f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def describe_path(path: str) -> str:
    """What ``path`` is, for a message: "no such file", "a directory", "a socket", ..."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "no such file"
    except NotADirectoryError:
        return "no such file (a parent is not a directory)"
    except OSError as exc:
        return exc.strerror or "cannot be read"
    if stat.S_ISDIR(st.st_mode):
        return "a directory, not a file"
    if stat.S_ISSOCK(st.st_mode):
        return "a socket, not a file"
    if stat.S_ISBLK(st.st_mode):
        return "a block device, not a file"
    return "a file"


def read_bytes(path: str | os.PathLike[str], what: str = "file") -> bytes:
    """The bytes of ``path``, read once (regular files, FIFOs and character devices alike)."""
    name = os.fspath(path)
    kind = describe_path(name)
    if kind != "a file":
        raise ValueError(f"{name}: {kind}" + (f" (expected a {what})" if "not a file" in kind else ""))
    try:
        with open(name, "rb") as fh:
            data = fh.read(MAX_INPUT_BYTES + 1)
    except IsADirectoryError:
        raise ValueError(f"{name}: a directory, not a file") from None
    except OSError as exc:
        raise ValueError(f"{name}: cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_INPUT_BYTES:
        raise ValueError(f"{name}: larger than {MAX_INPUT_BYTES // 2**20} MB; not a {what}")
    return data


def decode_text(data: bytes, source: str) -> str:
    """UTF-8 text of ``data`` (a UTF-8 byte-order mark is dropped)."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        hint = ""
        if data[:2] in (b"\xff\xfe", b"\xfe\xff") or (len(data) > 1 and b"\x00" in data[:64]):
            hint = "; it looks like UTF-16: save it as UTF-8"
        raise ValueError(f"{source}: not UTF-8 text (byte {exc.start}: {exc.reason}){hint}") from None


def read_text(path: str | os.PathLike[str], what: str = "file") -> str:
    """:func:`read_bytes` then :func:`decode_text`."""
    return decode_text(read_bytes(path, what), os.fspath(path))


def _reject_constant(token: str) -> Any:
    raise ValueError(f"non-standard JSON number {token!r} (infinity is written as \"inf\")")


def parse_json(text: str, source: str) -> Any:
    """Strict JSON (``NaN``/``Infinity`` refused); every failure a one-line ``ValueError``."""
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{source}: not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    except RecursionError:
        raise ValueError(f"{source}: not valid JSON: nested too deeply") from None
    except ValueError as exc:  # parse_constant, int digit limit
        raise ValueError(f"{source}: not valid JSON: {clip(str(exc))}") from None


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """TOML; every failure a one-line ``ValueError``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source}: invalid TOML: {clip(str(exc))}") from None
    except RecursionError:
        raise ValueError(f"{source}: invalid TOML: nested too deeply") from None
    except ValueError as exc:  # int digit limit
        raise ValueError(f"{source}: invalid TOML: {clip(str(exc))}") from None


def key_path(parts: tuple[Any, ...]) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{clip(str(p))}" if out else clip(str(p)))
    return out


def check_magnitudes(data: Any, limit: float = MAX_MAGNITUDE, depth_limit: int = 64) -> None:
    """Raise ``ValueError("key.path: ...")`` for the first number of ``data`` (nested tables and
    arrays) whose magnitude exceeds ``limit`` (or nesting deeper than ``depth_limit``)."""
    stack: list[tuple[Any, tuple[Any, ...]]] = [(data, ())]
    while stack:
        value, where = stack.pop()
        if len(where) > depth_limit:
            raise ValueError(f"{key_path(where)}: nested more than {depth_limit} levels deep")
        if isinstance(value, bool) or value is None or isinstance(value, str):
            continue
        if isinstance(value, Mapping):
            stack.extend((v, (*where, k)) for k, v in reversed(list(value.items())))
        elif isinstance(value, (list, tuple)):
            stack.extend((v, (*where, i)) for i, v in reversed(list(enumerate(value))))
        elif isinstance(value, numbers.Real):
            big = (abs(value) > limit) if isinstance(value, int) else not (
                math.isnan(value) or abs(float(value)) <= limit)
            if big and not (isinstance(value, float) and math.isinf(value)):
                text = f"{float(value):.3g}" if not isinstance(value, int) or value.bit_length() < 1000 \
                    else f"an integer of {value.bit_length()} bits"
                hint = ("no budget this large fits in memory or time" if where and where[0] == "solver"
                        else "use metres and moderate weights")
                raise ValueError(f"{key_path(where)}: {text} is beyond the supported magnitude "
                                 f"{limit:.0e} ({hint})")


def check_waypoints(waypoints: object, n_uavs: int, what: str = "waypoints") -> np.ndarray:
    """``waypoints`` as a float ``(N, K, 3)`` array, or :class:`~staghunt.errors.FieldError`
    (field ``waypoints``, one line starting with ``what``) when it has another shape, holds a
    non-finite number or a magnitude beyond :data:`MAX_MAGNITUDE` (absurd coordinates overflow
    the costs)."""
    try:
        wp = np.asarray(waypoints, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise FieldError(f"{what}: expected numbers in an (N, K, 3) array", "waypoints") from None
    if wp.ndim != 3 or wp.shape[0] != n_uavs or wp.shape[2] != 3 or wp.shape[1] < 1:
        raise FieldError(f"{what}: expected shape (N={n_uavs}, K>=1, 3), got {wp.shape}", "waypoints")
    if not np.all(np.isfinite(wp)):
        raise FieldError(f"{what}: must be finite numbers", "waypoints")
    if np.max(np.abs(wp)) > MAX_MAGNITUDE:
        raise FieldError(f"{what}: a coordinate beyond the supported magnitude {MAX_MAGNITUDE:.0e}", "waypoints")
    return wp


_SEED_PART = re.compile(r"(\d+)(?:\s*-\s*(\d+))?")


def parse_seeds(text: str, limit: int | None = None) -> tuple[int, ...]:
    """``"1-10"``, ``"3"``, ``"1,4,7"`` or ``"1-3,8"`` -> seeds in order, duplicates dropped.

    Raises ``ValueError`` with one line for anything else (negative, empty, reversed range, more
    than ``limit`` seeds).
    """
    out: list[int] = []
    seen: set[int] = set()
    for part in text.split(","):
        match = _SEED_PART.fullmatch(part.strip())
        if match is None:
            raise FieldError(f"seeds: expected seeds >= 0 like 1-10, 7 or 1,4,7, got {text!r}", "seeds")
        lo = int(match.group(1))
        hi = int(match.group(2)) if match.group(2) is not None else lo
        if lo > hi:
            raise FieldError(f"seeds: the range {part.strip()!r} runs backwards", "seeds")
        if hi - lo > 100_000:
            raise FieldError(f"seeds: the range {part.strip()!r} is too long", "seeds")
        for v in range(lo, hi + 1):
            if v not in seen:
                seen.add(v)
                out.append(v)
        if limit is not None and len(out) > limit:
            raise FieldError(f"seeds: more than {limit:,} seeds", "seeds")
    return tuple(out)
