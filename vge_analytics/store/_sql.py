"""Read-only SQL over the replay tables (`vge sql`, the dashboard's query box), with limits.

Two independent guards keep a query read-only:

1. The connection itself (`_locked`, opened by `_store`): DuckDB opens no file
   (`enable_external_access = false`, no allowed directory; the tables are Arrow datasets
   that pyarrow reads), its catalog is an empty database opened read-only, no extension can
   be installed or loaded, and `lock_configuration = true` makes that final. `read_csv('/etc/
   passwd')`, `read_parquet` of any path (inside OUT too), `COPY ... TO`, `ATTACH`, `EXPORT
   DATABASE` fail with a permission error, `CREATE`, `DROP`, `INSERT` as writes to a read-only
   database, whatever the SQL text looks like.
2. The statement type, as DuckDB's parser classifies it (`duckdb.extract_statements`, not
   string matching): exactly one statement, of type SELECT (which covers `WITH`, `FROM ...`,
   `VALUES`, `DESCRIBE`, `SHOW`, `SUMMARIZE`) or EXPLAIN of such a statement. INSERT, CREATE,
   COPY, ATTACH, PRAGMA, SET, INSTALL, LOAD, CALL, ... are refused before they run, with a
   message that says so.

The query's text is refused past `MAX_SQL_TEXT` bytes before it is parsed (DuckDB's parser
takes hundreds of times the text's size in memory).

And every query runs within `SqlLimits` (`_limits`): DuckDB's memory and spill limits on the
connection, a timer that interrupts the query, and a result that is read batch by batch
(`stream`) so it never has to fit in memory: `sql` collects at most `limits.memory` bytes of
it, `sql_head` the first rows. A query stopped by a limit raises `QueryLimitError`.

Every statement that may hold SQL a user wrote goes through one door, `guarded_cursor`:
`vge sql` and the SQL page (`stream`), and every query of the analytics (`run_query`), a
metric file's expressions and the `--where` filters among them, over an OUT or over the
tables a sweep holds in memory (`memory_store`). `run_query` runs within the bounds the code
around it set (`_bounds.query_limits`): DuckDB's memory limit, the time limit, and the process
cap, around the query in a command's process or, in a server's, by running a query that holds
a metric file's SQL in a query process of its own (`_isolated`). Under the cap a result is
made a polars frame only when what is left holds it (`polars_frame`): polars aborts the
process where an allocation fails, where DuckDB, pyarrow and Python raise.
"""

from __future__ import annotations

import contextlib
import re
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import duckdb
import polars as pl
import pyarrow as pa

from .._errors import QueryError, QueryLimitError, QueryRefused
from ._bounds import query_bounds
from ._limits import (
    CLI_TIMEOUT,
    MAX_SQL_TEXT,
    SqlLimits,
    format_size,
    memory_room,
    process_memory_cap,
    text_too_large,
)
from ._store import Store, open_store

_ALLOWED = {duckdb.StatementType.SELECT}
_EXPLAIN = re.compile(r"^\s*explain(\s+analy[sz]e)?\s+", re.IGNORECASE)
BATCH_ROWS = 2048
"""Rows per result batch read from DuckDB."""
RESULT_BATCH_ROWS = 131_072
"""Rows per batch of an analytics query's result (`run_query`): as DuckDB's `.pl()` reads
them, so its frame has the same chunks."""
VIEW_BYTES = 16
"""Bytes polars takes per string (or binary) value on top of its bytes: its view."""
WRITE_COPIES = 6
"""Copies of a `vge sql` result's frame there must be room for under the cap: the frame,
rechunked, and its text as the commands write it (polars' buffer, Python's string as it is
built and as it is written)."""
POLARS_SLACK = 32 * 1024**2
"""Room kept free when a result is made a polars frame under the cap: its allocator maps
memory in blocks, and its threads may take theirs."""
ROW_TEXT_COPIES = 16
"""Bytes polars' CSV writer may take per byte of the longest row it writes: it formats
rows in chunks, and a chunk's buffers grow with its rows (measured: 13 to 14 times the text
of one row of a 15 to 60 MB value, whatever the frame's size; about 2 times for short rows,
which `WRITE_COPIES` covers)."""


def _kind(statement) -> str:
    return str(statement.type).rsplit(".", 1)[-1]


