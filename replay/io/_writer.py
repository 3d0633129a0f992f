"""Writing outputs so that a reader never sees a half-written file or a half run.

- every file is written under a temporary name (`*.tmp`) and renamed when complete;
- a run's Parquet parts are written into a staging directory outside the tables, then
  each partition directory is swapped in with two renames (old -> trash, staging -> final).
Row groups and part files are cut at fixed row counts, so file boundaries depend only on
the rows, never on batch timing or the number of workers.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

import pyarrow as pa
import pyarrow.parquet as pq

ROW_GROUP_ROWS = 65_536
"""Rows per Parquet row group."""
PART_ROWS = 1_048_576
"""Rows per part file (`part-NNNNN.parquet`)."""
COMPRESSION = "zstd"


def atomic_write(path: Path, write: Callable[[BinaryIO], None]) -> None:
    """Write `path` through `write(stream)` under a temporary name, then rename it."""
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: Path, data: bytes) -> None:
    atomic_write(path, lambda fh: fh.write(data))


class PartWriter:
    """Appends Arrow tables of one schema to `part-NNNNN.parquet` files in a directory."""

    def __init__(
        self,
        directory: Path,
        schema: pa.Schema,
        *,
        row_group_rows: int | None = None,
        part_rows: int | None = None,
    ) -> None:
        self.directory = directory
        self.schema = schema
        self.row_group_rows = row_group_rows or ROW_GROUP_ROWS
        self.part_rows = part_rows or PART_ROWS
        self.files: list[str] = []
        self.rows = 0
        self._pending: list[pa.Table] = []
        self._pending_rows = 0
        self._writer: pq.ParquetWriter | None = None
        self._tmp: Path | None = None
        self._part_rows = 0
        directory.mkdir(parents=True, exist_ok=True)

    def write(self, table: pa.Table) -> None:
        if table.num_rows == 0:
            return
        self._pending.append(table)
        self._pending_rows += table.num_rows
        self.rows += table.num_rows
        while self._pending_rows >= self._next_cut():
            self._flush(self._next_cut())

    def _next_cut(self) -> int:
        """Rows of the next row group: a full group, or what the current part still takes."""
        return min(self.row_group_rows, self.part_rows - self._part_rows)

    def _flush(self, n: int) -> None:
        table = pa.concat_tables(self._pending)
        group, rest = table.slice(0, n), table.slice(n)
        self._pending = [rest] if rest.num_rows else []
        self._pending_rows = rest.num_rows
        self._write_group(group)

    def _open_part(self) -> pq.ParquetWriter:
        name = f"part-{len(self.files):05d}.parquet"
        self.files.append(name)
        self._tmp = self.directory / (name + ".tmp")
        self._writer = pq.ParquetWriter(self._tmp, self.schema, compression=COMPRESSION)
        self._part_rows = 0
        return self._writer

    def _write_group(self, group: pa.Table) -> None:
        if self._writer is None:
            self._open_part()
        assert self._writer is not None
        self._writer.write_table(group, row_group_size=group.num_rows)
        self._part_rows += group.num_rows
        if self._part_rows >= self.part_rows:
            self._close_part()

    def _close_part(self) -> None:
        assert self._writer is not None and self._tmp is not None
        self._writer.close()
        os.replace(self._tmp, self._tmp.with_suffix(""))
        self._writer = None
        self._tmp = None
        self._part_rows = 0

    def close(self) -> list[str]:
        """Write what is pending and finish the last part; an empty table gets one empty part."""
        if self._pending_rows:
            self._flush(self._pending_rows)
        if self._writer is not None:
            self._close_part()
        if not self.files:
            self._open_part()
            self._close_part()
        return list(self.files)

    def abort(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self._tmp is not None:
            self._tmp.unlink(missing_ok=True)


def swap_in(staged: Path, final: Path, trash: Path) -> None:
    """Replace directory `final` by `staged` (two renames; the old one is deleted after)."""
    final.parent.mkdir(parents=True, exist_ok=True)
    old = None
    if final.exists():
        trash.mkdir(parents=True, exist_ok=True)
        old = trash / f"{final.parent.name}-{final.name}"
        if old.exists():
            shutil.rmtree(old)
        os.rename(final, old)
    os.rename(staged, final)
    if old is not None:
        shutil.rmtree(old)


def remove_dir(final: Path, trash: Path) -> None:
    """Remove a directory readers may be looking at (renamed away first, then deleted)."""
    if not final.exists():
        return
    trash.mkdir(parents=True, exist_ok=True)
    old = trash / f"{final.parent.name}-{final.name}"
    if old.exists():
        shutil.rmtree(old)
    os.rename(final, old)
    shutil.rmtree(old)
