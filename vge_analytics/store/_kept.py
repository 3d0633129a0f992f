"""What the store keeps beside a local OUT, in `OUT/.metric-cache/` (docs/METRICS.md, The
metric cache): the key of OUT's contents, and each table's schema as its files unify it.

Opening an OUT reads the footer of every Parquet file to unify their schemas: 8,200 footers
at 100 times the full benchmark, seconds. The unified schema (its dictionary columns marked)
is kept in `schema-<table>-<contents>.arrow`; an OUT opened again with the same contents
builds its datasets from it, and a file's footer is read only when the file is first
scanned. `<contents>` is `contents_key`: the sha256 of the manifest and the size and
modification time of every table file, so a replay, or a file changed by hand, names
another schema file. Nothing is kept for an OUT without a manifest or one in object storage;
an OUT that cannot be written keeps nothing and is read as before.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import stat
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import replay
from replay.io import METRIC_CACHE_DIR, atomic_file, schema_cache_path

if TYPE_CHECKING:
    import polars as pl
    import pyarrow as pa

T = TypeVar("T")

Files = Mapping[str, Sequence[tuple[str, str | None]]]
"""table -> (path relative to OUT, run) of each of its files (`_contents.table_files`)."""


def contents_key(out: replay.Location, files: Files, digest: str | None) -> str | None:
    """A hash of OUT's manifest (`digest`, its sha256) and of the size and modification time
    of every table file; None for an OUT in object storage or without a manifest, or when a
    file cannot be looked at."""
    if out.local is None or digest is None:
        return None
    h = hashlib.sha256(digest.encode())
    try:
        for table in sorted(files):
            for name, _ in files[table]:
                st = os.stat(os.path.join(out.local, name))
                h.update(f"\0{name}\0{st.st_size}\0{st.st_mtime_ns}".encode())
    except OSError:
        return None
    return h.hexdigest()[:16]


def own_folder(out: Path) -> bool:
    """Whether `OUT/.metric-cache` may be used: absent, or a folder that is no link (one
    planted as a link to elsewhere would have the cache write and delete files there)."""
    folder = out / METRIC_CACHE_DIR
    return not folder.is_symlink() and (folder.is_dir() or not folder.exists())


def read_kept(path: Path, limit: int) -> bytes | None:
    """The bytes of a file kept in the cache folder, or None: absent, a link (never followed),
    not a regular file (a FIFO planted there opens at once, `O_NONBLOCK`, and is not read),
    over `limit` bytes, or unreadable."""
    try:
        handle = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(handle).st_mode):
            return None
        with os.fdopen(handle, "rb", closefd=False) as fh:
            data = fh.read(limit + 1)
    except OSError:
        return None
    finally:
        os.close(handle)
    return data if len(data) <= limit else None


def prune_kept(kept: Path, pattern: str, limit: int) -> None:
    """Remove the files of `pattern` (`<kind>-<contents>-<key>.<ext>`) beside `kept` that were
    kept for other contents of OUT than `kept`'s, then the oldest past `limit` in all."""
    contents = kept.name.split("-")[1]
    alive: list[tuple[int, str, Path]] = []
    for path in kept.parent.glob(pattern):
        with contextlib.suppress(OSError):
            if path.name.split("-")[1] != contents:
                path.unlink()
            elif path != kept:
                alive.append((path.lstat().st_mtime_ns, path.name, path))
    alive.sort()
    for _, _, path in alive[: max(0, len(alive) - (limit - 1))]:
        with contextlib.suppress(OSError):
            path.unlink()


def read_kept_frame(
    path: Path, limit: int, columns: Sequence[str] | None = None, rows: int | None = None
):
    """The Parquet frame kept at `path` (`columns` of it, its first `rows` rows: 0 for its
    columns and types alone), read as `read_kept` reads a file (no link, no FIFO, within
    `limit` bytes), or None when it cannot be had: absent, not Parquet, without those
    columns. By polars: 9.3 million rows in 0.7 s, pyarrow 7.7 s."""
    import io

    import polars as pl  # (here: the CLI's start reads the folder without it)

    data = read_kept(path, limit)
    if data is None:
        return None
    try:
        return pl.read_parquet(
            io.BytesIO(data), columns=list(columns) if columns else None, n_rows=rows
        )
    except (OSError, pl.exceptions.PolarsError, ValueError):
        return None


