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
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import PurePosixPath

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as pads
import pyarrow.fs as pafs

import replay
from replay.io import (
    RUNS_TABLE,
    TABLE_ROWS,
    TABLES,
    manifest_path,
    runs_table,
)

from .._errors import OutputDirError
from ._kept import contents_key, keep_schema, kept_schema

SCAN_OPTIONS: Mapping[str, int] = {
    "batch_size": 16_384,
    "batch_readahead": 2,
    "fragment_readahead": 2,
}
"""Scanner options of every scan: batches of 16,384 rows (8 of DuckDB's vectors), two batches
and two files read ahead (pyarrow's defaults, 131,072 rows, 16 batches and 4 files, decode
dozens of MB before a LIMIT can stop them)."""


class _Dataset(pads.FileSystemDataset):
    """A pyarrow dataset whose scanners take `SCAN_OPTIONS`. DuckDB asks the dataset for a
    scanner with the columns and filter it pushes down; the rest is set here."""

    def scanner(self, *args, **kwargs) -> pads.Scanner:  # type: ignore[override]
        return super().scanner(*args, **{**SCAN_OPTIONS, **kwargs})


def empty_table(table: str) -> pa.Table:
    """A table of OUT with no row: the replay's columns."""
    if table == RUNS_TABLE:  # the fixed columns the replay writes (no meta_* without a run)
        return runs_table([])
    return replay.arrow_schema(TABLE_ROWS[table]).empty_table()


def _refuse(out: replay.Location, what: str) -> OutputDirError:
    return OutputDirError(f"{manifest_path(out)}: {what}")


def _real(path: str, folders: dict[str, str], *, keep: bool = False) -> str:
    """`os.path.realpath(path)`, built from its folder's, each folder resolved once
    (`folders` keeps them, `keep`): a path that is no link is its resolved folder's entry."""
    hit = folders.get(path)
    if hit is not None:
        return hit
    folder, _, entry = path.rpartition("/")
    if not folder or os.path.islink(path):
        real = os.path.realpath(path)
    else:
        real = f"{_real(folder, folders, keep=True).rstrip('/')}/{entry}"
    if keep:
        folders[path] = real
    return real


def _checked(
    out: replay.Location, table: str, name: object, who: str, folders: dict[str, str]
) -> str:
    """`name` if it is the path of a file of `table` inside OUT, else the error; `who`: what
    listed it, as the message says it (`OUT/manifest.json: run 'x' lists`); `folders`: the
    folders resolved so far (`_real`; OUT's own under "")."""
    if not isinstance(name, str):
        raise OutputDirError(f"{who} {name!r} as a {table} file (not a path)")
    parts = PurePosixPath(name).parts
    if name.startswith("/") or ".." in parts or parts[:1] != (table,):
        raise OutputDirError(f"{who} {name!r}, which is not a file of {table}/ in OUT")
    if out.local is not None:
        if "" not in folders:
            folders[""] = os.path.realpath(out.local)
        inside = folders[""]
        real = os.path.normpath(_real(os.path.join(out.local, name), folders))
        if os.path.commonpath([inside, real]) != inside:
            raise OutputDirError(f"{who} {name!r}, which leads outside OUT ({real})")
    return name


def _listed(out: replay.Location, manifest: Mapping, table: str) -> list[tuple[str, str | None]]:
    """(path, run) of each file of `table` the manifest lists, checked."""
    runs = manifest.get("runs", [])
    if not isinstance(runs, list):
        raise _refuse(out, "'runs' is not a list")
    found: list[tuple[str, str | None]] = []
    folders: dict[str, str] = {}
    for run in runs:
        run_id = run.get("run_id") if isinstance(run, dict) else None
        outputs = run.get("outputs") if isinstance(run, dict) else None
        names = outputs.get(table) if isinstance(outputs, dict) else None
        if not isinstance(run_id, str) or not isinstance(names, list):
            raise _refuse(out, f"a run without a run_id and its {table} files ({str(run)[:80]})")
        who = f"{manifest_path(out)}: run {run_id!r} lists"
        found += [(_checked(out, table, name, who, folders), run_id) for name in names]
    return sorted(found)


def table_files(
    out: replay.Location, manifest: Mapping | None, table: str
) -> list[tuple[str, str | None]]:
    """(path relative to OUT, the run whose rows it holds, or None) of each file of a table."""
    if table == RUNS_TABLE:
        names = [f"{RUNS_TABLE}/{n}" for n in (out / RUNS_TABLE).names() if n.endswith(".parquet")]
    elif manifest is None:  # a local OUT without a manifest: its folders, file by file
        names = [f"{table}/{rel}" for rel in (out / table).files() if rel.endswith(".parquet")]
    else:
        return _listed(out, manifest, table)
    folders: dict[str, str] = {}
    who = f"{out}: OUT holds"
    return [(_checked(out, table, name, who, folders), None) for name in names]


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
    fs = out.fs if out.fs is not None else pafs.LocalFileSystem()
    base = out.path.rstrip("/")
    paths = [f"{base}/{name}" for name, _ in files]
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
    return _Dataset(fragments, schema, read_as, fs)


def table_sources(
    out: replay.Location, manifest: Mapping | None, digest: str | None = None
) -> tuple[dict[str, object], str | None]:
    """Each table of OUT as an Arrow dataset over its files (an empty Arrow table when it has
    none), and the key of OUT's contents (`_kept.contents_key`; `digest`: the sha256 of its
    manifest). Raises `OutputDirError` for a path outside OUT; pyarrow's errors pass
    through."""
    files = {table: table_files(out, manifest, table) for table in TABLES}
    key = contents_key(out, files, digest)
    sources: dict[str, object] = {}
    for table in TABLES:
        if not files[table]:
            sources[table] = empty_table(table)
            continue
        schema = kept_schema(out, table, key)
        sources[table] = _dataset(out, files[table], schema)
        if schema is None:
            keep_schema(out, table, key, sources[table].schema)
    return sources, key


__all__ = ["SCAN_OPTIONS", "empty_table", "table_files", "table_sources"]
