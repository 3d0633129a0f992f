"""`vge sql OUT "QUERY"`: read-only SQL over the views steps, episodes, goals, runs, with
memory and time limits (see `vge_analytics.store._limits`)."""

from __future__ import annotations

import typer

from .. import reports
from .._errors import QueryLimitError
from ..store import CLI_MAX_ROWS, CLI_TIMEOUT, SqlLimits, process_memory_cap, sized_memory_limit
from ._bounds import hinted
from ._options import format_option, memory_limit_option, out_argument
from ._output import emit, emit_stream


def sql(
    out: str = out_argument(),
    query: str = typer.Argument(..., help="One SELECT query over steps, episodes, goals, runs."),
    fmt: str = format_option(),
    timeout: float = typer.Option(
        CLI_TIMEOUT, "--timeout", help="Stop the query after this many seconds (0: no limit)."
    ),
    memory_limit: str = memory_limit_option(),
    max_rows: int = typer.Option(
        CLI_MAX_ROWS,
        "--max-rows",
        min=1,
        help="Rows printed in the formats for people (table, markdown, latex); csv and json "
        "write every row, as they come.",
    ),
) -> None:
    """Read-only SQL over the views steps, episodes, goals, runs.

    One SELECT statement; writing statements and access to files outside OUT are refused.
    A query that goes past its time or memory limit stops with a one-line error.
    """
    reports.check_format(fmt)  # the renderers imported, before the cap below
    # The query's libraries (DuckDB, pyarrow, polars) are imported before the process's memory
    # is capped: the cap is for what the query takes, not for the code that runs it.
    from ..store import sql_head, stream

    limits = SqlLimits.make(memory=sized_memory_limit(out, memory_limit), timeout=timeout)
    try:
        with process_memory_cap(limits):
            if fmt in ("csv", "json"):
                with stream(out, query, limits=limits) as result:
                    emit_stream(result, fmt)
                return
            head = sql_head(out, query, max_rows, limits=limits)
    except QueryLimitError as exc:
        raise hinted(exc) from None
    emit(head.frame, fmt, marks=False)
    if head.truncated:
        typer.echo(
            f"note: the first {max_rows:,} rows are shown; --format csv or json writes every row",
            err=True,
        )


def register(app: typer.Typer) -> None:
    app.command("sql")(sql)
