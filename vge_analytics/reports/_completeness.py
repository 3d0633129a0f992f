"""Runs that are not finished: their run.json says `complete: false` (PROTOCOL §1.4, §10.3),
the runs table's `complete` column (§7.5). Their metrics cover the episodes written so far
only, so every report names them and marks their rows: one warning line each, and a mark on
the run's label (`INCOMPLETE_MARK`) or a `complete` column where a table is read by tools.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import polars as pl

from ..store import open_store, run_query

INCOMPLETE_MARK = " (incomplete)"
"""What the label of an incomplete run carries in the tables for people and the dashboard."""


@dataclass(frozen=True, slots=True)
class RunCompleteness:
    """What a run's run.json says of its completeness (None: it does not say)."""

    run_id: str
    complete: bool | None
    infrastructure_failures: int | None

    @property
    def incomplete(self) -> bool:
        return self.complete is False

    def warning(self) -> str:
        """One line naming the run and its failures."""
        failures = self.infrastructure_failures
        why = (
            f"{failures} episode(s) ended on an infrastructure failure and are not scored"
            if failures
            else "it stopped before every selected episode was played"
        )
        return (
            f"warning: run {self.run_id!r} is incomplete (run.json: complete false): {why}; "
            "its metrics cover the episodes written so far (vge run --resume completes it)"
        )


def completeness(out, run_ids: Sequence[str] | None = None) -> list[RunCompleteness]:
    """Every run of OUT (or those of `run_ids`), sorted by run id."""
    store = open_store(out)
    sql = "SELECT run_id, complete, infrastructure_failures FROM runs"
    params: list[object] = []
    if run_ids is not None:
        sql += " WHERE run_id IN (SELECT unnest(CAST(? AS VARCHAR[])))"
        params.append(list(run_ids))
    rows = run_query(store, sql + " ORDER BY run_id", params).to_dicts()
    return [RunCompleteness(r["run_id"], r["complete"], r["infrastructure_failures"]) for r in rows]


def incomplete_runs(out, run_ids: Sequence[str] | None = None) -> list[RunCompleteness]:
    """The runs of OUT (or of `run_ids`) whose run.json says they are not complete."""
    return [r for r in completeness(out, run_ids) if r.incomplete]


def mark_incomplete(df: pl.DataFrame, column: str, run_ids: Iterable[str]) -> pl.DataFrame:
    """`df` (with a run_id column) with `INCOMPLETE_MARK` after the value of `column` on the
    rows of the runs `run_ids`."""
    return mark_rows(df, column, df["run_id"].is_in(list(run_ids)))


def mark_rows(df: pl.DataFrame, column: str, flags: pl.Series) -> pl.DataFrame:
    """`df` with `INCOMPLETE_MARK` after the value of `column` where `flags` is true."""
    label = pl.col(column).cast(pl.String)
    return df.with_columns(
        pl.when(flags).then(label + pl.lit(INCOMPLETE_MARK)).otherwise(label).alias(column)
    )


def with_complete_column(
    df: pl.DataFrame, runs: Sequence[RunCompleteness], after: str = "run_id"
) -> pl.DataFrame:
    """`df` (grouped by run_id) with a `complete` column after the column `after` (its last
    group column): run.json's word on each run (null where it says nothing), for the formats
    tools read."""
    said = {r.run_id: r.complete for r in runs}
    column = pl.Series("complete", [said.get(r) for r in df["run_id"]], dtype=pl.Boolean)
    return df.insert_column(df.columns.index(after) + 1, column)


__all__ = [
    "INCOMPLETE_MARK",
    "RunCompleteness",
    "completeness",
    "incomplete_runs",
    "mark_incomplete",
    "mark_rows",
    "with_complete_column",
]