def check_size(query: str) -> str:
    """The query if its text is at most `MAX_SQL_TEXT` bytes, else `QueryRefused` (checked
    without parsing it)."""
    # A character is at most 4 bytes in UTF-8: most texts need no encoding to be measured.
    if len(query) * 4 > MAX_SQL_TEXT:
        why = text_too_large(len(query.encode("utf-8", "surrogatepass")))
        if why is not None:
            raise QueryRefused(f"the query holds {why}")
    return query


def check_read_only(query: str, con: duckdb.DuckDBPyConnection | None = None) -> str:
    """The query if it is one read-only statement, else `QueryRefused` (one line). Its size
    is checked first (`check_size`).

    `con`: the connection whose parser to use; without one, DuckDB's module-level default
    connection is opened (a database of its own, with its threads: a long-lived process
    that has a connection passes it)."""
    check_size(query)
    parser = con if con is not None else duckdb
    try:
        statements = parser.extract_statements(query)
    except duckdb.OutOfMemoryException:  # a long, deeply nested text, under the size cap
        raise QueryLimitError(
            "parsing the query needed more memory than it may use: shorten it, or nest it less",
            limit="memory",
        ) from None
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
            inner_statements = parser.extract_statements(inner)
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


class Deadline:
    """Interrupts a cursor's query after `seconds` (None: never); remembers that it did."""

    def __init__(self, cursor: duckdb.DuckDBPyConnection, seconds: float | None) -> None:
        self.fired = threading.Event()
        self._cursor = cursor
        self._timer = None if seconds is None else threading.Timer(seconds, self._fire)
        if self._timer is not None:
            self._timer.daemon = True
            self._timer.start()

    def _fire(self) -> None:
        self.fired.set()
        with contextlib.suppress(duckdb.Error):  # the query may just have ended
            self._cursor.interrupt()

    def cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()

    def stopped(self, exc: BaseException) -> bool:
        """Whether `exc` is the interruption this deadline caused (DuckDB's, or its text
        carried by a pyarrow error while batches are read)."""
        if not self.fired.is_set():
            return False
        first = (str(exc).splitlines() or [""])[0]
        return isinstance(exc, duckdb.InterruptException) or "INTERRUPT" in first


@contextlib.contextmanager
def guarded_cursor(
    store: Store, sql: str, timeout: float | None, *, ours: bool = False
) -> Iterator[tuple[duckdb.DuckDBPyConnection, Deadline]]:
    """The one door through which every statement that may hold SQL a user wrote is run: a
    metric file's expressions, the `--where` filters, `vge sql`, the SQL page, the sweep's
    metrics. The block gets a cursor of the store's locked connection (no file opened,
    a read-only catalog, settings final, DuckDB's memory limit) once the statement is checked
    to be one read-only query, and the deadline that interrupts it after `timeout` seconds
    (None: never). Running the statement and reading its result is the block's. `ours`: a
    query the analytics composed (`run_query`), whose cursor registers only the tables its
    text names (`Store.cursor`); a user's query sees every table."""
    cursor = store.cursor(sql if ours else None)
    deadline = Deadline(cursor, timeout)
    try:
        check_read_only(sql, cursor)
        yield cursor, deadline
    finally:
        deadline.cancel()
        cursor.close()


def subject_of(out: object, sources: Sequence[str]) -> str:
    """How a message names a query of the analytics: by the metric files whose SQL it holds,
    else by OUT (`out`)."""
    if not sources:
        return f"{out}: a query"
    if len(sources) == 1:
        return f"{sources[0]}: the query of this metric file"
    return f"{', '.join(sources)}: the query of these metric files"


def run_query(
    store: Store, sql: str, params: Sequence[object], *, sources: Sequence[str] = ()
) -> pl.DataFrame:
    """Run one of the analytics' queries through `guarded_cursor`, within the bounds of the
    block around it (`query_limits`: DuckDB's memory limit, the time limit, the process cap,
    or a process of its own); the result as a polars DataFrame.

    `sources`: the metric files whose SQL the statement holds (none: only this package's
    SQL and bound values). A query stopped by a bound raises `QueryLimitError`, another
    failure `QueryError`, each one line naming those files, else OUT."""
    bounds = query_bounds()
    if bounds is not None and bounds.isolated and sources:
        from ._isolated import query_isolated  # it runs this function in a child

        return query_isolated(store, sql, params, bounds, sources)
    limits = bounds.limits if bounds is not None else None
    capped = process_memory_cap(limits) if limits is not None and bounds.capped else None
    with capped or contextlib.nullcontext():
        return _run_here(store, sql, params, limits, subject_of(store.out, sources))


