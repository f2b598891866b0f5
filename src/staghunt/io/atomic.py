"""Atomic file writes: a result, table or figure is either complete or not there at all, and a set
of files (a mission) is written as one (:func:`write_file_set`)."""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from collections.abc import Callable, Mapping, Sequence
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


def write_file_set(directory: str | os.PathLike[str], files: Mapping[str, str | bytes],
                   more: Callable[[Path], Sequence[Path]] | None = None,
                   previous: Sequence[str] = (),
                   manifest: Callable[[list[str]], tuple[str, str | bytes]] | None = None) -> list[Path]:
    """Write a set of files into ``directory`` as one: all of them or none.

    Every file (``files``: name -> text or bytes; then whatever ``more(stage)`` writes into the
    staging directory it is given, returning the paths) is first written and ``fsync``-ed in a
    hidden staging directory inside ``directory``; only when all are complete are they moved into
    place, each ``os.replace``-ing a file of the same name. A failure or an interrupt while
    staging removes the staging directory (and ``directory`` if this call created it and it is
    empty again); one while moving puts back the files it replaced and removes the ones it had
    placed. ``previous``: the names of the set this one replaces (a previous export's files, as
    its manifest lists them); those the new set does not name are removed with the move (and put
    back if it fails), so that the directory never mixes two sets; only regular files directly in
    ``directory`` are removed. Other files in ``directory`` are never touched. ``manifest``:
    given the names of every file staged, returns the name and content of one more file (say,
    ``mission.json`` listing the set, itself included), staged and moved last. Raises
    ``ValueError`` (one line) for a name whose destination is not a regular file, ``OSError`` for
    a failed write (the directory is then as it was)."""
    out = Path(directory)
    created = _make_dirs(out)
    stage: Path | None = None
    try:
        for name in files:
            check_replaceable(out / name)
        stage = Path(tempfile.mkdtemp(prefix=".staghunt-set.", suffix=".tmp", dir=out))
        names: list[str] = []
        for name, content in files.items():
            _write_new(stage / name, content, _new_file_mode(out / name))
            names.append(name)
        if more is not None:
            for p in more(stage):
                check_replaceable(out / Path(p).name)
                names.append(Path(p).name)
        if manifest is not None:
            name, content = manifest(list(names))
            check_replaceable(out / name)
            _write_new(stage / name, content, _new_file_mode(out / name))
            names.append(name)
        _commit(stage, out, names, _stale(out, previous, names))
    except BaseException:
        kept = None if stage is None else stage / ".replaced"
        if stage is not None and not (kept is not None and kept.is_dir() and any(kept.iterdir())):
            shutil.rmtree(stage, ignore_errors=True)  # (a replaced file that could not be put back stays there)
        for d in reversed(created):
            try:
                d.rmdir()
            except OSError:
                break
        raise
    shutil.rmtree(stage, ignore_errors=True)
    _fsync_dir(out)
    return [out / name for name in names]


def _make_dirs(out: Path) -> list[Path]:
    """``mkdir -p out``; the directories it created, outermost first."""
    missing = []
    p = out
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    out.mkdir(parents=True, exist_ok=True)
    return list(reversed(missing))


def _write_new(path: Path, content: str | bytes, mode: int) -> None:
    """Create ``path`` (it must not exist), write ``content`` (text as UTF-8), flush and fsync."""
    data = content.encode("utf-8") if isinstance(content, str) else content
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as fh:
        os.chmod(path, mode)
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def _stale(out: Path, previous: Sequence[str], names: Sequence[str]) -> list[str]:
    """The files of the previous set that the new one does not name: plain names (no directory
    part, not hidden) of regular files (not followed through a symbolic link) in ``out``."""
    keep = set(names)
    stale = []
    for name in dict.fromkeys(previous):
        if (not isinstance(name, str) or name in keep or not name or name.startswith(".")
                or Path(name).name != name or os.sep in name or "/" in name):
            continue
        try:
            if stat.S_ISREG(os.lstat(out / name).st_mode):
                stale.append(name)
        except OSError:
            continue
    return stale


def _commit(stage: Path, out: Path, names: Sequence[str], stale: Sequence[str] = ()) -> None:
    """Move the staged ``names`` into ``out`` and the ``stale`` files of ``out`` aside (removed
    with the staging directory); on any failure undo every move made."""
    backup = stage / ".replaced"
    backup.mkdir()
    replaced: list[str] = []
    placed: list[str] = []
    try:
        for name in stale:
            os.replace(out / name, backup / name)
            replaced.append(name)
        for name in names:
            dest = out / name
            if os.path.lexists(dest):
                os.replace(dest, backup / name)
                replaced.append(name)
            os.replace(stage / name, dest)
            placed.append(name)
    except BaseException:
        for name in placed:
            try:
                os.unlink(out / name)
            except OSError:
                pass
        for name in replaced:
            try:
                os.replace(backup / name, out / name)
            except OSError:
                pass
        raise
