"""A replay output directory (PROTOCOL §7) opened for DuckDB, cached per directory.

`open_store(out)` returns one `Store` per OUT (re-opened when its contents change): a DuckDB
connection on which every cursor sees the tables `steps episodes goals runs`, plus the column
catalogue used to validate every grouping or filter column before it is quoted into a query.

The tables are Arrow datasets over exactly the Parquet files OUT's manifest lists
(`_datasets`), read by pyarrow, locally or through its filesystem for a URI (`s3://bucket/out
?...`, `gs://...`; docs/SCALE.md; `file://` is the local directory). DuckDB scans them and
reads no file itself: its connection (`_locked`) has no file access at all, an empty catalog
opened read-only, no extensions, its memory capped (`memory_limit`, spilling to a private
temporary directory capped by `max_temp_directory_size`; see `_limits`), and
`lock_configuration = true` makes all of it final. Every query, ours or a user's (`vge sql`),
runs on a cursor of that connection (`Store.cursor`, which registers the tables on it). A
store is cached per (directory, memory limits).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import re
import tempfile
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import duckdb
import pyarrow as pa

import replay
from replay.io import MANIFEST, PARTITIONED, RUNS_TABLE, TABLES, manifest_path

from .._errors import OutputDirError, UnknownRunError
from ._bounds import store_limits
from ._contents import manifest_and_digest, no_collection, read_manifest
from ._datasets import Deferred, empty_table, table_sources
from ._limits import SqlLimits
from ._locked import locked_connection, register_all

NUMERIC_TYPES: tuple[str, ...] = (
    "TINYINT",
    "SMALLINT",
    "INTEGER",
    "BIGINT",
    "HUGEINT",
    "UTINYINT",
    "USMALLINT",
    "UINTEGER",
    "UBIGINT",
    "UHUGEINT",
    "FLOAT",
    "DOUBLE",
)
"""DuckDB's number types (and DECIMAL(p, s))."""
_SCALAR_TYPES = ("BOOLEAN", *NUMERIC_TYPES, "VARCHAR", "DATE", "TIMESTAMP")


def _signature(out: Path) -> tuple:
    """Cheap fingerprint of OUT: changes when a replay rewrites it."""
    parts = []
    for name in (MANIFEST, RUNS_TABLE, *PARTITIONED):
        p = out / name
        try:
            st = p.stat()
            parts.append((name, st.st_mtime_ns, st.st_size))
        except OSError:
            parts.append((name, None, None))
        if p.is_dir() and name != RUNS_TABLE:
            with contextlib.suppress(OSError):
                parts.append(tuple(sorted(c.name for c in p.iterdir())))
    return tuple(parts)


@dataclass
class Store:
    """An opened OUT directory: DuckDB connection, column catalogue, manifest."""

    out: Path | replay.Location
    """A local directory, or a location in object storage."""
    con: duckdb.DuckDBPyConnection
    columns: dict[str, dict[str, str]]
    """table -> {column: DuckDB type}, in table order."""
    manifest: dict
    """What the store read of OUT's manifest: each run's id, files and benchmark, the totals,
    the engine version (`run_entry` reads a run's whole entry)."""
    sources: Mapping[str, object] = field(default_factory=dict)
    """The tables, by name: Arrow datasets over OUT's files (`_datasets.table_sources`, some
    `Deferred`: built when a query names them), or Arrow tables in memory (`memory_store`)."""
    in_memory: bool = False
    """Its tables are Arrow tables held in this process (`memory_store`), not OUT's files: a
    query process is handed the tables, not OUT."""
    limits: SqlLimits | None = None
    """The memory limits its connection was opened with."""
    digest: str | None = None
    """The sha256 of OUT's manifest as read (a local OUT with one), else None."""
    contents: str | None = None
    """The key of OUT's contents (`_kept.contents_key`: what the metric cache is keyed by),
    None where nothing is cached."""
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def cursor(self, statement: str | None = None) -> duckdb.DuckDBPyConnection:
        """A cursor for one query, the tables registered on it (cursors of one connection may
        run in different threads; what one registers or creates, no other sees).
        `statement`: the one statement of the analytics' own the cursor is for; a `Deferred`
        table its text does not name is left out, unbuilt (a query the metric cache
        answers opens no file of OUT, and needs no dataset)."""
        with self._lock:
            cursor = self.con.cursor()
        register_all(cursor, _registered(self.sources, statement))
        return cursor

    def close(self) -> None:
        """Close its connection (a store of `memory_store`; `open_store`'s are cached)."""
        self.con.close()

    def has_column(self, table: str, name: str) -> bool:
        return name in self.columns[table]

    def is_scalar(self, table: str, name: str) -> bool:
        return self.columns[table][name].upper() in _SCALAR_TYPES

    @property
    def meta_columns(self) -> list[str]:
        """Run facet columns (`meta_<key>`) of the runs table."""
        return [c for c in self.columns[RUNS_TABLE] if c.startswith("meta_")]

    def run_ids(self) -> list[str]:
        statement = "SELECT DISTINCT run_id FROM runs ORDER BY run_id"
        rows = self.cursor(statement).execute(statement).fetchall()
        return [r[0] for r in rows]