def query_limits_of(store: Store, limits: SqlLimits | None = None) -> SqlLimits:
    """The limits an analytics query over `store` runs within: `limits` (the block's, from
    `query_bounds`), else the store's, else none but DuckDB's defaults."""
    return limits or store.limits or SqlLimits.make(timeout=None)


def _run_here(
    store: Store, sql: str, params: Sequence[object], limits: SqlLimits | None, subject: str
) -> pl.DataFrame:
    limits = query_limits_of(store, limits)
    failure = None
    with guarded_cursor(store, sql, limits.timeout, ours=True) as (cursor, deadline):
        try:
            table = _fetched(cursor.sql(sql, params=list(params)))
        except _FAILURES as exc:
            failure = _limit_error(exc, limits, deadline, subject)
    if failure is None:  # DuckDB's result is let go first: the frame may take its room
        return polars_frame(table, limits, subject)
    if isinstance(failure, QueryLimitError):
        raise failure from None
    raise type(failure)(f"{subject} failed: {failure}") from None


def _fetched(relation: duckdb.DuckDBPyRelation) -> pa.Table:
    """A query's whole result as Arrow, its columns named as `.pl()` names them."""
    reader = relation.to_arrow_reader(RESULT_BATCH_ROWS)
    try:
        table = reader.read_all()
    finally:
        reader.close()
    names = unique_names(table.schema.names)
    return table if names == table.schema.names else table.rename_columns(names)


def _views(data: pa.Array | pa.ChunkedArray) -> int:
    """How many string and binary values `data` holds, nested ones too."""
    if isinstance(data, pa.ChunkedArray):
        return sum(_views(chunk) for chunk in data.chunks)
    kind = data.type
    if pa.types.is_dictionary(kind):
        return _views(data.dictionary)
    if pa.types.is_struct(kind):
        return sum(_views(data.field(i)) for i in range(kind.num_fields))
    if pa.types.is_map(kind):
        return _views(data.keys) + _views(data.items)
    if pa.types.is_list(kind) or pa.types.is_large_list(kind) or pa.types.is_fixed_size_list(kind):
        return _views(data.values)
    return len(data) if _text(kind) else 0


_STRING_TYPES = (
    pa.types.is_string,
    pa.types.is_large_string,
    pa.types.is_string_view,
    pa.types.is_binary,
    pa.types.is_large_binary,
    pa.types.is_binary_view,
)


def _text(kind: pa.DataType) -> bool:
    """Whether values of `kind` are strings or binaries (polars makes a view of each)."""
    return any(test(kind) for test in _STRING_TYPES)


def polars_room(table: pa.Table, copies: int) -> int:
    """Bytes polars may take to make `table` a frame and use it: `copies` copies of its
    buffers with a view per string (polars turns strings into views, may convert other
    types, copies them again to rechunk or to write them out), and `POLARS_SLACK`."""
    copy = table.nbytes + VIEW_BYTES * sum(_views(column) for column in table.columns)
    return copies * copy + POLARS_SLACK


class RowText(NamedTuple):
    """The text a table stands for when written out (`row_text`)."""

    longest: int
    """Bytes of text in its longest row."""
    encoded: int
    """Bytes its dictionary-encoded values stand for, over all rows: a table holds each
    distinct value once, its text as many times as rows use it."""


def row_text(table: pa.Table) -> RowText:
    """The text of `table`'s rows: the string and binary values of its columns, lists of
    them and dictionary-encoded ones (DuckDB's ENUM) included (a list is written as its
    values joined, a dictionary's value as itself). A dictionary's lengths are taken per
    distinct value, then by index: one long value on many rows is never written out here."""
    import numpy as np
    import pyarrow.compute as pc

    total = np.zeros(table.num_rows, dtype=np.int64)
    encoded = 0
    for column in table.columns:
        data, rows = column.combine_chunks(), None
        while pa.types.is_list(data.type) or pa.types.is_large_list(data.type):
            parents = pc.list_parent_indices(data).to_numpy()
            rows = parents if rows is None else rows[parents]
            data = pc.list_flatten(data)
        if len(data) == 0:
            continue
        coded = pa.types.is_dictionary(data.type)
        if coded and _text(data.type.value_type):
            sizes = pc.fill_null(pc.binary_length(data.dictionary), 0)
            lengths = pc.fill_null(pc.take(sizes, data.indices), 0)
        elif not coded and _text(data.type):
            lengths = pc.fill_null(pc.binary_length(data), 0)
        else:
            continue
        lengths = lengths.to_numpy().astype(np.int64)
        if coded:
            encoded += int(lengths.sum())
        if rows is not None:  # a list's values summed into its row
            lengths = np.bincount(rows, lengths, table.num_rows).astype(np.int64)
        total += lengths
    return RowText(int(total.max()) if table.num_rows else 0, encoded)


