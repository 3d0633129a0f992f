"""A DuckDB connection that can change nothing: the store's (`_store`) and the one that binds
metric expressions (`_metric_check`).

- Its catalog is an empty database opened read-only: `CREATE`, `DROP`, `INSERT`, `ATTACH` fail
  inside DuckDB ("attached in read-only mode"). The file is a copy of an empty database made
  once per process, unlinked as soon as it is open, so nothing is left behind.
- It reads no file: `enable_external_access = false` with no allowed directory, so `COPY ...
  TO`, `ATTACH 'file'`, `EXPORT DATABASE`, `read_csv(...)` fail with a permission error,
  whatever the path. The tables are Arrow objects registered on each cursor (`register`),
  read by pyarrow, not by DuckDB.
- No extension can be installed or loaded, and `lock_configuration` makes all of it final.

A cursor may still create temporary objects in its own temporary schema; they vanish with the
cursor and no other cursor sees them.
"""

from __future__ import annotations

import itertools
import os
import tempfile
import threading
from collections.abc import Mapping, Sequence

import duckdb

_template: list[bytes] = []
_template_lock = threading.Lock()
_COUNT = itertools.count()


def _empty_database() -> bytes:
    """The bytes of an empty DuckDB database file (made once per process)."""
    with _template_lock:
        if not _template:
            with tempfile.TemporaryDirectory(prefix="vge-db-") as folder:
                path = os.path.join(folder, "empty.duckdb")
                duckdb.connect(path).close()
                with open(path, "rb") as fh:
                    _template.append(fh.read())
        return _template[0]


def locked_connection(
    config: Mapping[str, str] | None = None, settings: Sequence[tuple[str, object]] = ()
) -> duckdb.DuckDBPyConnection:
    """A read-only, file-less, locked connection. `config`: options DuckDB takes when it
    starts (threads); `settings`: `SET name = value` applied before the lock (memory and
    spill limits)."""
    # A name never used before in this process: DuckDB keeps one instance per path, and an
    # unlinked name could come back from mkstemp while an older store still holds it.
    handle, path = tempfile.mkstemp(prefix=f"vge-db-{next(_COUNT)}-", suffix=".duckdb")
    try:
        with os.fdopen(handle, "wb") as fh:
            fh.write(_empty_database())
        con = duckdb.connect(path, read_only=True, config=dict(config or {}))
    finally:
        os.unlink(path)
    try:
        for name, value in settings:
            con.execute(f"SET {name} = ?", [value])  # names are this package's constants
        # allowed_directories is empty: with external access off, DuckDB opens no file.
        con.execute("SET enable_external_access = false")
        con.execute("SET autoinstall_known_extensions = false")
        con.execute("SET autoload_known_extensions = false")
        con.execute("SET lock_configuration = true")  # last: it freezes every setting
    except BaseException:
        con.close()
        raise
    return con


def register_all(cursor: duckdb.DuckDBPyConnection, tables: Mapping[str, object]) -> None:
    """Register each Arrow table or dataset of `tables` on `cursor` under its name (a temporary
    view of that cursor's own)."""
    for name, source in tables.items():
        cursor.register(name, source)


__all__ = ["locked_connection", "register_all"]
