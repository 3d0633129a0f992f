"""The Errors page: error shares and sampled steps of an error type."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import polars as pl

from replay.io import STEPS_TABLE

from ..store import (
    Filters,
    build_scope,
    check_columns,
    open_store,
    quote_ident,
    run_query,
)
from ._first_rows import runs_holding_first


def error_step_sample(
    out: str | Path,
    error_type: str,
    where: Filters = None,
    columns: Sequence[str] = ("run_id", "episode_id", "step"),
    *,
    limit: int = 500,
) -> tuple[pl.DataFrame, int]:
    """The first `limit` scored steps with `error_type` (by run, episode, step) and how many
    there are in all: the drill-down table. Unlike `steps_with_error`, the limit is applied
    in the query, so a common error type on the full benchmark (10^5 steps) stays cheap."""
    store = open_store(out)
    check_columns(store, [*(where or {}), *columns], [STEPS_TABLE], "filter/column")
    order = "ORDER BY g.run_id, g.episode_id, g.step LIMIT ?"
    scope = build_scope(store, STEPS_TABLE, [], where)
    base = f"FROM {scope.from_sql} WHERE {scope.where_sql} AND g.error_type = ?"
    runs, total = runs_holding_first(store, base, [*scope.params, error_type], int(limit))
    # The columns are read from the runs of the first rows only: the scan skips the other
    # runs' files instead of sorting every match of every step (same rows).
    scope = build_scope(store, STEPS_TABLE, [], {**(where or {}), "run_id": runs})
    cols = ", ".join(f"g.{quote_ident(c)}" for c in columns)
    base = f"FROM {scope.from_sql} WHERE {scope.where_sql} AND g.error_type = ?"
    df = run_query(store, f"SELECT {cols} {base} {order}", [*scope.params, error_type, int(limit)])
    return df, total


def error_share_wide(dist: pl.DataFrame) -> pl.DataFrame:
    """An `error_distribution(..., labels=True)` result with a `group` column as one row per
    group: `errors` (their number), then each error type's share in percent (paper names)."""
    from ..reports import ERROR_LABELS, ERROR_TYPES

    labels = [ERROR_LABELS[t] for t in ERROR_TYPES]
    order = dist["group"].unique(maintain_order=True)
    totals = dist.group_by("group", maintain_order=True).agg(errors=pl.col("count").sum())
    wide = dist.pivot(on="label", index="group", values="share", aggregate_function="first")
    for label in labels:
        if label not in wide.columns:
            wide = wide.with_columns(pl.lit(None, dtype=pl.Float64).alias(label))
    return (
        pl.DataFrame({"group": order})
        .join(totals, on="group", how="left")
        .join(wide.select("group", *labels), on="group", how="left")
    )
