"""Read-only SQL over the replay tables (`vge sql`, the dashboard's query box).

Two independent guards:

1. DuckDB's own settings on the connection (see `_store._secure`): file access limited to
   OUT (`allowed_directories` + `enable_external_access = false`), no extension install or
   load, and `lock_configuration = true` so no statement can undo them. `read_csv('/etc/
   passwd')`, `read_parquet` of another path, `COPY ... TO`, `ATTACH`, `EXPORT DATABASE`
   fail inside DuckDB with a permission error, whatever the SQL text looks like.
2. The statement type, as DuckDB's parser classifies it (`duckdb.extract_statements`, not
   string matching): exactly one statement, of type SELECT (which covers `WITH`, `FROM ...`,
   `VALUES`, `DESCRIBE`, `SHOW`, `SUMMARIZE`) or EXPLAIN of such a statement. INSERT, CREATE,
   COPY, ATTACH, PRAGMA, SET, INSTALL, LOAD, CALL, ... are refused before they run, so the
   views of the shared connection cannot be replaced or dropped.
"""

from __future__ import annotations

import re

import duckdb
import polars as pl

from ._errors import QueryError, QueryRefused
from ._store import open_store

_ALLOWED = {duckdb.StatementType.SELECT}
_EXPLAIN = re.compile(r"^\s*explain(\s+analy[sz]e)?\s+", re.IGNORECASE)


def _kind(statement) -> str:
    return str(statement.type).rsplit(".", 1)[-1]


def check_read_only(query: str) -> str:
    """The query if it is one read-only statement, else `QueryRefused` (one line)."""
    try:
        statements = duckdb.extract_statements(query)
    except duckdb.Error as exc:
        raise QueryError(f"cannot parse the query: {str(exc).splitlines()[0]}") from None
    if not statements:
        raise QueryRefused("empty query")
    if len(statements) > 1:
        raise QueryRefused(f"one statement at a time, got {len(statements)}")
    statement = statements[0]
    if statement.type == duckdb.StatementType.EXPLAIN:
        inner = _EXPLAIN.sub("", query, count=1)
        try:
            inner_statements = duckdb.extract_statements(inner)
        except duckdb.Error:
            inner_statements = []
        if len(inner_statements) != 1 or inner_statements[0].type not in _ALLOWED:
            raise QueryRefused("EXPLAIN is only allowed on a SELECT query")
        return query
    if statement.type not in _ALLOWED:
        raise QueryRefused(
            f"read-only: {_kind(statement)} statements are not allowed "
            "(only SELECT queries over steps, episodes, goals, runs)"
        )
    return query


def sql(out, query: str) -> pl.DataFrame:
    """Run one read-only query over the views `steps episodes goals runs` of OUT.

    Writing statements and any access to files outside OUT raise `QueryRefused`; other
    failures (syntax, unknown column) raise `QueryError`. Both carry a one-line message.
    """
    store = open_store(out)
    check_read_only(query)
    try:
        rel = store.cursor().sql(query)
        if rel is None:  # pragma: no cover - only SELECT/EXPLAIN get here
            return pl.DataFrame()
        return rel.pl()
    except duckdb.PermissionException as exc:
        first = str(exc).splitlines()[0]
        raise QueryRefused(f"access outside {store.out} is not allowed ({first})") from None
    except duckdb.Error as exc:
        raise QueryError(str(exc).splitlines()[0]) from None


__all__ = ["check_read_only", "sql"]
