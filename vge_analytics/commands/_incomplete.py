"""How the commands that report metrics present an incomplete run (PROTOCOL §10.3): a warning
line on stderr naming it and its failures, and its rows marked, so that its metrics are never
read as a finished run's."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import typer

from .. import reports

if TYPE_CHECKING:
    import polars as pl

    from ..reports import RunCompleteness

PEOPLE_FORMATS = ("table", "markdown", "latex")


def say(line: str) -> None:
    """Write one line of a command's on stderr (a warning)."""
    typer.echo(line, err=True)


def warn_incomplete(
    out: str, run_ids: Sequence[str] | None = None, *, warn: Callable[[str], None] = say
) -> list[RunCompleteness]:
    """One warning line (`warn`: on stderr) per incomplete run of OUT (or of `run_ids`);
    every run's completeness, for marking the rows."""
    runs = reports.completeness(out, run_ids)
    for run in runs:
        if run.incomplete:
            warn(run.warning())
    return runs


def marked(
    df: pl.DataFrame, runs: Sequence[RunCompleteness], fmt: str, groups: Sequence[str]
) -> pl.DataFrame:
    """A table grouped by `groups` (run_id among them) with its incomplete runs marked: their
    run_id carries `(incomplete)` in the formats for people, a `complete` column after the
    group columns says it in the others. Unchanged when every run is complete (or says
    nothing), or when the table is not grouped by run."""
    incomplete = [r.run_id for r in runs if r.incomplete]
    if not incomplete or "run_id" not in df.columns:
        return df
    if fmt in PEOPLE_FORMATS:
        return reports.mark_incomplete(df, "run_id", incomplete)
    return reports.with_complete_column(df, runs, after=[c for c in groups if c in df.columns][-1])


def marked_rows(df: pl.DataFrame, label: str, flags: pl.Series) -> pl.DataFrame:
    """`df` with the rows of `flags` marked on `label` (a table whose run_id was dropped)."""
    return reports.mark_rows(df, label, flags) if flags.any() else df


__all__ = ["PEOPLE_FORMATS", "marked", "marked_rows", "say", "warn_incomplete"]
