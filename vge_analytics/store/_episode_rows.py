"""A count's or a sum's terms per (run, episode) over the episodes grain, as a projection of
that table.

`_episode_terms` keeps a metric's terms per (run, episode): its grain's rows grouped by run
and episode, joined to the episodes' columns. Over the episodes grain each (run, episode) is
one row of the table (PROTOCOL §7.6: an episode id seen again in a run is quarantined as
`duplicate_episode`), so each group is that row alone, and its aggregate is known without
grouping. For a count: `count(*)` is 1, and `count(*) FILTER (WHERE condition)` is 1 when
the condition is true and 0 when it is false or null, the row's
`CASE WHEN (condition) THEN 1 ELSE 0 END` (a BIGINT, as count's). For a sum (`sum`, `fsum`,
`kahan_sum`, `sumkahan` of one value of the row): the same aggregate over a list of that one
value, `list_aggregate([value], 'fsum')`, which DuckDB computes with the aggregate's own
function, so its type and bits are the grouped query's (a sum of a row's value is not
always that value: of an integer a HUGEINT, of a DECIMAL(p, s) a DECIMAL(38, s), of -0.0 a
0.0, of null a null); with a `FILTER (WHERE condition)`, the list sliced to nothing unless
the condition is true (no row: the sum's null; the value evaluated on every row, as the
grouped query evaluates it, so that it fails where that fails), each term wrapped in
`coalesce(..., 0)` as `ratio_terms` wraps it.
Any other term (another aggregate, DISTINCT, ORDER BY, an aggregate, subquery or window in
the value or the condition) is computed as before, grouped and joined.

The rows of a part's runs are read by polars from those runs' files of the dataset DuckDB
scans (the files the manifest lists), only the columns needed: the keys, the episodes'
columns kept, and those the conditions and the sums' values name (read from DuckDB's own
parse of the metric's SQL; booleans and numbers only: a text or a list is left to the
grouped query, which streams it), each of the type DuckDB gives it there (else the grouped
query answers); a file's run_id is its run, read from its folder's name, as the dataset
gives it whatever the file holds (`_scan_counts._in_its_folder`: a path polars would read
otherwise is grouped). DuckDB evaluates the conditions and values over those columns alone;
the rows are sorted by run and episode (the replay writes them so: then only checked). A
part whose keys repeat or are null (a table edited by hand), or whose projection fails, is
computed as before, so the rows are the same either way. At 100 times the full benchmark
this took keeping SR's terms per episode from 14 s of CPU to 4, and SPL's first interval
from 22 s of CPU to 10 (docs/PERFORMANCE.md).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import weakref
from collections.abc import Sequence

import duckdb
import polars as pl
import pyarrow as pa

from replay.io import EPISODES_TABLE, PARTITION_KEY

from .._errors import QueryError, QueryLimitError
from ._bounds import query_bounds
from ._datasets import Deferred, run_files
from ._ratios import Ratio, ratio_terms, term_name
from ._scan_counts import _in_its_folder
from ._scope import quote_ident
from ._sql import run_query
from ._store import NUMERIC_TYPES, Store

_KEYS = ("run_id", "episode_id")

_ROWS = "__episode_rows"
"""The name of a part's rows (the columns the conditions name) in the projection's query."""

_FIXED = frozenset({"BOOLEAN", *NUMERIC_TYPES})
"""The types of the columns a condition may read here: of a fixed width (a part's 500,000
episodes of a boolean are half a megabyte; of a text or a list, unbounded)."""

_PLAIN = frozenset(
    {"BETWEEN", "CASE", "CAST", "COLLATE", "COLUMN_REF", "COMPARISON", "CONJUNCTION"}
    | {"CONSTANT", "FUNCTION", "LAMBDA", "OPERATOR", "TYPE"}
)
"""Classes of DuckDB's parsed expressions a condition or a sum's value may hold: values of
the row alone (no subquery, star, parameter or window; a TYPE is a cast's)."""


def _nodes(node: object):
    """Every parsed expression (a dict with a `class`) in `node`, itself included."""
    if isinstance(node, dict):
        if "class" in node:
            yield node
        for value in node.values():
            yield from _nodes(value)
    elif isinstance(node, list):
        for value in node:
            yield from _nodes(value)


@functools.lru_cache(maxsize=1)
def _aggregates() -> frozenset[str]:
    """The names of DuckDB's aggregate functions (none may be read within a term's
    argument or condition here: over the projection's rows it would aggregate them)."""
    with duckdb.connect() as con:
        rows = con.execute(
            "SELECT DISTINCT function_name FROM duckdb_functions() "
            "WHERE function_type = 'aggregate'"
        ).fetchall()
    return frozenset(name.lower() for (name,) in rows)


def _of_the_row(
    parsed: dict, statement: dict, con: duckdb.DuckDBPyConnection
) -> tuple[str, set[str]] | None:
    """The SQL of a parsed expression (DuckDB's own text of it: `statement`, the parsed
    `SELECT` that holds it, with the expression alone selected) and the names its column
    references hold, or None when it holds anything but values of the row (an aggregate,
    a subquery, a star, a parameter, a window)."""
    names: set[str] = set()
    for node in _nodes(parsed):
        if node["class"] not in _PLAIN:
            return None
        if node["class"] == "FUNCTION" and (
            node.get("filter") or node.get("distinct") or node.get("function_name") in _aggregates()
        ):
            return None  # an aggregate's
        if node["class"] == "COLUMN_REF":
            names.update(n for n in node.get("column_names", []) if isinstance(n, str))
    select = {**statement, "node": {**statement["node"], "select_list": [parsed]}}
    document = json.dumps({"error": False, "statements": [select]})
    (text,) = con.execute("SELECT json_deserialize_sql(?)", [document]).fetchone()
    if not isinstance(text, str) or not text.startswith("SELECT "):
        return None
    return text.removeprefix("SELECT "), names


def _only(statement: dict) -> dict | None:
    """The one expression a parsed `SELECT expression` selects, or None when the statement
    holds anything else (a FROM, WHERE, GROUP BY, ORDER BY, LIMIT, CTE...)."""
    node = statement.get("node", {})
    bare = (
        node.get("type") == "SELECT_NODE"
        and not node.get("modifiers")
        and not node.get("cte_map", {}).get("map")
        and node.get("from_table", {}).get("type") == "EMPTY"
        and all(not node.get(k) for k in ("where_clause", "having", "qualify", "sample"))
        and not node.get("group_expressions")
        and not node.get("group_sets")
        and len(node.get("select_list", [])) == 1
    )
    return node["select_list"][0] if bare else None


_SUMS = frozenset({"sum", "fsum", "kahan_sum", "sumkahan"})
"""DuckDB's sums a term may be projected from: over one row, `list_aggregate([value], name)`
(the same aggregate over a list of that row's value: its type and bits, -0.0 made 0.0, a
null kept null, as the grouped query gives them; tests/vge_analytics/store)."""


def _aggregate(term: dict | None) -> dict | None:
    """The aggregate of a parsed term `coalesce(aggregate [FILTER (WHERE ...)], 0)`, as
    `ratio_terms` wraps it, when it is a built-in call (no schema, DISTINCT, ORDER BY or
    exported state); else None."""
    if term is None or term.get("type") != "OPERATOR_COALESCE":
        return None
    children = term.get("children", [])
    if len(children) != 2 or children[1].get("class") != "CONSTANT":
        return None
    call, zero = children
    plain = (
        zero.get("literal") == {"kind": "INTEGER", "text": "0"}
        and call.get("class") == "FUNCTION"
        and not call.get("schema")
        and not call.get("catalog")
        and not call.get("distinct")
        and not call.get("export_state")
        and not (call.get("order_bys") or {}).get("orders")
    )
    return call if plain else None


def _summed(call: dict, statement: dict, con: duckdb.DuckDBPyConnection):
    """The SQL of the value a sum of `_SUMS` adds up (a value of the row) and the names it
    reads, or None when `call` is not such a sum."""
    arguments = call.get("arguments") or []
    if call.get("function_name") not in _SUMS or len(arguments) != 1 or arguments[0].get("name"):
        return None
    return _of_the_row(arguments[0]["expression"], statement, con)


def _row_term(expression: str, con: duckdb.DuckDBPyConnection) -> tuple[str, set[str]] | None:
    """The projection over one row of a term of `ratio_terms` that is a count (`count(*)`)
    or a sum (`_SUMS`, of a value of the row), either with a `FILTER (WHERE condition)` of
    values of the row, and the names it reads; None for any other term."""
    (text,) = con.execute("SELECT json_serialize_sql(?)", [f"SELECT {expression}"]).fetchone()
    document = json.loads(text)
    if document.get("error") or len(document.get("statements", [])) != 1:
        return None
    statement = document["statements"][0]
    call = _aggregate(_only(statement))
    if call is None:
        return None
    count = call.get("function_name") == "count_star" and not call.get("arguments")
    value = ("", set()) if count else _summed(call, statement, con)
    condition = ("TRUE", set())
    if call.get("filter") is not None:
        condition = _of_the_row(call["filter"], statement, con)
    if value is None or condition is None:
        return None
    names = value[1] | condition[1]
    if count and call.get("filter") is None:
        return "CAST(1 AS BIGINT)", names
    if count:  # 1 when the condition is true, else 0 (false or null)
        return f"CAST(CASE WHEN ({condition[0]}) THEN 1 ELSE 0 END AS BIGINT)", names
    # The sum over the row's value alone, or over none (null) unless the condition is true;
    # the value evaluated on every row, as the grouped query evaluates it (failing there).
    one = "" if call.get("filter") is None else f"[1:CASE WHEN ({condition[0]}) THEN 1 ELSE 0 END]"
    return f"coalesce(list_aggregate([{value[0]}]{one}, '{call['function_name']}'), 0)", names


@functools.lru_cache(maxsize=64)
def _row_terms(numerator: str, denominator: str) -> tuple[str, str, frozenset[str]] | None:
    """The projections of the terms `numerator` and `denominator` (as `ratio_terms` writes
    them) when both are counts or sums, and the names they read (`_row_term`), else None."""
    with duckdb.connect() as con:  # parses only: no table, no file
        try:
            terms = [_row_term(e, con) for e in (numerator, denominator)]
        except (duckdb.Error, json.JSONDecodeError, KeyError, TypeError, AttributeError):
            return None
    if terms[0] is None or terms[1] is None:
        return None
    return terms[0][0], terms[1][0], frozenset(terms[0][1] | terms[1][1])


def row_terms(ratio: Ratio) -> tuple[str, str, frozenset[str]] | None:
    """The projections over one row of the terms of `ratio`, a ratio of the episodes grain
    whose numerator and denominator are counts or sums (`_row_term`), and the names they
    read; else None."""
    if ratio.grain != EPISODES_TABLE:
        return None
    (numerator, _), (denominator, _) = ratio_terms([ratio])
    return _row_terms(numerator, denominator)


def _expected(schema: pa.Schema, columns: Sequence[str]) -> pl.Schema:
    """The polars types DuckDB gives `columns` of a table of `schema` (a dictionary column
    as its values)."""
    fields = [schema.field(c) for c in columns]
    plain = [
        f.with_type(f.type.value_type) if pa.types.is_dictionary(f.type) else f for f in fields
    ]
    return pl.from_arrow(pa.schema(plain).empty_table()).schema


_FILES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _run_files(source: object) -> dict[str, list[str]] | None:
    """`_datasets.run_files` of a table's source of the store (built), listed once per
    dataset of files (not for each part)."""
    if source in _FILES:  # (a source that is not a dataset is never kept: not weakly held)
        return _FILES[source]
    files = run_files(source)
    if files is not None:  # a dataset of files (weakly held)
        _FILES[source] = files
    return files


def _part_rows(
    store: Store, columns: Sequence[str], runs: Sequence[str] | None
) -> pl.DataFrame | None:
    """`columns` of the episodes of `runs` (None: all), read by polars from the files of
    those runs in the table's dataset (the one DuckDB scans), typed as DuckDB reads them
    there, each file's run_id its run (the dataset's partition, whatever the file holds, as
    DuckDB reads it); None when they are not so read here (not on the local disk, no file,
    a file whose run is not known or of other types: the grouped query answers)."""
    source = store.sources[EPISODES_TABLE]
    if isinstance(source, Deferred):
        source = source.source()
    files = _run_files(source)
    if files is None:
        return None
    chosen = [r for r in (sorted(files) if runs is None else runs) if r in files]
    if not chosen:
        return None
    paths = [p for run in chosen for p in files[run]]
    if not all(_in_its_folder(p, run) for run in chosen for p in files[run]):
        return None
    scan = pl.scan_parquet(
        paths,
        hive_partitioning=True,  # run_id: the file's run, as the dataset has it
        hive_schema={PARTITION_KEY: pl.String},
        try_parse_hive_dates=False,
        glob=False,  # a path is a name, not a pattern (an OUT named `out[12]`)
        missing_columns="insert",  # as the dataset unifies the files: null there
    )
    frame = scan.select(columns).collect()
    return frame if frame.schema == _expected(source.schema, columns) else None


def _in_order(frame: pl.DataFrame) -> bool:
    """Whether the keys of `frame` strictly increase, run then episode (none null, none
    repeated)."""
    run, episode = pl.col("run_id"), pl.col("episode_id")
    after = (run.shift(-1) > run) | ((run.shift(-1) == run) & (episode.shift(-1) > episode))
    check = after.head(frame.height - 1).fill_null(False).all()
    nulls = pl.any_horizontal(run.is_null().any(), episode.is_null().any())
    return bool(frame.select(check & ~nulls).item())


def projected_terms(
    store: Store,
    ratio: Ratio,
    held: Sequence[str],
    sources: Sequence[str],
    runs: Sequence[str] | None = None,
) -> pl.DataFrame | None:
    """The rows `_episode_terms._compute` gives for `ratio` and `runs` (run_id, episode_id,
    `held`, the terms; sorted by run and episode), as a projection of the episodes table, or
    None when it cannot give them so: a term that is neither a count nor a sum
    (`row_terms`), keys that repeat or are null, a projection that fails (the caller
    computes them as before)."""
    terms = row_terms(ratio)
    bounds = query_bounds()
    if terms is None or (bounds is not None and bounds.isolated and sources):
        return None  # (an isolated query opens OUT afresh, without this part's rows)
    numerator, denominator, names = terms
    columns = store.columns.get(EPISODES_TABLE, {})
    read = [c for c in columns if c in names]
    if any(columns[c] not in _FIXED for c in read):
        return None  # (a text or list read whole here: DuckDB's grouped query streams it)
    read = read or ["episode_id"]
    try:
        rows = _part_rows(store, list(dict.fromkeys([*_KEYS, *held, *read])), runs)
    except (OSError, pa.ArrowException, pl.exceptions.PolarsError):
        return None
    if rows is None:
        return None
    num, den = (term_name(ratio, p) for p in ("num", "den"))
    sql = (
        f"SELECT {numerator} AS {quote_ident(num)}, {denominator} AS {quote_ident(den)} "
        f"FROM {_ROWS} AS g"
    )
    table = rows.select(read).to_arrow()
    derived = dataclasses.replace(store, sources={**store.sources, _ROWS: table})
    try:
        values = run_query(derived, sql, [], sources=sources)
    except QueryLimitError:
        raise  # a bound stopped it: the grouped query would be stopped too
    except (duckdb.Error, QueryError, pa.ArrowException, pl.exceptions.PolarsError):
        return None  # (a condition that does not bind here: the grouped query answers)
    if values.height != rows.height:
        return None
    frame = rows.select(list(dict.fromkeys([*_KEYS, *held]))).hstack(values.select([num, den]))
    if not _in_order(frame):
        frame = frame.sort(list(_KEYS))
        if not _in_order(frame):
            return None
    return frame


__all__ = ["projected_terms", "row_terms"]
