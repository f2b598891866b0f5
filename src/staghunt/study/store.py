"""The append-only result store of a sweep: a Parquet *directory dataset* of part files.

``DIR/results.parquet/`` holds ``part-<time>-<pid>-<n>.parquet`` files, one per batch of rows;
``pyarrow.parquet.read_table(DIR / "results.parquet")`` and ``pandas.read_parquet`` read them as
one table. A part is written to a hidden temporary name (``.part-...tmp``, which Parquet
readers skip) and renamed when complete, so a reader (or a killed writer) never sees half a
part. Only the client writes; workers send rows back.

Every row has a ``key`` (sha256 of the task's full configuration). :meth:`ResultStore.open`
removes the temporary files of a killed writer and, if two parts hold the same key (a task
finished twice: two clients on one directory, or a crash between writing a compacted part and
removing the parts it replaces), rewrites the dataset with each key once (the first row kept),
so the dataset holds every finished task exactly once.

Parts stay few, so that reading the keys (which tasks are done) stays fast whatever the
store's history: a writer merges its own parts into one every :data:`MERGE_EVERY` parts, and
:meth:`ResultStore.open` merges the small parts (below :data:`SMALL_PART_ROWS` rows) when it
finds more than :data:`MAX_PARTS`. A merge writes the new part before removing the old ones,
so a crash in between leaves duplicates, which the next open removes.
"""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

_counter = itertools.count()

MERGE_EVERY = 256
"""A writer merges the parts it wrote into one after this many."""

MAX_PARTS = 256
"""Above this many parts, :meth:`ResultStore.open` merges the small ones."""

SMALL_PART_ROWS = 20_000
"""Parts below this many rows are merged by :meth:`ResultStore.open`."""


class ResultStore:
    """The dataset at ``path`` (a directory) with the columns of ``schema``."""

    def __init__(self, path: str | os.PathLike[str], schema: pa.Schema) -> None:
        self.path = Path(path)
        self.schema = schema
        self._keys: set[str] | None = None  # known since open(), kept up to date by append()
        self._written: list[Path] = []  # parts this writer wrote since its last merge

    # -- reading ---------------------------------------------------------------------------

    def parts(self) -> list[Path]:
        """The complete part files, oldest first."""
        if not self.path.is_dir():
            return []
        return sorted(p for p in self.path.glob("part-*.parquet") if p.is_file())

    def read(self) -> pa.Table:
        """Every row, each key once (its first row), in the store's schema (columns a part
        lacks are null; columns the schema lacks are dropped)."""
        tables = [self._conform(pq.read_table(p)) for p in self.parts()]
        if not tables:
            return self.schema.empty_table()
        table = pa.concat_tables(tables)
        return _first_per_key(table)

    def keys(self) -> set[str]:
        """The keys present (read once by :meth:`open`, then kept up to date by :meth:`append`)."""
        if self._keys is None:
            return set(self._key_column().to_pylist())
        return set(self._keys)

    def __contains__(self, key: str) -> bool:
        return key in (self._keys if self._keys is not None else self.keys())

    def _key_column(self, parts: list[Path] | None = None) -> pa.ChunkedArray:
        """The ``key`` column of every row of ``parts`` (default: all), read in one go."""
        parts = self.parts() if parts is None else parts
        if not parts:
            return pa.chunked_array([], type=pa.string())
        import pyarrow.dataset as ds

        return ds.dataset([str(p) for p in parts], format="parquet").to_table(columns=["key"]).column("key")

    def _conform(self, table: pa.Table) -> pa.Table:
        cols = []
        for f in self.schema:
            if f.name in table.column_names:
                col = table.column(f.name)
                cols.append(col if col.type == f.type else col.cast(f.type))
            else:
                cols.append(pa.nulls(table.num_rows, f.type))
        return pa.Table.from_arrays(cols, schema=self.schema)

    # -- writing ---------------------------------------------------------------------------

    def open(self) -> "ResultStore":
        """Create the directory, drop a killed writer's temporary files, dedupe by key."""
        self.path.mkdir(parents=True, exist_ok=True)
        for tmp in self.path.glob(".part-*.tmp"):
            try:
                tmp.unlink()
            except OSError:
                pass
        parts = self.parts()
        column = self._key_column(parts)
        keys = set(column.to_pylist())
        if len(keys) != len(column):
            self._replace(parts, self.read())
        elif len(parts) > MAX_PARTS:
            small = [p for p in parts if pq.read_metadata(p).num_rows < SMALL_PART_ROWS]
            self.merge(small)
        self._keys = keys
        return self

    def merge(self, parts: list[Path]) -> None:
        """Replace ``parts`` (two or more) by one part holding their rows."""
        if len(parts) > 1:
            self._merged(parts)

    def _merged(self, parts: list[Path]) -> Path:
        return self._replace(parts, pa.concat_tables([self._conform(pq.read_table(p)) for p in parts]))

    def _replace(self, parts: list[Path], table: pa.Table) -> Path:
        dest = self._write(table)
        for p in parts:
            p.unlink()
        return dest

    def append(self, rows: Sequence[dict[str, Any]]) -> Path | None:
        """Write ``rows`` (dicts with the schema's columns; missing ones are null) as one new
        part; returns the part (``None`` without rows; the merged part when this part was
        merged with the writer's previous ones)."""
        if not rows:
            return None
        table = pa.Table.from_pylist([{f.name: r.get(f.name) for f in self.schema} for r in rows],
                                     schema=self.schema)
        part = self._write(table)
        if self._keys is not None:
            self._keys.update(str(r.get("key")) for r in rows)
        self._written.append(part)
        if len(self._written) >= MERGE_EVERY:
            part = self._merged(self._written)
            self._written = []
        return part

    def _write(self, table: pa.Table) -> Path:
        name = f"part-{time.time_ns():020d}-{os.getpid()}-{next(_counter):06d}.parquet"
        tmp, dest = self.path / f".{name}.tmp", self.path / name
        try:
            pq.write_table(table, tmp)
            with open(tmp, "rb") as fh:
                os.fsync(fh.fileno())
            os.replace(tmp, dest)
        except BaseException:
            try:
                tmp.unlink()
            except OSError:
                pass
            raise
        try:
            fd = os.open(self.path, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        except OSError:
            pass
        return dest


def _first_per_key(table: pa.Table) -> pa.Table:
    seen: set[str] = set()
    keep: list[int] = []
    for i, k in enumerate(table.column("key").to_pylist()):
        if k not in seen:
            seen.add(k)
            keep.append(i)
    return table if len(keep) == table.num_rows else table.take(pa.array(keep, type=pa.int64()))


def columns(names: Iterable[tuple[str, pa.DataType]]) -> pa.Schema:
    """A schema from ``(name, type)`` pairs."""
    return pa.schema([pa.field(n, t) for n, t in names])
