"""Paired comparison of two runs on the episodes both have (human vs VLM, model vs model).

- Metrics: each registry metric on the common episodes for run A and run B, the difference
  B - A, and its uncertainty with the benchmark's structure respected (docs/STATISTICS.md):
  episodes of one device move together, so by default the *devices* are resampled, not the
  episodes (`cluster`: `device`, `category`, or `episode` for independent episodes). A
  resample draws the clusters with replacement and takes all their common episodes, the same
  draw for both runs and every metric; its metric is the pooled `scale * sum(num) /
  sum(den)` of the drawn episodes' terms (`episode_terms`). Beside the 95% percentile
  interval: the clustered (CR1) standard error of B - A, the naive one (independent
  episodes), the design effect (their variances' ratio), the cluster sign-flip p-value, and
  that p-value adjusted across the metrics reported (`correction`: Holm by default).
- McNemar's exact test on episode success: b = episodes only A solved, c = episodes only B
  solved; under H0 each discordant pair is A-only with probability 1/2, so the two-sided
  p-value is min(1, 2 * P(X <= min(b, c))) for X ~ Binomial(b + c, 1/2) (1 when b + c = 0);
  beside it the clustered McNemar test (Durkalski), which counts the discordant episodes
  per cluster.
- The error-type distribution of each run on the common episodes and the difference B - A
  in percentage points (the paper's human vs Gemini table).
- The episodes that flip: solved by A only, solved by B only.
- Whether each run is complete (run.json's word, PROTOCOL §7.5): a run cut short is compared
  on the episodes it has, and the summary says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from math import comb

import numpy as np
import polars as pl

from .._errors import AnalyticsError
from ..metrics import Metric, MetricsSource, metric_set
from ..store import Store, check_runs, check_same_benchmark, open_store, run_query
from ._completeness import completeness
from ._defaults import DEFAULT_RESAMPLES, DEFAULT_SEED
from ._taxonomy import ERROR_LABELS, error_distribution
from .inference import (
    CLUSTER_COLUMNS,
    DEFAULT_CLUSTER,
    DEFAULT_CORRECTION,
    PairStatistics,
    adjust_p,
    check_cluster,
    check_correction,
    check_resampling,
    cluster_codes,
    clustered_mcnemar,
    entity_terms,
    finite,
    pair,
    pair_statistics,
    test_name,
)

METRIC_COLUMNS: dict[str, pl.DataType] = {
    "metric": pl.String,
    "direction": pl.String,
    "unit": pl.String,
    "A": pl.Float64,
    "B": pl.Float64,
    "diff": pl.Float64,
    "ci_low": pl.Float64,
    "ci_high": pl.Float64,
    "se": pl.Float64,
    "se_naive": pl.Float64,
    "deff": pl.Float64,
    "p_value": pl.Float64,
    "p_adjusted": pl.Float64,
}
"""The columns of `Comparison.metrics`."""


def mcnemar_exact(b: int, c: int) -> float:
    """Two-sided exact McNemar p-value from the discordant counts b and c."""
    n = b + c
    if n == 0:
        return 1.0
    k = min(b, c)
    tail = sum(comb(n, i) for i in range(k + 1))
    return float(min(Fraction(1), Fraction(2 * tail, 2**n)))


@dataclass
class Comparison:
    """Result of `compare`: scalars plus one polars DataFrame per section."""

    run_a: str
    run_b: str
    model_a: str
    model_b: str
    n_common: int
    n_only_a: int
    n_only_b: int
    seed: int
    resamples: int
    metrics: pl.DataFrame
    """metric, direction, unit, A, B, diff (B - A), ci_low, ci_high (95% cluster bootstrap),
    se (clustered CR1), se_naive, deff, p_value (cluster sign-flip), p_adjusted."""
    mcnemar: pl.DataFrame
    """One row: n_common, both, a_only (b), b_only (c), neither, p_value (exact McNemar),
    p_cluster (clustered McNemar)."""
    errors: pl.DataFrame
    """error_group, error_type, label, count_a, count_b, share_a, share_b, diff_pp (B - A)."""
    flips: pl.DataFrame
    """episode_id, device_id, category, direction ('A_only' or 'B_only')."""
    complete_a: bool | None = None
    complete_b: bool | None = None
    """run.json's `complete` of each run (None: it does not say)."""
    cluster: str = DEFAULT_CLUSTER
    """The unit resampled: device, category or episode."""
    n_clusters: int = 0
    correction: str = DEFAULT_CORRECTION
    test: str = ""
    """The test behind p_value, as the summary names it."""
    note: str | None = None
    """What the reader must know (one cluster: no interval)."""
    summary: pl.DataFrame = field(init=False)
    """One row describing the pairing (runs, models, whether each is complete, episode
    counts, clusters, seed, resamples, correction, test, note)."""

    def __post_init__(self) -> None:
        self.summary = pl.DataFrame(
            [
                {
                    "run_a": self.run_a,
                    "model_a": self.model_a,
                    "run_b": self.run_b,
                    "model_b": self.model_b,
                    "complete_a": self.complete_a,
                    "complete_b": self.complete_b,
                    "n_common": self.n_common,
                    "n_only_a": self.n_only_a,
                    "n_only_b": self.n_only_b,
                    "cluster": self.cluster,
                    "n_clusters": self.n_clusters,
                    "seed": self.seed,
                    "resamples": self.resamples,
                    "correction": self.correction,
                    "test": self.test,
                    "note": self.note,
                }
            ],
            schema_overrides={
                "complete_a": pl.Boolean,
                "complete_b": pl.Boolean,
                "note": pl.String,
            },
        )

    def sections(self) -> dict[str, pl.DataFrame]:
        """Every table of the comparison, by name (what the CLI prints)."""
        return {
            "summary": self.summary,
            "metrics": self.metrics,
            "mcnemar": self.mcnemar,
            "errors": self.errors,
            "flips": self.flips,
        }


