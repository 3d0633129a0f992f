"""The Significance page: every pair of runs with its adjusted p-value, the ranking with its
tied groups, and pass@k / pass^k curves of repeated runs (docs/STATISTICS.md)."""

from __future__ import annotations

import polars as pl

from ..reports import MISSING, AllPairs, Repeated

CLUSTER_WORDS: dict[str, str] = {
    "device": "devices",
    "category": "categories",
    "episode": "single episodes",
}
"""How the pages name the unit resampled (plural)."""
CORRECTION_WORDS: dict[str, str] = {
    "holm": "Holm-adjusted",
    "bh": "Benjamini-Hochberg-adjusted",
    "none": "unadjusted",
}


def significance_caption(result: AllPairs) -> str:
    """What the matrix and the letters mean, with the numbers of this result."""
    s = result.summary.row(0, named=True)
    return (
        f"{s['pairs']} pairs of {s['entries']} {result.by} values, each on its common "
        f"episodes: {s['significant']} differ at α = {result.alpha:g} "
        f"({CORRECTION_WORDS[result.correction]} p-values of the cluster sign-flip test, "
        f"{CLUSTER_WORDS[result.cluster]} resampled). Entries sharing a letter are not "
        "distinguishable."
    )


def pair_matrix(result: AllPairs) -> pl.DataFrame:
    """The pairs as a square, both triangles (row, column, diff = column − row of the
    metric, p_adjusted, significant, text), rows and columns in ranking order."""
    a, b = f"{result.by}_a", f"{result.by}_b"
    pairs = result.pairs.select(
        pl.col(a).alias("row"),
        pl.col(b).alias("column"),
        "diff",
        "p_adjusted",
        "significant",
    )
    mirrored = pairs.select(
        pl.col("column").alias("row"),
        pl.col("row").alias("column"),
        -pl.col("diff"),
        "p_adjusted",
        "significant",
    )
    p = pl.col("p_adjusted")
    return pl.concat([pairs, mirrored]).with_columns(
        text=pl.when(p.is_null())
        .then(pl.lit(MISSING))
        .when(p < 0.01)
        .then(pl.lit("<.01"))
        .otherwise(p.round(2).cast(pl.String))
    )


def ranking_order(result: AllPairs) -> list[str]:
    return result.ranking[result.by].cast(pl.String).to_list()


def passk_curves(result: Repeated) -> pl.DataFrame:
    """pass@k and pass^k of the groups of two or more runs, long (group, k, measure, value,
    low, high), for one line per group and measure."""
    multi = result.groups.filter(pl.col("n_runs") >= 2)["group"].to_list()
    rows = result.passk.filter(pl.col("group").is_in(multi) & pl.col("pass_at_k").is_not_null())
    parts = [
        rows.select(
            "group",
            "k",
            pl.lit(label).alias("measure"),
            pl.col(name).alias("value"),
            pl.col(f"{name}_low").alias("low"),
            pl.col(f"{name}_high").alias("high"),
        )
        for name, label in (("pass_at_k", "pass@k"), ("pass_hat_k", "pass^k"))
    ]
    return pl.concat(parts).sort("group", "measure", "k")


def repeated_rows(result: Repeated) -> pl.DataFrame:
    """The groups of two or more runs, as the page shows them."""
    return result.groups.filter(pl.col("n_runs") >= 2).select(
        "group",
        pl.col("runs"),
        pl.col("n_runs").alias("seeds"),
        pl.col("n_episodes").alias("episodes"),
        pl.col("SR_mean").alias("SR mean"),
        pl.col("SR_sd").alias("SD between seeds"),
        pl.col("ci_low").alias("CI low"),
        pl.col("ci_high").alias("CI high"),
    )
