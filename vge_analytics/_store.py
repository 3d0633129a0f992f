"""A replay output directory (PROTOCOL §7) opened as DuckDB views, cached per directory.

`open_store(out)` returns one `Store` per OUT directory (re-opened when the directory's
contents change): an in-memory DuckDB connection with the views `steps episodes goals runs`
reading the Parquet files directly, plus the column catalogue used to validate every
grouping or filter column before it is quoted into a query.

The connection is locked down as soon as the views exist: file access is limited to OUT
(`allowed_directories`, then `enable_external_access = false`), extensions cannot be
installed or loaded, its memory is capped (`memory_limit`, spilling to a private temporary
directory capped by `max_temp_directory_size`; see `_limits`), and `lock_configuration =
true` makes those settings final. Every query, ours or a user's (`vge sql`), runs on a cursor
of that connection. A store is cached per (directory, memory limits).

OUT may also be a URI (`s3://bucket/out?...`, `gs://...`; docs/SCALE.md): its Parquet files are
then read through pyarrow's filesystem (`replay.Location`, the replay's own), as Arrow
datasets that DuckDB scans, so no DuckDB extension is needed, and DuckDB is given no file
access at all. A `file://` URI is the local directory.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import tempfile
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.dataset as pads

import replay

from ._errors import OutputDirError
from ._limits import SqlLimits

TABLES: tuple[str, ...] = ("steps", "episodes", "goals", "runs")
PARTITIONED: tuple[str, ...] = ("steps", "episodes", "goals")

RUN_COLUMNS_FIXED: tuple[str, ...] = ("run_id", "model", "agent_kind", "lambda")
"""Columns every runs table has (meta facets add `meta_<key>` columns and `meta`)."""

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


def quote_ident(name: str) -> str:
    """Quote a column name as a DuckDB identifier.

    Only ever applied to names that were checked to be existing columns (see
    `Store.check_column`) or to the fixed metric names of the registry. Inside double quotes
    the parser reads everything up to the next unescaped `"` as one identifier, and every `"`
    in the name is doubled, so the name cannot end the identifier early: whatever characters a
    meta facet key holds, the result is one identifier naming that existing column, never SQL.
    """
    return '"' + name.replace('"', '""') + '"'


def _empty_runs() -> pa.Table:
    return pa.table(
        {
            "run_id": pa.array([], pa.string()),
            "model": pa.array([], pa.string()),
            "agent_kind": pa.array([], pa.string()),
            "lambda": pa.array([], pa.float64()),
            "meta": pa.array([], pa.string()),
        }
    )


def _signature(out: Path) -> tuple:
    """Cheap fingerprint of OUT: changes when a replay rewrites it."""
    parts = []
    for name in ("manifest.json", "runs", *PARTITIONED):
        p = out / name
        try:
            st = p.stat()
            parts.append((name, st.st_mtime_ns, st.st_size))
        except OSError:
            parts.append((name, None, None))
        if p.is_dir() and name != "runs":
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
    sources: tuple = ()
    """The Arrow datasets the views of a remote OUT scan (kept alive with the connection)."""
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def cursor(self) -> duckdb.DuckDBPyConnection:
        """A cursor for one query (cursors of one connection may run in different threads)."""
        with self._lock:
            return self.con.cursor()

    def has_column(self, table: str, name: str) -> bool:
        return name in self.columns[table]

    def is_scalar(self, table: str, name: str) -> bool:
        return self.columns[table][name].upper() in _SCALAR_TYPES

    @property
    def meta_columns(self) -> list[str]:
        """Run facet columns (`meta_<key>`) of the runs table."""
        return [c for c in self.columns["runs"] if c.startswith("meta_")]

    def run_ids(self) -> list[str]:
        rows = self.cursor().execute("SELECT DISTINCT run_id FROM runs ORDER BY run_id").fetchall()
        return [r[0] for r in rows]


def _files(root: Path) -> list[str]:
    return sorted(str(p) for p in root.rglob("*.parquet") if p.is_file())


def _create_views(con: duckdb.DuckDBPyConnection, out: Path) -> None:
    for table in PARTITIONED:
        root = out / table
        if _files(root):
            # run_id is a column of every file; the directory name (`run_id=<id>`, possibly
            # percent-encoded by the writer) is not read back.
            rel = con.read_parquet(
                str(root / "**" / "*.parquet"), hive_partitioning=False, union_by_name=True
            )
        else:
            schema = replay.arrow_schema(replay.TABLE_ROWS[table])
            rel = con.from_arrow(schema.empty_table())
        rel.create_view(table)
    runs_root = out / "runs"
    if _files(runs_root):
        rel = con.read_parquet(str(runs_root / "*.parquet"), union_by_name=True)
    else:
        rel = con.from_arrow(_empty_runs())
    rel.create_view("runs")


def _remote_source(loc: replay.Location, names: list[str]) -> pads.Dataset:
    """The Parquet files `names` (relative to `loc`) as one Arrow dataset, their schemas
    unified by column name as DuckDB's `union_by_name` does (a column some files lack is
    null there)."""
    paths = [f"{loc.path.rstrip('/')}/{name}" for name in names]
    found = pads.dataset(paths, filesystem=loc.fs, format="parquet")
    schema = pa.unify_schemas(
        [fragment.physical_schema for fragment in found.get_fragments()],
        promote_options="permissive",
    )
    return found.replace_schema(schema)  # the same files, not listed or opened again


def _create_remote_views(
    con: duckdb.DuckDBPyConnection, out: replay.Location, manifest: dict
) -> tuple:
    """The four views over a remote OUT; returns the datasets they scan. The tables' files
    are the ones the manifest lists (`runs[].outputs`), not a listing of the prefix: on object
    storage a listing may catch a run mid-commit, the manifest never does (docs/SCALE.md)."""
    sources = []
    for table in TABLES:
        if table == "runs":
            names = [f"runs/{n}" for n in (out / "runs").names() if n.endswith(".parquet")]
            empty = _empty_runs()
        else:
            names = sorted(f for run in manifest.get("runs", []) for f in run["outputs"][table])
            empty = replay.arrow_schema(replay.TABLE_ROWS[table]).empty_table()
        if names:
            source = _remote_source(out, names)
            sources.append(source)
            rel = con.from_arrow(source)
        else:
            rel = con.from_arrow(empty)
        rel.create_view(table)
    return tuple(sources)


_SPILL_DIRS = itertools.count()


def _spill_directory() -> str:
    """A temporary directory of its own for each connection: DuckDB creates it when it first
    spills and removes it when the connection closes (its default, `.tmp` in the current
    directory, would litter wherever the command runs)."""
    name = f"vge-sql-{os.getpid()}-{next(_SPILL_DIRS)}"
    return str(Path(tempfile.gettempdir()) / name)


def _secure(con: duckdb.DuckDBPyConnection, out: Path | None, limits: SqlLimits) -> None:
    """Lock the connection down; `out`: the one directory it may read (None: none, the views
    of a remote OUT scan Arrow datasets, not files)."""
    # Order matters: allowed_directories can only be set while external access is on, and
    # lock_configuration must come last (it freezes every setting, including itself).
    con.execute("SET memory_limit = ?", [f"{limits.memory}B"])
    con.execute("SET temp_directory = ?", [_spill_directory()])
    con.execute("SET max_temp_directory_size = ?", [f"{limits.spill}B"])
    con.execute("SET allowed_directories = ?", [[str(out) + "/"] if out is not None else []])
    con.execute("SET enable_external_access = false")
    con.execute("SET autoinstall_known_extensions = false")
    con.execute("SET autoload_known_extensions = false")
    con.execute("SET lock_configuration = true")


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


def _read_manifest(out: Path | replay.Location) -> dict:
    path = out / "manifest.json"
    if not path.exists():
        return {}
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, ValueError) as exc:
        raise OutputDirError(f"{path}: unreadable manifest ({exc})") from None
    return data if isinstance(data, dict) else {}


def _open(out: Path, limits: SqlLimits) -> Store:
    if not out.is_dir():
        raise OutputDirError(f"{out}: replay output directory not found")
    missing = [t for t in PARTITIONED if not (out / t).is_dir()]
    if missing:
        raise OutputDirError(
            f"{out}: not a replay output directory (no {'/, '.join(missing)}/); "
            "run `vge replay ... --out` first"
        )
    con = duckdb.connect(":memory:")
    con.execute("SET parquet_metadata_cache = true")
    try:
        _create_views(con, out)
    except duckdb.Error as exc:
        con.close()
        raise OutputDirError(f"{out}: cannot read the Parquet tables ({exc})") from None
    columns = _catalogue(con)
    _secure(con, out, limits)
    return Store(out=out, con=con, columns=columns, manifest=_read_manifest(out))


def _open_remote(out: replay.Location, limits: SqlLimits) -> Store:
    try:
        data = (out / "manifest.json").read_bytes()
    except FileNotFoundError:
        raise OutputDirError(
            f"{out}: not a replay output (no manifest.json); run `vge replay ... --out {out}` first"
        ) from None
    except OSError as exc:
        raise OutputDirError(f"{out}: cannot read it ({exc})") from None
    try:
        manifest = json.loads(data.decode("utf-8"))
        con = duckdb.connect(":memory:")
        sources = _create_remote_views(con, out, manifest)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise OutputDirError(f"{out}: cannot read the replay output ({exc})") from None
    columns = _catalogue(con)
    _secure(con, None, limits)
    return Store(out=out, con=con, columns=columns, manifest=manifest, sources=sources)


def _catalogue(con: duckdb.DuckDBPyConnection) -> dict[str, dict[str, str]]:
    columns: dict[str, dict[str, str]] = {}
    for table in TABLES:
        rows = con.execute(f"DESCRIBE {table}").fetchall()  # table names are constants
        columns[table] = {r[0]: str(r[1]) for r in rows}
    return columns


def _remote_signature(out: replay.Location) -> tuple:
    """Fingerprint of a remote OUT: its manifest, which the replay writes last, after every
    table file (the commit marker of object storage, docs/SCALE.md)."""
    try:
        return ("manifest", (out / "manifest.json").read_bytes())
    except OSError:
        return ("manifest", None)


_CACHE: dict[tuple[str, int, int], tuple[tuple, Store]] = {}
_CACHE_LOCK = threading.Lock()


def open_store(out: str | Path | replay.Location | Store, limits: SqlLimits | None = None) -> Store:
    """The `Store` of an OUT directory (a path or a URI), cached per directory and memory
    limits (re-opened if the directory changed). `limits`: the memory DuckDB may use
    (default: `SqlLimits.make()`, a quarter of the machine's memory)."""
    if isinstance(out, Store):
        return out
    limits = limits or SqlLimits.make()
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
    "PARTITIONED",
    "RUN_COLUMNS_FIXED",
    "resolve_input",
    "TABLES",
    "Store",
    "clear_cache",
    "open_store",
    "quote_ident",
    "table_columns",
]