def _names(statement: str, table: str) -> bool:
    """Whether the text of `statement` holds the name `table` as a word (in any case, quoted
    or not, in a comment too: more tables registered than read is only slower)."""
    return (
        re.search(rf"(?<![\w$]){re.escape(table)}(?![\w$])", statement, re.IGNORECASE) is not None
    )


def _registered(sources: Mapping[str, object], statement: str | None) -> dict[str, object]:
    """What a cursor for `statement` (None: any) registers of `sources`: a `Deferred` table
    its dataset (built now, once), or nothing when `statement` does not name it."""
    kept: dict[str, object] = {}
    for name, source in sources.items():
        if isinstance(source, Deferred):
            if statement is not None and not _names(statement, name):
                continue
            source = source.source()
        kept[name] = source
    return kept


_SPILL_DIRS = itertools.count()


def _spill_directory() -> str:
    """A temporary directory of its own for each connection: DuckDB creates it when it first
    spills and removes it when the connection closes (its default, `.tmp` in the current
    directory, would litter wherever the command runs)."""
    name = f"vge-sql-{os.getpid()}-{next(_SPILL_DIRS)}"
    return str(Path(tempfile.gettempdir()) / name)


def _connection(limits: SqlLimits) -> duckdb.DuckDBPyConnection:
    """A locked connection (`_locked`) within `limits`."""
    return locked_connection(
        settings=[
            ("memory_limit", f"{limits.memory}B"),
            ("temp_directory", _spill_directory()),
            ("max_temp_directory_size", f"{limits.spill}B"),
        ]
    )


def resolve_input(out: str | Path | replay.Location, recorded: str) -> Path | replay.Location:
    """An input path as the manifest records it (as given to `vge replay`): a URI
    (`s3://...`, opened as it is), absolute, or relative to the directory the replay ran in,
    which is not recorded: the current directory is tried first, then OUT's parent
    (`vge replay ... --out OUT` run next to OUT). Returns the path as recorded when neither
    exists (the caller reports it)."""
    if replay.is_uri(recorded):
        return replay.location(recorded)
    path = Path(recorded)
    if path.is_absolute() or path.exists():
        return path
    if isinstance(out, replay.Location):
        if out.local is None:  # nothing is beside an OUT in object storage
            return path
        out = out.local
    beside = Path(out).resolve().parent / path
    return beside if beside.exists() else path


def _entry(runs: list, run_id: str, out: object) -> dict:
    for entry in runs:
        if entry.get("run_id") == run_id:
            return entry
    raise UnknownRunError(f"run {run_id!r} is not in {out}/{MANIFEST}")


def run_entry(out: str | Path | replay.Location, run_id: str) -> dict:
    """The manifest's entry of a run (its inputs, options, counts)."""
    return _entry((read_manifest(replay.location(out)) or {}).get("runs", []), run_id, out)


def bench_dir(out: str | Path, run_id: str | None = None) -> Path | replay.Location:
    """The benchmark directory a run (default: the first run) was replayed against (from the
    manifest as the store decoded it: parsing a 156 MB manifest again took seconds a picture)."""
    runs = open_store(out).manifest.get("runs", [])
    if not runs:
        raise OutputDirError(f"{out}: the manifest lists no run")
    entry = _entry(runs, run_id, out) if run_id is not None else runs[0]
    bench = resolve_input(out, entry["inputs"]["bench"])
    if not bench.is_dir():
        raise OutputDirError(
            f"benchmark {entry['inputs']['bench']} (recorded in {out}/{MANIFEST}) not found: "
            "start the app from the directory `vge replay` ran in"
        )
    return bench


def _store(
    out: Path | replay.Location, manifest: dict | None, limits: SqlLimits, digest: str | None = None
) -> Store:
    """The store over OUT's tables (`manifest` None: a local OUT without one; `digest`: the
    sha256 of a local manifest's bytes)."""
    try:
        sources, contents = table_sources(replay.location(out), manifest, digest)
    except (OSError, ValueError, pa.ArrowException) as exc:  # pyarrow's ArrowInvalid: both
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise OutputDirError(f"{out}: cannot read the Parquet tables ({first})") from None
    try:
        store = _opened(out, manifest or {}, sources, limits)
    except duckdb.Error as exc:
        raise OutputDirError(f"{out}: cannot read the Parquet tables ({exc})") from None
    store.digest, store.contents = digest, contents
    return store


def _opened(
    out: Path | replay.Location,
    manifest: dict,
    sources: Mapping[str, object],
    limits: SqlLimits,
    *,
    in_memory: bool = False,
) -> Store:
    """A store over `sources` on a new locked connection within `limits`, its catalogue read."""
    con = _connection(limits)
    store = Store(
        out=out,
        con=con,
        columns={},
        manifest=manifest,
        sources=sources,
        in_memory=in_memory,
        limits=limits,
    )
    try:
        store.columns = _catalogue(store)
    except BaseException:
        con.close()
        raise
    return store


