"""Writing outputs so that a reader never sees a half-written file or a half run.

- every file is written whole (`Location.writer`: on disk under a temporary name `*.tmp`
  then renamed; in an object store uploaded in one write);
- a run's Parquet parts (one per batch of lines and table) are written into a staging
  directory outside the tables, then each partition directory is committed
  (`commit_dir`): on disk swapped in with two renames (old -> trash, staging -> final); in
  an object store, which cannot rename a directory, its files are moved in one by one and
  the files of the old version that the new one lacks deleted (the runner first takes the
  run out of the manifest, the commit marker: docs/SCALE.md).
A part holds the rows of a fixed range of lines, in row groups of a fixed row count, so the
files depend only on the input, never on timing or the number of workers.
"""

from __future__ import annotations

import os
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from ._durable import atomic_file
from ._fs import Location, remove_local

STATE_DIR = ".replay"
"""Private state under OUT: per-run quarantine records, the lock, staging and trash."""
ROW_GROUP_ROWS = 65_536
"""Rows per Parquet row group."""
COMPRESSION = "zstd"
PLAIN_TEXT_COLUMNS = frozenset({"output", "thinking", "action_raw"})
"""Long free-text columns: written without trying a dictionary."""


def write_part(table: pa.Table, path: Location, row_group_rows: int) -> None:
    """One Parquet file: row groups of `row_group_rows`, zstd, dictionary encoding tried on
    every column but the long texts (where it never pays), no min/max statistics (their
    cost is a sixth of the writing, and with one row group per part and rows in line order
    they would not let a reader skip anything). Same table, same bytes, wherever written."""
    options = {
        "row_group_size": row_group_rows,
        "compression": COMPRESSION,
        "use_dictionary": [c for c in table.column_names if c not in PLAIN_TEXT_COLUMNS],
        "write_statistics": False,
    }
    if path.local is None:  # made in memory, uploaded whole
        sink = pa.BufferOutputStream()
        pq.write_table(table, sink, **options)
        path.write_bytes(memoryview(sink.getvalue()))
        return
    with atomic_file(path.local, sync=False) as fh:
        pq.write_table(table, fh, **options)


def commit_dir(staged: Location, final: Location, trash: Location) -> None:
    """Replace directory `final` by `staged`: renamed in on disk (`swap_in`); elsewhere its
    files moved in one by one, then the old files it lacks deleted."""
    if staged.local is not None and final.local is not None and trash.local is not None:
        swap_in(staged.local, final.local, trash.local)
        return
    new = staged.files()
    for rel in new:
        (staged / rel).replace(final / rel)
    kept = set(new)
    for rel in final.files():
        if rel not in kept:
            (final / rel).unlink(missing_ok=True)
    staged.rmtree()


def remove_dir(final: Location, trash: Location) -> None:
    """Remove a directory readers may be looking at (on disk renamed away first, then
    deleted)."""
    if final.local is None or trash.local is None:
        final.rmtree()
        return
    final_path, trash_path = final.local, trash.local
    if not final_path.exists():
        return
    trash_path.mkdir(parents=True, exist_ok=True)
    old = trash_path / f"{final_path.parent.name}-{final_path.name}"
    remove_local(old)
    os.rename(final_path, old)
    remove_local(old)


def swap_in(staged: Path, final: Path, trash: Path) -> None:
    """Replace directory `final` by `staged` (two renames; the old one is deleted after)."""
    final.parent.mkdir(parents=True, exist_ok=True)
    old = None
    if final.exists():
        trash.mkdir(parents=True, exist_ok=True)
        old = trash / f"{final.parent.name}-{final.name}"
        remove_local(old)  # a leftover, or a link someone put there (unlinked, not followed)
        os.rename(final, old)
    os.rename(staged, final)
    if old is not None:
        remove_local(old)

