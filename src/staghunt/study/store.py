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


class ResultStore:
    """The dataset at ``path`` (a directory) with the columns of ``schema``."""

    def __init__(self, path: str | os.PathLike[str], schema: pa.Schema) -> None:
        self.path = Path(path)
        self.schema = schema

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
        """The keys present."""
        keys: set[str] = set()
        for p in self.parts():
            keys.update(str(k) for k in pq.read_table(p, columns=["key"]).column("key").to_pylist())
        return keys

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
        if parts:
            n_rows = sum(pq.read_metadata(p).num_rows for p in parts)
            if len(self.keys()) != n_rows:
                self._write(self.read())
                for p in parts:
                    p.unlink()
        return self

    def append(self, rows: Sequence[dict[str, Any]]) -> Path | None:
        """Write ``rows`` (dicts with the schema's columns; missing ones are null) as one new part."""
        if not rows:
            return None
        table = pa.Table.from_pylist([{f.name: r.get(f.name) for f in self.schema} for r in rows],
                                     schema=self.schema)
        return self._write(table)

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
