"""The SQL page: a query in a process of its own, its limits and captions."""


from __future__ import annotations

import json
from pathlib import Path

import polars as pl

from ..store import (
    CELL_CHARS,
    RESULT_BYTES,
    SLOT_WAIT,
    IsolatedResult,
    SqlLimits,
    format_size,
    open_store,
    run_isolated,
)

EXAMPLE_QUERIES: dict[str, str] = {
    "Success rate and steps per model": (
        "SELECT model, count(*) AS episodes, round(100 * avg(success::INT), 2) AS SR,\n"
        "       round(avg(L_act), 1) AS avg_steps\n"
        "FROM episodes\nGROUP BY model\nORDER BY SR DESC"
    ),
    "Most common error per category": (
        "SELECT category, error_type, count(*) AS n\n"
        "FROM steps\nWHERE error_type IS NOT NULL AND NOT truncated\n"
        "GROUP BY category, error_type\n"
        "QUALIFY row_number() OVER (PARTITION BY category ORDER BY count(*) DESC, error_type) = 1\n"
        "ORDER BY n DESC"
    ),
    "Episodes no run solved": (
        "SELECT episode_id, any_value(device_id) AS device_id, count(*) AS runs\n"
        "FROM episodes\nGROUP BY episode_id\nHAVING NOT bool_or(success)\nORDER BY episode_id"
    ),
    "Clicks far from every target": (
        "SELECT run_id, episode_id, step, view_before, x, y, round(distance, 1) AS distance\n"
        "FROM steps\nWHERE distance > 200 AND NOT truncated\nORDER BY distance DESC\nLIMIT 100"
    ),
    "Dangerous actions per run": (
        "SELECT run_id, count(*) FILTER (WHERE dangerous) AS dangerous_steps,\n"
        "       count(*) AS steps\nFROM steps\nWHERE NOT truncated\nGROUP BY run_id\n"
        "ORDER BY dangerous_steps DESC"
    ),
    "Steps that diverge from the log": (
        "SELECT run_id, episode_id, step, diverged_fields, recorded_feedback, feedback_kind\n"
        "FROM steps\nWHERE diverged\nORDER BY run_id, episode_id, step\nLIMIT 100"
    ),
    "Run facets": "SELECT * FROM runs ORDER BY run_id",
}
"""The SQL page's examples (each is checked to run on the test output)."""


def table_columns_frame(out: str | Path) -> pl.DataFrame:
    """(table, column, type) of the four tables of OUT, for the SQL page's reference."""
    store = open_store(out)
    rows = [
        {"table": table, "column": column, "type": sql_type}
        for table, columns in store.columns.items()
        for column, sql_type in columns.items()
    ]
    return pl.DataFrame(rows, schema={"table": pl.String, "column": pl.String, "type": pl.String})


def sql_preview(
    out: str | Path, query: str, rows: int, limits: SqlLimits, *, max_queries: int | None = None
) -> IsolatedResult:
    """The SQL page's query: the first `rows` rows, parsed and computed in a process of its
    own within `limits`, with at most `max_queries` such processes at once across the
    sessions (`vge_analytics.store._isolated`), so no query can take the dashboard down."""
    return run_isolated(out, query, rows, limits, max_queries=max_queries)


def example_preview(
    out: str | Path, name: str, rows: int, limits: SqlLimits, *, max_queries: int | None = None
) -> IsolatedResult:
    """The SQL page's example `name` (`EXAMPLE_QUERIES`) as `sql_preview` runs it. An example
    reads OUT's tables alone (no `random()`, no `now()`), so the dashboard keeps its result
    beside OUT for the next server, as it keeps the other pages' defaults; a query a person
    wrote is never kept."""
    return sql_preview(out, EXAMPLE_QUERIES[name], rows, limits, max_queries=max_queries)


def sql_limits_note(limits: SqlLimits, rows: int, max_queries: int | None = None) -> str:
    """What the SQL page says about its limits (and, given, the number of queries at once)."""
    time = f"after {limits.timeout:g} s or " if limits.timeout is not None else ""
    note = (
        f"Each query runs in a process of its own and is stopped {time}past "
        f"{limits.describe()}; the page shows the first {rows:,} rows."
    )
    if max_queries is not None:
        many = "1 query runs" if max_queries == 1 else f"{max_queries} queries run"
        note += f" At most {many} at once, for all visitors; another waits up to {SLOT_WAIT:g} s."
    return note


def sql_caption(result: IsolatedResult, rows: int) -> str:
    """What the SQL page says about a result: rows, time, memory, and what was cut (by the
    row cap, or by the query process to fit a page: `bound_result`)."""
    took = f"in {result.seconds:.2f} s, peak memory {format_size(result.peak_memory)}"
    n = result.frame.height
    cut = result.cut
    if cut.cells or cut.rows:
        return _cut_caption(result, took)
    if result.truncated:
        return (
            f"The first {rows:,} rows ({took}): the query has more. The page and the CSV "
            f"download hold these {rows:,} rows; `vge sql OUT QUERY --format csv` writes them all."
        )
    return f"{n:,} {'row' if n == 1 else 'rows'} ({took})."


def _cut_caption(result: IsolatedResult, took: str) -> str:
    n, cut = result.frame.height, result.cut
    what = []
    if cut.cells:
        cells = "1 text cell" if cut.cells == 1 else f"{cut.cells:,} text cells"
        what.append(f"{cells} longer than {CELL_CHARS:,} characters cut (marked “… [cut: …]”)")
    if cut.rows:
        left = "1 row" if cut.rows == 1 else f"{cut.rows:,} rows"
        what.append(f"{left} past the page's {format_size(RESULT_BYTES)} left out")
    more = ", and the query has more rows" if result.truncated else ""
    return (
        f"{n:,} {'row' if n == 1 else 'rows'} shown ({took}); {format_size(cut.bytes)} cut to "
        f"fit the page: {' and '.join(what)}{more}. The page and the CSV download hold what "
        f"is shown; `vge sql OUT QUERY --format csv` writes everything."
    )


def csv_bytes(df: pl.DataFrame) -> bytes:
    """CSV of any query result; list and struct columns are written as JSON text."""
    nested = [c for c, t in df.schema.items() if isinstance(t, (pl.List, pl.Array, pl.Struct))]
    if nested:
        df = df.with_columns(
            pl.col(c).map_elements(
                lambda v: json.dumps(v if not isinstance(v, pl.Series) else v.to_list()),
                return_dtype=pl.String,
            )
            for c in nested
        )
    return df.write_csv().encode("utf-8")