def read_kept_footed(path: Path, limit: int, name: str) -> tuple[pl.DataFrame, str] | None:
    """The Parquet frame kept at `path`, read as `read_kept_frame` reads it, and the value
    its footer holds under `name` (`keep_parts`' `footer`), or None: no such frame, or none
    kept under `name`."""
    import io

    import polars as pl

    data = read_kept(path, limit)
    if data is None:
        return None
    try:
        footer = pl.read_parquet_metadata(io.BytesIO(data)).get(name)
        frame = pl.read_parquet(io.BytesIO(data)) if footer is not None else None
    except (OSError, pl.exceptions.PolarsError, ValueError):
        return None
    return None if frame is None else (frame, footer)


def kept_frame(
    path: Path,
    read: Callable[[Path], pl.DataFrame | None],
    compute: Callable[[], pl.DataFrame],
    pattern: str,
    limit: int,
    footer: Callable[[], Mapping[str, str]] | None = None,
) -> pl.DataFrame:
    """The polars frame `read(path)` gives (None: no valid frame kept there), else
    `compute()`, kept at `path` as Parquet, written whole or not at all (not when OUT cannot be
    written), and the files of `pattern` pruned (`prune_kept`, at most `limit`); `footer()`,
    asked once `compute()` returned: what the file's footer holds besides (`keep_parts`)."""
    import polars as pl

    kept = read(path)
    if kept is not None:
        return kept
    frame = compute()
    with contextlib.suppress(pl.exceptions.PolarsError):
        keep_parts(path, [frame], pattern, limit, footer() if footer is not None else None)
    return frame


def keep_parts(
    path: Path,
    parts: Iterable[pl.DataFrame],
    pattern: str,
    limit: int,
    footer: Mapping[str, str] | None = None,
) -> bool:
    """Write the frames `parts` (one schema), each as it comes, to `path` as one Parquet file,
    whole or not at all, and prune the files of `pattern` (`prune_kept`, at most `limit`):
    a large result is written without holding all of it. `footer`: names and values kept in
    the file's footer (its key-value metadata; `read_kept_footed`). False when OUT cannot be
    written (read-only, full: nothing kept); a failure of a part's query is raised (the file
    is not left behind)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from replay import OutputError

    try:
        path.parent.mkdir(exist_ok=True)
        with atomic_file(path, sync=False) as fh:
            writer = None
            try:
                for part in parts:
                    table = part.to_arrow()
                    if writer is None:
                        schema = table.schema.with_metadata(footer) if footer else table.schema
                        writer = pq.ParquetWriter(fh, schema, compression="zstd")
                    writer.write_table(table.cast(writer.schema))
            finally:
                if writer is not None:
                    writer.close()
            if writer is None:
                raise OSError(f"{path}: nothing to write")  # (no part: no schema)
    except (OSError, OutputError, pa.ArrowException):
        return False
    prune_kept(path, pattern, limit)
    return True


def unless_failed(compute: Callable[[], T]) -> T | None:
    """`compute()` (which reads or computes and keeps a file), or None when it failed in a
    way the tables answer around (an OUT that cannot be written, a term that fails); a bound
    that stopped its query is raised: the tables' query would be stopped the same way."""
    import duckdb
    import polars as pl

    from .._errors import QueryError, QueryLimitError

    try:
        return compute()
    except QueryLimitError:
        raise
    except (OSError, duckdb.Error, pl.exceptions.PolarsError, QueryError):
        return None


def kept_schema(out: replay.Location, table: str, key: str | None) -> pa.Schema | None:
    """The unified schema of `table` kept for contents `key`, or None."""
    import pyarrow as pa  # (here: the key and the folder's check are read without it)

    if key is None or not own_folder(out.local):
        return None
    data = read_kept(schema_cache_path(out.local, table, key), 1 << 20)
    if data is None:
        return None
    try:
        return pa.ipc.read_schema(pa.py_buffer(data))
    except pa.ArrowException:
        return None


def keep_schema(out: replay.Location, table: str, key: str | None, schema: pa.Schema) -> None:
    """Keep `schema` for contents `key` (nothing when OUT cannot be written), and remove the
    schemas of `table` kept for other contents."""
    if key is None or not own_folder(out.local):
        return
    path = schema_cache_path(out.local, table, key)
    with contextlib.suppress(OSError):
        path.parent.mkdir(exist_ok=True)
        with atomic_file(path, sync=False) as fh:
            fh.write(schema.serialize().to_pybytes())
        for old in path.parent.glob(f"schema-{table}-*.arrow"):
            if old.name != path.name:
                old.unlink()


__all__ = [
    "Files",
    "contents_key",
    "keep_parts",
    "kept_frame",
    "keep_schema",
    "kept_schema",
    "own_folder",
    "prune_kept",
    "read_kept",
    "read_kept_footed",
    "read_kept_frame",
    "unless_failed",
]
