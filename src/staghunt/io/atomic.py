"""Atomic file writes: a result, table or figure is either complete or not there at all."""

from __future__ import annotations

import os
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, Iterator


@contextmanager
def atomic_file(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` for writing (``"w"`` text, ``"wb"`` bytes); when the
    block ends normally it is flushed, ``fsync``-ed and moved over ``path`` with ``os.replace``.
    On any failure (or an interrupt) the temporary file is removed and ``path`` is left as it was.
    """
    dest = Path(path)
    directory = dest.parent if str(dest.parent) else Path(".")
    check_replaceable(dest)
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp", dir=directory)
    try:
        kwargs = {"encoding": "utf-8", "newline": "\n"} if "b" not in mode else {}
        with os.fdopen(fd, mode, **kwargs) as fh:
            os.chmod(tmp, _new_file_mode(dest))
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, dest)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    _fsync_dir(directory)


def check_replaceable(dest: Path) -> None:
    """Raise ``ValueError`` if ``dest`` exists and is not a regular file (a directory, a device
    such as ``/dev/full``, a FIFO, a socket): an atomic write would replace it by a file."""
    try:
        mode = os.stat(dest).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise ValueError(f"{dest}: cannot write: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        kind = "a directory" if stat.S_ISDIR(mode) else "not a regular file (a device, FIFO or socket)"
        raise ValueError(f"{dest}: is {kind}; refusing to replace it (give a file name)")


def write_text_atomic(text: str, path: str | os.PathLike[str]) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path."""
    with atomic_file(path, "w") as fh:
        fh.write(text)
    return Path(path)


def _new_file_mode(dest: Path) -> int:
    """The mode an ordinary new file would get (``mkstemp`` creates ``0o600``); keep an existing file's."""
    try:
        return dest.stat().st_mode & 0o777
    except OSError:
        pass
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def _fsync_dir(directory: Path) -> None:
    """Best effort: make the rename durable (not possible on every platform)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