def polars_frame(
    table: pa.Table,
    limits: SqlLimits,
    subject: str = "the query",
    *,
    copies: int = 1,
    text: bool = False,
) -> pl.DataFrame:
    """`table` as a polars frame (its chunks kept), or, when the process is capped
    (`process_memory_cap`) and there may not be room under the cap for `copies` copies of
    it (`polars_room`), and with `text` for its CSV text too (`ROW_TEXT_COPIES` times its
    longest row, and `copies` times the text its dictionary-encoded values stand for),
    the one-line memory error naming `subject`: polars aborts the process where an
    allocation fails instead of raising."""
    room = memory_room()
    if room is not None:
        need = polars_room(table, copies)
        if text and need <= room:
            written = row_text(table)
            need += ROW_TEXT_COPIES * written.longest + copies * written.encoded
        if need > room:
            raise QueryLimitError(memory_message(subject, limits), limit="memory")
    return pl.from_arrow(table, rechunk=False)


def _limit_error(
    exc: BaseException, limits: SqlLimits, deadline: Deadline, subject: str = "the query"
) -> Exception:
    """The one-line error for a failure while a query ran or its result was read; a bound's
    message begins with `subject` (what ran past it).

    DuckDB's errors reach us as duckdb exceptions, or, while the Arrow reader pulls batches,
    as pyarrow errors carrying DuckDB's text: both are classified by that text."""
    first = (str(exc).splitlines() or [type(exc).__name__])[0]
    if deadline.stopped(exc):
        return QueryLimitError(time_message(subject, limits), limit="time")
    if isinstance(exc, MemoryError | duckdb.OutOfMemoryException) or first.startswith(
        "Out of Memory Error"
    ):
        return QueryLimitError(memory_message(subject, limits), limit="memory")
    if isinstance(exc, duckdb.PermissionException) or first.startswith("Permission Error"):
        return QueryRefused(
            "access outside the tables steps, episodes, goals, runs is not allowed: no file "
            f"is opened, in OUT or elsewhere ({first})"
        )
    return QueryError(first)


def time_message(subject: str, limits: SqlLimits) -> str:
    """`<subject> ran past its time limit of 30 s and was stopped`."""
    return f"{subject} ran past its time limit of {limits.timeout:g} s and was stopped"


def memory_message(subject: str, limits: SqlLimits) -> str:
    """`<subject> needed more memory than its limit (...) and was stopped`."""
    return f"{subject} needed more memory than its limit ({limits.describe()}) and was stopped"


_FAILURES = (duckdb.Error, pa.ArrowException, OSError, MemoryError)


def unique_names(names: list[str]) -> list[str]:
    """Column names made unique as DuckDB does for DataFrames (`a, a, a_1` -> `a, a_1,
    a_1_1`; compared case-insensitively), so `SELECT a.x, b.x` gives two columns."""
    seen: dict[str, int] = {}
    unique = []
    for name in names:
        low = name.lower()
        if low not in seen:
            seen[low] = 1
            unique.append(name)
            continue
        candidate = f"{name}_{seen[low]}"
        while candidate.lower() in seen:
            seen[low] += 1
            candidate = f"{name}_{seen[low]}"
        seen[candidate.lower()] = 1
        unique.append(candidate)
    return unique


class Batches:
    """The result of a running query: its `schema`, and its record batches when iterated
    (each read from DuckDB when it is asked for; a failure raises the one-line error)."""

    def __init__(self, reader: pa.RecordBatchReader, fail, limits: SqlLimits) -> None:
        names = unique_names(reader.schema.names)
        self.schema: pa.Schema = pa.schema(
            [field.with_name(name) for field, name in zip(reader.schema, names, strict=True)]
        )
        self._renamed = names != reader.schema.names
        self._reader = reader
        self._fail = fail
        self._limits = limits

    def __iter__(self) -> Iterator[pa.RecordBatch]:
        while True:
            try:
                batch = self._reader.read_next_batch()
            except StopIteration:
                return
            except _FAILURES as exc:
                raise self._fail(exc) from None
            yield batch.rename_columns(self.schema.names) if self._renamed else batch

    def frame(self, batches: list[pa.RecordBatch]) -> pl.DataFrame:
        """Batches of this result as one polars DataFrame (the columns even with no rows,
        one chunk); the one-line memory error where there may not be room under the cap
        for it and its text (`WRITE_COPIES`, `ROW_TEXT_COPIES`, `polars_frame`)."""
        table = pa.Table.from_batches(batches, schema=self.schema)
        return polars_frame(table, self._limits, copies=WRITE_COPIES, text=True).rechunk()


