"""`vge sql OUT "QUERY"`: read-only SQL over the views steps, episodes, goals, runs."""

from __future__ import annotations

from pathlib import Path

import typer

from .._format import check_format
from .._output import FORMAT_HELP, emit
from .._sql import sql as run_sql


def sql(
    out: Path = typer.Argument(..., help="Replay output directory."),
    query: str = typer.Argument(..., help="One SELECT query over steps, episodes, goals, runs."),
    fmt: str = typer.Option("table", "--format", "-f", help=FORMAT_HELP),
) -> None:
    """Read-only SQL over the views steps, episodes, goals, runs.

    One SELECT statement; writing statements and access to files outside OUT are refused.
    """
    check_format(fmt)
    emit(run_sql(out, query), fmt, marks=False)


def register(app: typer.Typer) -> None:
    app.command("sql")(sql)