def metric_rows(chosen: list[Metric], stats: PairStatistics, correction: str) -> pl.DataFrame:
    """The metrics section: one row per metric, p-values adjusted across the metrics."""
    adjusted = adjust_p([finite(p) for p in stats.p_value], correction)
    rows = []
    for i, m in enumerate(chosen):
        a, b = finite(stats.a[i]), finite(stats.b[i])
        diff = b - a if a is not None and b is not None else None
        present = diff is not None
        rows.append(
            {
                "metric": m.name,
                "direction": m.direction,
                "unit": m.unit,
                "A": a,
                "B": b,
                "diff": diff,
                "ci_low": stats.ci_low[i] if present else None,
                "ci_high": stats.ci_high[i] if present else None,
                "se": finite(stats.se[i]),
                "se_naive": finite(stats.se_naive[i]),
                "deff": finite(stats.deff[i]),
                "p_value": finite(stats.p_value[i]),
                "p_adjusted": adjusted[i],
            }
        )
    return pl.DataFrame(rows, schema=METRIC_COLUMNS)


def _episodes(store: Store, run_a: str, run_b: str) -> tuple[pl.DataFrame, pl.DataFrame]:
    eps = run_query(
        store,
        "SELECT run_id, model, episode_id, device_id, category, success FROM episodes "
        "WHERE run_id IN (SELECT unnest(CAST(? AS VARCHAR[])))",
        [[run_a, run_b]],
    )
    return eps.filter(pl.col("run_id") == run_a), eps.filter(pl.col("run_id") == run_b)