@contextlib.contextmanager
def stream(
    out: str | Path | Store,
    query: str,
    *,
    limits: SqlLimits | None = None,
    batch_rows: int = BATCH_ROWS,
) -> Iterator[Batches]:
    """Run one read-only query over OUT; the block gets its result as Arrow record batches,
    produced as they are read (DuckDB computes the next batch when it is asked for).

    The query is interrupted when `limits.timeout` runs out, also while the block reads;
    leaving the block early stops it. Failures raise `QueryRefused`, `QueryLimitError` or
    `QueryError`, each with a one-line message."""
    limits = limits or SqlLimits.make()
    check_size(query)  # before OUT is opened; the whole check is `guarded_cursor`'s
    store = open_store(out, limits)
    with guarded_cursor(store, query, limits.timeout) as (cursor, deadline):

        def fail(exc: BaseException) -> Exception:
            return _limit_error(exc, limits, deadline)

        reader = None
        try:
            try:
                reader = cursor.sql(query).to_arrow_reader(batch_size=batch_rows)
            except _FAILURES as exc:
                raise fail(exc) from None
            yield Batches(reader, fail, limits)
        finally:
            if reader is not None:
                reader.close()


def _collect(
    result: Batches, limits: SqlLimits, rows: int | None = None
) -> tuple[list[pa.RecordBatch], bool]:
    """The batches of a result, at most `rows` rows (None: all) and at most `limits.memory`
    bytes (`QueryLimitError` past that); and whether rows were left unread."""
    kept: list[pa.RecordBatch] = []
    count = size = 0
    for batch in result:
        size += batch.nbytes
        if size > limits.memory:
            what = "the result" if rows is None else f"the first {rows:,} rows"
            raise QueryLimitError(
                f"{what} is larger than the memory limit ({format_size(limits.memory)})",
                limit="result",
            )
        if rows is not None and count + batch.num_rows > rows:
            kept.append(batch.slice(0, rows - count))
            return kept, True
        kept.append(batch)
        count += batch.num_rows
    return kept, False


def sql(
    out: str | Path | Store,
    query: str,
    *,
    timeout: float | None = CLI_TIMEOUT,
    memory_limit: str | int | None = None,
) -> pl.DataFrame:
    """Run one read-only query over the views `steps episodes goals runs` of OUT.

    `memory_limit` (bytes or `"4GB"`; default a quarter of the machine's memory) bounds
    DuckDB's memory (it spills up to twice that to disk) and the result collected here;
    `timeout` (seconds, None for none) stops the query. Writing statements and any access to
    files outside OUT raise `QueryRefused`; a query past a limit raises `QueryLimitError`;
    other failures (syntax, unknown column) raise `QueryError`. All carry a one-line message.
    """
    limits = SqlLimits.make(memory=memory_limit, timeout=timeout)
    with stream(out, query, limits=limits) as result:
        return result.frame(_collect(result, limits)[0])


@dataclass(frozen=True)
class SqlHead:
    """The first rows of a query's result."""

    frame: pl.DataFrame
    truncated: bool
    """The result has more rows than `frame` holds."""


def sql_head(
    out: str | Path | Store, query: str, rows: int, *, limits: SqlLimits | None = None
) -> SqlHead:
    """The first `rows` rows of a read-only query (reading stops after `rows + 1` rows, so
    the rest is never computed when the query can stream). Limits and errors as `stream`."""
    limits = limits or SqlLimits.make()
    with stream(out, query, limits=limits, batch_rows=min(BATCH_ROWS, rows + 1)) as result:
        kept, truncated = _collect(result, limits, rows)
        return SqlHead(frame=result.frame(kept), truncated=truncated)


__all__ = [
    "BATCH_ROWS",
    "Batches",
    "Deadline",
    "SqlHead",
    "check_read_only",
    "check_size",
    "guarded_cursor",
    "memory_message",
    "polars_frame",
    "query_limits_of",
    "run_query",
    "sql",
    "sql_head",
    "stream",
    "subject_of",
    "time_message",
]
