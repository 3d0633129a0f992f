"""The Rescore page: what a metrics folder changes, as tables and slopes."""


from __future__ import annotations

import polars as pl

from ..reports import Rescore, group_label


def rescore_changes(result: Rescore) -> pl.DataFrame:
    """The rows of a `rescore` result for people: metric, group (the group values as one
    label), before, after, difference, rank before, rank after and the move (`▲ 2`...)."""
    table = result.tables()["changes"]
    labels = [group_label(row, result.by) for row in table.iter_rows(named=True)]
    return table.select(
        "metric",
        pl.Series("group", labels, dtype=pl.String),
        "before",
        "after",
        pl.col("delta").alias("after − before"),
        pl.col("rank_before").alias("rank before"),
        pl.col("rank_after").alias("rank after"),
        "move",
    )


def rescore_rankings(result: Rescore) -> pl.DataFrame:
    """One row per metric of a `rescore` result: change, defining file, groups ranked both
    times, Kendall's tau-b between the rankings, the groups whose rank moved."""
    return result.tables()["rankings"].select(
        "metric",
        "change",
        pl.col("source").alias("file"),
        pl.col("groups").alias("groups ranked"),
        pl.col("kendall_tau_b").alias("Kendall τ-b"),
        pl.col("moved").alias("rank moved"),
    )


def rank_slopes(result: Rescore, metric: str) -> pl.DataFrame:
    """A metric's ranks before and after, in long form for a slope chart: group, ranking
    (`before`, `after`), rank, value; groups without a rank are left out."""
    rows = result.rows.filter(pl.col("metric") == metric)
    labels = pl.Series(
        "group", [group_label(r, result.by) for r in rows.iter_rows(named=True)], pl.String
    )
    parts = [
        rows.select(
            labels,
            pl.lit(when).alias("ranking"),
            pl.col(f"rank_{when}").alias("rank"),
            pl.col(when).alias("value"),
        )
        for when in ("before", "after")
    ]
    return pl.concat(parts).drop_nulls("rank")