def memory_store(
    tables: Mapping[str, pa.Table],
    *,
    label: Path | replay.Location,
    limits: SqlLimits | None = None,
) -> Store:
    """A store over Arrow tables held in memory (the episode rows a sweep replays at each
    lambda), on a locked connection within `limits` (default: the block's, `query_limits`)
    as an OUT's store is: every query over it, a metric file's expressions included, meets
    the same guard and bounds (`guarded_cursor`, `run_query`). A table not given is empty, with the replay's columns.
    `label` is how messages name it (the OUT the tables come from). Not cached: the caller
    closes it (`Store.close`)."""
    sources = {t: tables[t] if t in tables else empty_table(t) for t in TABLES}
    return _opened(label, {}, sources, limits or store_limits(), in_memory=True)


def _open(out: Path, limits: SqlLimits) -> Store:
    if not out.is_dir():
        raise OutputDirError(f"{out}: replay output directory not found")
    missing = [t for t in PARTITIONED if not (out / t).is_dir()]
    if missing:
        raise OutputDirError(
            f"{out}: not a replay output directory (no {'/, '.join(missing)}/); "
            "run `vge replay ... --out` first"
        )
    with no_collection():
        manifest, digest = manifest_and_digest(out)
        return _store(out, manifest, limits, digest)


def _open_remote(out: replay.Location, limits: SqlLimits) -> Store:
    try:
        data = manifest_path(out).read_bytes()
    except FileNotFoundError:
        raise OutputDirError(
            f"{out}: not a replay output (no {MANIFEST}); run `vge replay ... --out {out}` first"
        ) from None
    except OSError as exc:
        raise OutputDirError(f"{out}: cannot read it ({exc})") from None
    try:
        manifest = json.loads(data.decode("utf-8"))
    except ValueError as exc:
        raise OutputDirError(f"{out}: unreadable manifest ({exc})") from None
    if not isinstance(manifest, dict):
        raise OutputDirError(f"{out}: unreadable manifest (not a JSON object)")
    return _store(out, manifest, limits)


def _catalogue(store: Store) -> dict[str, dict[str, str]]:
    """Each table's columns and their DuckDB types (a `Deferred` table's from its schema,
    without building its dataset)."""
    columns: dict[str, dict[str, str]] = {}
    with store._lock:
        cursor = store.con.cursor()
    described = {
        # (not `schema.empty_table()`, which imports pandas)
        name: pa.Table.from_batches([], source.schema) if isinstance(source, Deferred) else source
        for name, source in store.sources.items()
    }
    register_all(cursor, described)
    try:
        for table in TABLES:
            rows = cursor.execute(f"DESCRIBE {table}").fetchall()  # table names are constants
            columns[table] = {r[0]: str(r[1]) for r in rows}
    finally:
        cursor.close()
    return columns


def _remote_signature(out: replay.Location) -> tuple:
    """Fingerprint of a remote OUT: its manifest, which the replay writes last, after every
    table file (the commit marker of object storage, docs/SCALE.md)."""
    try:
        return ("manifest", manifest_path(out).read_bytes())
    except OSError:
        return ("manifest", None)


_CACHE: dict[tuple[str, int, int], tuple[tuple, Store]] = {}
_CACHE_LOCK = threading.Lock()


def open_store(out: str | Path | replay.Location | Store, limits: SqlLimits | None = None) -> Store:
    """The `Store` of an OUT directory (a path or a URI), cached per directory and memory
    limits (re-opened if the directory changed). `limits`: the memory DuckDB may use
    (default: the bounds of the block around, `query_limits`, else `SqlLimits.make()`, a
    quarter of the machine's memory)."""
    if isinstance(out, Store):
        return out
    limits = limits or store_limits()
    where: Path | replay.Location
    if isinstance(out, replay.Location) or replay.is_uri(str(out)):
        where = replay.location(out)
        if where.local is not None:  # file://
            where = where.local.resolve()
    else:
        where = Path(out).resolve()
    if isinstance(where, Path):
        sig, opener = _signature(where), _open
    else:
        sig, opener = _remote_signature(where), _open_remote
    key = (str(where), limits.memory, limits.spill)
    with _CACHE_LOCK:
        hit = _CACHE.get(key)
        if hit is not None and hit[0] == sig:
            return hit[1]
        store = opener(where, limits)  # type: ignore[arg-type]
        # The previous connection is not closed here: another thread may still be reading
        # from it; it closes when the last reference goes.
        _CACHE[key] = (sig, store)
        return store


def clear_cache() -> None:
    """Close every cached connection (tests, or after rewriting OUT in place)."""
    with _CACHE_LOCK:
        for _, store in _CACHE.values():
            store.con.close()
        _CACHE.clear()


def table_columns(out: str | Path | Store) -> Mapping[str, list[str]]:
    """Column names of the four tables of OUT."""
    store = open_store(out)
    return {t: list(cols) for t, cols in store.columns.items()}


__all__ = [
    "NUMERIC_TYPES",
    "resolve_input",
    "Store",
    "clear_cache",
    "memory_store",
    "open_store",
    "table_columns",
]
