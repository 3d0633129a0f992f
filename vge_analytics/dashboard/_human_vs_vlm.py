"""The Human vs VLM page: paired comparison, error differences, flipped episodes."""

from __future__ import annotations

import polars as pl

from ..metrics import MetricSet
from ..reports import Comparison
from ._leaderboard import _metric
from ._significance import CLUSTER_WORDS, CORRECTION_WORDS


def run_choices(runs: pl.DataFrame) -> tuple[list[str], list[str]]:
    """(reference runs, model runs) for the human-vs-VLM page: human runs first as the
    reference (all runs if there is none), non-human runs as the models, the most successful
    first, as the paper compares its best model (all runs if there is none).

    `runs` is a `runs()` table (with n_success and n_episodes)."""
    ranked = runs.with_columns(
        __rate=pl.col("n_success") / pl.when(pl.col("n_episodes") > 0).then(pl.col("n_episodes"))
    ).sort(["__rate", "run_id"], descending=[True, False], nulls_last=True)
    human = ranked.filter(pl.col("agent_kind") == "human")["run_id"].to_list()
    other = ranked.filter(pl.col("agent_kind") != "human")["run_id"].to_list()
    everything = ranked["run_id"].to_list()
    return (human + other if human else everything), (other or everything)


def comparison_rows(
    metrics: pl.DataFrame, label_a: str, label_b: str, metric_set: MetricSet | None = None
) -> pl.DataFrame:
    """A `Comparison.metrics` table for people: metric (with its arrow), both values under
    the runs' names, the difference B - A, its 95% clustered interval, whether the interval
    excludes 0, the clustered SE, the design effect and the adjusted p-value."""
    arrows = {m: _metric(m, metric_set).arrow for m in metrics["metric"].to_list()}
    return metrics.select(
        pl.col("metric").map_elements(lambda m: f"{m} {arrows[m]}", return_dtype=pl.String),
        pl.col("A").alias(label_a),
        pl.col("B").alias(label_b),
        pl.col("diff").alias(f"{label_b} − {label_a}"),
        pl.col("ci_low").alias("CI low"),
        pl.col("ci_high").alias("CI high"),
        ((pl.col("ci_low") > 0) | (pl.col("ci_high") < 0)).alias("CI excludes 0"),
        pl.col("se").alias("SE"),
        pl.col("deff").alias("design effect"),
        pl.col("p_adjusted").alias("p (adjusted)"),
    )


def interval_caption(cmp: Comparison) -> str:
    """How the intervals and p-values of a comparison were made, with its numbers."""
    unit = CLUSTER_WORDS[cmp.cluster]
    text = (
        f"95% intervals from {cmp.resamples} resamples of the {cmp.n_clusters} {unit} the "
        f"common episodes are in (all of a resampled one's episodes, the same draw for both "
        "runs); SE is the clustered standard error of the difference, the design effect its "
        "variance over the one of independent episodes; p-values of the cluster sign-flip "
        f"test, {CORRECTION_WORDS[cmp.correction]} across the metrics."
    )
    return text + (f" Note: {cmp.note}." if cmp.note else "")


def error_difference_rows(errors: pl.DataFrame, label_a: str, label_b: str) -> pl.DataFrame:
    """A `Comparison.errors` table like the paper's: error type, share of all errors of each
    run (%), and the difference B - A in percentage points."""
    return errors.select(
        pl.col("label").alias("error type"),
        pl.col("share_a").alias(f"{label_a} %"),
        pl.col("share_b").alias(f"{label_b} %"),
        pl.col("diff_pp").alias("difference (pp)"),
        pl.col("count_a").alias(f"{label_a} errors"),
        pl.col("count_b").alias(f"{label_b} errors"),
    )


def flip_rows(flips: pl.DataFrame, run_a: str, run_b: str) -> pl.DataFrame:
    """`Comparison.flips` with who solved the episode and `run_id`, the run that failed it
    (what the link opens: where it went wrong)."""
    return flips.select(
        "episode_id",
        "device_id",
        "category",
        pl.when(pl.col("direction") == "A_only")
        .then(pl.lit(run_a))
        .otherwise(pl.lit(run_b))
        .alias("solved only by"),
        pl.when(pl.col("direction") == "A_only")
        .then(pl.lit(run_b))
        .otherwise(pl.lit(run_a))
        .alias("run_id"),
    )
