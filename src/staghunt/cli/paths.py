"""Checks of the paths the command line writes to, made before any work: names and paths the file
system cannot hold, an output directory that is a file or cannot be created or written, a
default directory name made from a scenario's name."""

from __future__ import annotations

import os
import re
from pathlib import Path

__all__ = ["SAFE_NAME_MAX", "check_out_dir", "check_path_lengths", "safe_name"]

SAFE_NAME_MAX = 64
"""Longest scenario-name part of a default output directory name."""


def safe_name(name: str) -> str:
    """A scenario name usable as part of a directory name (at most :data:`SAFE_NAME_MAX` characters)."""
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")[:SAFE_NAME_MAX].strip("._")
    return cleaned or "scenario"


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

