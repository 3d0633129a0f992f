"""Writing outputs so that a reader never sees a half-written file or a half run.

- every file is written under a temporary name (`*.tmp`) and renamed when complete;
- a run's Parquet parts (one per batch of lines and table) are written into a staging
  directory outside the tables, then each partition directory is swapped in with two
  renames (old -> trash, staging -> final).
A part holds the rows of a fixed range of lines, in row groups of a fixed row count, so the
files depend only on the input, never on timing or the number of workers.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

import pyarrow as pa
import pyarrow.parquet as pq

STATE_DIR = ".replay"
"""Private state under OUT: per-run quarantine records, the lock, staging and trash."""
ROW_GROUP_ROWS = 65_536
"""Rows per Parquet row group."""
COMPRESSION = "zstd"
PLAIN_TEXT_COLUMNS = frozenset({"output", "thinking", "action_raw"})
"""Long free-text columns: written without trying a dictionary."""


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


def write_part(table: pa.Table, path: Path, row_group_rows: int) -> None:
    """One Parquet file: row groups of `row_group_rows`, zstd, dictionary encoding tried on
    every column but the long texts (where it never pays), no min/max statistics (their
    cost is a sixth of the writing, and with one row group per part and rows in line order
    they would not let a reader skip anything). Same table, same bytes."""
    tmp = path.with_name(path.name + ".tmp")
    try:
        pq.write_table(
            table,
            tmp,
            row_group_size=row_group_rows,
            compression=COMPRESSION,
            use_dictionary=[c for c in table.column_names if c not in PLAIN_TEXT_COLUMNS],
            write_statistics=False,
        )
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


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