def success_tests(
    a_eps: pl.DataFrame, b_eps: pl.DataFrame, cluster_column: str
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """(the McNemar section, the flips) from both runs' episodes (success per episode)."""
    paired = (
        a_eps.select("episode_id", "device_id", "category", pl.col("success").alias("a"))
        .join(b_eps.select("episode_id", pl.col("success").alias("b")), on="episode_id")
        .sort("episode_id")
    )
    a_only_each = (paired["a"] & ~paired["b"]).cast(pl.Float64).to_numpy()
    b_only_each = (~paired["a"] & paired["b"]).cast(pl.Float64).to_numpy()
    codes, names = cluster_codes(paired[cluster_column].to_list())
    per_a = np.bincount(codes, weights=a_only_each, minlength=len(names))
    per_b = np.bincount(codes, weights=b_only_each, minlength=len(names))
    both = int((paired["a"] & paired["b"]).sum())
    a_only, b_only = int(a_only_each.sum()), int(b_only_each.sum())
    mcnemar = pl.DataFrame(
        [
            {
                "n_common": len(paired),
                "both": both,
                "a_only": a_only,
                "b_only": b_only,
                "neither": len(paired) - both - a_only - b_only,
                "p_value": mcnemar_exact(a_only, b_only),
                "p_cluster": clustered_mcnemar(per_a, per_b),
            }
        ]
    )
    flips = (
        paired.filter(pl.col("a") != pl.col("b"))
        .with_columns(
            direction=pl.when(pl.col("a")).then(pl.lit("A_only")).otherwise(pl.lit("B_only"))
        )
        .select("episode_id", "device_id", "category", "direction")
        .sort("direction", "episode_id")
    )
    return mcnemar, flips


def error_difference(store: Store, run_a: str, run_b: str, common: list[str]) -> pl.DataFrame:
    """Both runs' error distributions on the common episodes and B - A in points."""
    dist = error_distribution(
        store, by=("run_id",), where={"run_id": [run_a, run_b], "episode_id": common}
    )
    a_d = dist.filter(pl.col("run_id") == run_a).select(
        "error_group",
        "error_type",
        pl.col("count").alias("count_a"),
        pl.col("share").alias("share_a"),
    )
    b_d = dist.filter(pl.col("run_id") == run_b).select(
        "error_type", pl.col("count").alias("count_b"), pl.col("share").alias("share_b")
    )
    return (
        a_d.join(b_d, on="error_type", how="full", coalesce=True, maintain_order="left")
        .with_columns(
            label=pl.col("error_type").replace_strict(ERROR_LABELS),
            diff_pp=pl.col("share_b") - pl.col("share_a"),
        )
        .select(
            "error_group",
            "error_type",
            "label",
            "count_a",
            "count_b",
            "share_a",
            "share_b",
            "diff_pp",
        )
    )


def _check_runs(store: Store, run_a: str, run_b: str, allow_different: bool) -> None:
    check_runs(store, [run_a, run_b])
    if run_a == run_b:
        raise AnalyticsError(f"compare needs two different runs, got {run_a!r} twice")
    check_same_benchmark(store, [run_a, run_b], allow=allow_different)


def single_cluster_note(cluster: str, n_clusters: int) -> str | None:
    """The note of a pair whose episodes fall in fewer than two clusters, else None."""
    if n_clusters >= 2:
        return None
    return (
        f"the common episodes are all in one {cluster}: no {cluster}-clustered interval, "
        "standard error or p-value (a spread between clusters needs two or more; "
        "--cluster episode treats the episodes as independent)"
    )


def compare(
    out,
    run_a: str,
    run_b: str,
    *,
    metrics: str | list[str] | None = None,
    seed: int = DEFAULT_SEED,
    resamples: int = DEFAULT_RESAMPLES,
    cluster: str = DEFAULT_CLUSTER,
    correction: str = DEFAULT_CORRECTION,
    metrics_dir: MetricsSource = None,
    allow_different_benchmarks: bool = False,
) -> Comparison:
    """Compare run B with run A on their common episodes (see the module docstring).

    `metrics_dir`: a metrics folder (or `MetricSet`) whose metrics are compared; default
    `$VGE_METRICS_DIR`, else the built-ins.

    `allow_different_benchmarks`: compare runs replayed against different benchmarks (refused
    by default, `DifferentBenchmarksError`: their episodes share ids, not tasks)."""
    store = open_store(out)
    check_resampling(seed, resamples)
    check_cluster(cluster)
    check_correction(correction)
    _check_runs(store, run_a, run_b, allow_different_benchmarks)
    available = metric_set(metrics_dir)
    chosen = available.resolve(metrics)
    a_eps, b_eps = _episodes(store, run_a, run_b)
    ids_a, ids_b = set(a_eps["episode_id"]), set(b_eps["episode_id"])
    if not ids_a & ids_b:
        raise AnalyticsError(f"runs {run_a!r} and {run_b!r} have no episode in common")

    terms = entity_terms(store, {run_a: [run_a], run_b: [run_b]}, chosen, available)
    paired = pair(terms, run_a, run_b, chosen, cluster)
    (stats,) = pair_statistics([paired], [m.scale for m in chosen], seed, resamples)
    mcnemar, flips = success_tests(a_eps, b_eps, CLUSTER_COLUMNS[cluster])
    said = {r.run_id: r.complete for r in completeness(store, [run_a, run_b])}
    return Comparison(
        run_a=run_a,
        run_b=run_b,
        model_a=str(a_eps["model"][0]),
        model_b=str(b_eps["model"][0]),
        n_common=len(paired.episodes),
        n_only_a=len(ids_a - ids_b),
        n_only_b=len(ids_b - ids_a),
        seed=seed,
        resamples=resamples,
        metrics=metric_rows(chosen, stats, correction),
        mcnemar=mcnemar,
        errors=error_difference(store, run_a, run_b, paired.episodes),
        flips=flips,
        complete_a=said.get(run_a),
        complete_b=said.get(run_b),
        cluster=cluster,
        n_clusters=len(paired.clusters),
        correction=correction,
        test=test_name(len(paired.clusters), stats.exact, resamples),
        note=single_cluster_note(cluster, len(paired.clusters)),
    )


__all__ = [
    "Comparison",
    "compare",
    "mcnemar_exact",
    "METRIC_COLUMNS",
    "metric_rows",
    "single_cluster_note",
]
