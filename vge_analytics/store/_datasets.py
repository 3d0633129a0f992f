"""The four tables of an OUT as Arrow datasets over exactly its Parquet files, for DuckDB to scan.

Which files: the ones the manifest lists per run (`runs[].outputs`; on object storage a
listing may catch a run mid-commit, the manifest never does, docs/SCALE.md), and the Parquet
files of `runs/`. A local OUT without a manifest is listed directory by directory. Every path
is a name joined to OUT, never a pattern: pyarrow opens it as it is, so an OUT named
`out[12]` reads its own files, not those of `out1` and `out2` (DuckDB's `read_parquet` would
expand the brackets, and has no escape for every name). A listed path must stay inside OUT
(relative, no `..`, under its table's folder; on the local disk, symbolic links resolved);
anything else is refused in one line naming the manifest.

How they are read, so that scanning them costs about what DuckDB's own reader does:
- each file of a run is a fragment known to hold that run's rows only (its partition
  expression), so `WHERE run_id = ...` skips the other runs' files;
- the string columns stored with a dictionary in every file (all but the long free texts)
  are read as dictionaries: grouping on `run_id` or `error_type` hashes small integers;
- scans read ahead little (`SCAN_OPTIONS`): a `LIMIT 100` decodes a few thousand rows, not
  several row groups of every column.

What is built when (docs/PERFORMANCE.md, Start-up): the runs table, a row per run, is read
whole into memory when its files are small (`RUNS_IN_MEMORY`); a table whose unified schema is
kept (`_kept`) is a `Deferred` table, its dataset built when a query first names it, so that a
command the metric cache answers never imports pyarrow's dataset module (which imports pandas,
half a second).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING

import pyarrow as pa
import pyarrow.fs as pafs
import pyarrow.parquet as pq

import replay
from replay.io import PARTITION_KEY, RUNS_TABLE, TABLES

from ._contents import table_files
from ._kept import contents_key, keep_schema, kept_schema

if TYPE_CHECKING:
    import pyarrow.dataset as pads

SCAN_OPTIONS: Mapping[str, int] = {
    "batch_size": 16_384,
    "batch_readahead": 2,
    "fragment_readahead": 2,
}
"""Scanner options of every scan: batches of 16,384 rows (8 of DuckDB's vectors), two batches
and two files read ahead (pyarrow's defaults, 131,072 rows, 16 batches and 4 files, decode
dozens of MB before a LIMIT can stop them)."""


RUNS_IN_MEMORY = 64 << 20
"""The runs table is read whole when its files hold at most this many bytes (a row per run:
kilobytes; a larger one, made by hand, is scanned as the other tables are)."""


@functools.cache
def _dataset_class() -> type:
    """`_Dataset`: a pyarrow dataset whose scanners take `SCAN_OPTIONS` (DuckDB asks the
    dataset for a scanner with the columns and filter it pushes down; the rest is set
    here). Made when first needed: pyarrow's dataset module is slow to import."""
    import pyarrow.dataset as pads

    class _Dataset(pads.FileSystemDataset):
        def scanner(self, *args, **kwargs) -> pads.Scanner:  # type: ignore[override]
            return super().scanner(*args, **{**SCAN_OPTIONS, **kwargs})

    return _Dataset


class Deferred:
    """A table whose Arrow source (a dataset over its files) is made when first asked for
    (`source`), once; `schema`, its columns, is known before."""

    def __init__(self, schema: pa.Schema, make: Callable[[], object]) -> None:
        self.schema = schema
        self._make: Callable[[], object] | None = make
        self._source: object = None
        self._lock = threading.Lock()

    @property
    def built(self) -> bool:
        """Whether its source has been made."""
        return self._make is None

    def source(self) -> object:
        with self._lock:
            if self._make is not None:
                self._source, self._make = self._make(), None
            return self._source


def run_files(source: object) -> dict[str, list[str]] | None:
    """{run: the paths of its files} of a table's `source` (of `Store.sources`; a `Deferred`
    one built) when it is a dataset over files on the local disk, each file's run its
    fragment's partition (the manifest's run that lists the file), in the dataset's order;
    else None (in memory, in object storage, or a file of no run)."""
    import pyarrow.dataset as pads

    if isinstance(source, Deferred):
        source = source.source()
    if not isinstance(source, pads.FileSystemDataset) or not isinstance(
        source.filesystem, pafs.LocalFileSystem
    ):
        return None
    files: dict[str, list[str]] = {}
    for fragment in source.get_fragments():
        run = pads.get_partition_keys(fragment.partition_expression).get(PARTITION_KEY)
        if not isinstance(run, str):
            return None
        files.setdefault(run, []).append(fragment.path)
    return files


def empty_table(table: str) -> pa.Table:
    """A table of OUT with no row: the replay's columns."""
    from replay.io import TABLE_ROWS, runs_table  # the row types: replay.semantics

    if table == RUNS_TABLE:  # the fixed columns the replay writes (no meta_* without a run)
        return runs_table([])
    return replay.arrow_schema(TABLE_ROWS[table]).empty_table()


def _dictionary_columns(fragments: Iterable[pads.ParquetFileFragment], schema: pa.Schema) -> set:
    """String columns stored with a dictionary page in every row group of every file."""
    columns = {f.name for f in schema if pa.types.is_string(f.type)}
    for fragment in fragments:
        meta = fragment.metadata
        names = meta.schema.names
        for group in range(meta.num_row_groups):
            row_group = meta.row_group(group)
            columns = {
                c
                for c in columns
                if c not in names or row_group.column(names.index(c)).has_dictionary_page
            }
    return columns


def _unified(fs: pafs.FileSystem, paths: list[str]) -> pa.Schema:
    """The schema of the files at `paths`, unified by column name, a string column stored
    with a dictionary in every file typed as a dictionary (read as one)."""
    import pyarrow.dataset as pads

    plain = pads.ParquetFileFormat()
    first = [plain.make_fragment(p, fs) for p in paths]
    schema = pa.unify_schemas([f.physical_schema for f in first], promote_options="permissive")
    dictionaries = _dictionary_columns(first, schema)
    return pa.schema(
        f.with_type(pa.dictionary(pa.int32(), f.type)) if f.name in dictionaries else f
        for f in schema
    ).with_metadata(schema.metadata)


def _dataset(
    out: replay.Location, files: list[tuple[str, str | None]], schema: pa.Schema | None = None
) -> pads.Dataset:
    """One dataset over `files`, their schemas unified by column name as DuckDB's
    `union_by_name` does (a column some files lack is null there); `schema`: that unified
    schema when it is known (`_kept`), else read from every file's footer."""
    import pyarrow.compute as pc
    import pyarrow.dataset as pads

    fs, paths = _paths(out, files)
    if schema is None:
        schema = _unified(fs, paths)
    dictionaries = [f.name for f in schema if pa.types.is_dictionary(f.type)]
    read_as = pads.ParquetFileFormat(
        read_options=pads.ParquetReadOptions(dictionary_columns=dictionaries),
        # On the local disk, a row group's columns are read when it is scanned: pre-buffering
        # reads every scanned column of the whole file at once, so memory grew with the part
        # (a part of long responses held all of them). A store fetches them ahead, to save
        # round trips.
        default_fragment_scan_options=pads.ParquetFragmentScanOptions(pre_buffer=out.local is None),
    )
    fragments = [
        read_as.make_fragment(
            path, fs, partition_expression=None if run is None else pc.field("run_id") == run
        )
        for path, (_, run) in zip(paths, files, strict=True)
    ]
    # A fragment's footer is read when it is first scanned, and kept (a query that reads no
    # file of a table, one the metric cache answers, reads none).
    return _dataset_class()(fragments, schema, read_as, fs)


def _paths(
    out: replay.Location, files: list[tuple[str, str | None]]
) -> tuple[pafs.FileSystem, list[str]]:
    """OUT's filesystem, and the path of each of `files` on it."""
    fs = out.fs if out.fs is not None else pafs.LocalFileSystem()
    base = out.path.rstrip("/")
    return fs, [f"{base}/{name}" for name, _ in files]


def _whole(
    out: replay.Location, files: list[tuple[str, str | None]], schema: pa.Schema | None
) -> pa.Table | None:
    """The rows of `files` in memory, as a dataset over them scans them (in this order, each
    file's columns typed as the unified `schema` has them, a column a file lacks null), or
    None when their footers say they hold more than `RUNS_IN_MEMORY` bytes."""
    fs, paths = _paths(out, files)
    if schema is None:
        schema = _unified(fs, paths)
    dictionaries = [f.name for f in schema if pa.types.is_dictionary(f.type)]
    parts, size = [], 0
    for path in paths:
        with fs.open_input_file(path) as fh:
            plain = pq.ParquetFile(fh)
            meta = plain.metadata
            size += sum(meta.row_group(g).total_byte_size for g in range(meta.num_row_groups))
            if size > RUNS_IN_MEMORY:
                return None
            held = set(plain.schema_arrow.names)
            read_as = [name for name in dictionaries if name in held]
            part = pq.ParquetFile(fh, metadata=meta, read_dictionary=read_as).read()
        columns = []
        for field in schema:
            at = part.schema.get_field_index(field.name)
            column = pa.nulls(part.num_rows, field.type) if at < 0 else part.column(at)
            # (cast only when needed: a cast imports pyarrow.compute, a tenth of a second)
            columns.append(column if column.type == field.type else column.cast(field.type))
        parts.append(pa.Table.from_arrays(columns, schema=schema))
    return pa.concat_tables(parts)


def table_sources(
    out: replay.Location, manifest: Mapping | None, digest: str | None = None
) -> tuple[dict[str, object], str | None]:
    """Each table of OUT as an Arrow dataset over its files (an empty Arrow table when it has
    none; the runs table read whole when small, `_whole`; a `Deferred` dataset when its schema
    is kept), and the key of OUT's contents (`_kept.contents_key`; `digest`: the sha256 of
    its manifest). Raises `OutputDirError` for a path outside OUT; pyarrow's errors pass
    through."""
    files = {table: table_files(out, manifest, table) for table in TABLES}
    key = contents_key(out, files, digest)
    sources: dict[str, object] = {}
    for table in TABLES:
        if not files[table]:
            sources[table] = empty_table(table)
            continue
        schema = kept_schema(out, table, key)
        source = _whole(out, files[table], schema) if table == RUNS_TABLE else None
        if source is None and schema is not None:
            source = Deferred(schema, functools.partial(_dataset, out, files[table], schema))
        elif source is None:
            source = _dataset(out, files[table])
        sources[table] = source
        if schema is None:
            keep_schema(out, table, key, source.schema)
    return sources, key


__all__ = [
    "RUNS_IN_MEMORY",
    "SCAN_OPTIONS",
    "Deferred",
    "empty_table",
    "run_files",
    "table_files",
    "table_sources",
]
